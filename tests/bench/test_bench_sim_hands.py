"""The other hands' bench plans its episodes so that a run cut short has covered every cell
evenly, and reads back a log whose last line an interrupted write cut short."""

from __future__ import annotations

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from bench_sim_hands import SETUPS, plan_all, read_log  # noqa: E402

from grace_dsl.sim.records import EpisodeRecord  # noqa: E402
from grace_dsl.sim.runner import plan_episodes  # noqa: E402


def test_plan_covers_every_cell_index_by_index() -> None:
    setups, categories, tasks = ["scaled", "topdown"], ("Drawer", "Oven"), ["open", "close"]
    jobs = plan_all(setups, categories, 3, 7, tasks)
    every = [j for s in setups for j in plan_episodes(categories, 3, 7, SETUPS[s], tasks)]  # type: ignore[arg-type]
    assert sorted(jobs, key=repr) == sorted(every, key=repr) and len(set(jobs)) == len(jobs)
    cells = len(setups) * len(categories) * len(tasks)
    first = jobs[:cells]  # episode 0 of every (set-up, category, task) before any episode 1
    assert len({(c.hand, c.scale, c.concept, c.task) for c, _ in first}) == cells
    index0 = plan_episodes(categories, 1, 7, SETUPS["scaled"], tasks)  # type: ignore[arg-type]
    assert {seed for _, seed in first} == {seed for _, seed in index0}


def test_log_skips_a_line_cut_short(tmp_path: Path) -> None:
    config = SETUPS["pusher"]
    record = EpisodeRecord(config, 5, "slide", (0.0, 0.4), 0.2, 0.0, True, True, option="push")
    line = json.dumps(record.to_json())
    log = tmp_path / "hands.jsonl"
    log.write_text(line + "\n" + line[: len(line) // 2])
    assert read_log(log) == [record]
    assert read_log(tmp_path / "none.jsonl") == []
