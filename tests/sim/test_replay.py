"""Replays of real episodes: the last frame as a picture (what ``grace bench`` writes for each
failure), before and after pictures, and the HTML viewer page of the traced motion."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from grace_dsl.cli.bench_cmd import bench
from grace_dsl.cli.grace import main as grace
from grace_dsl.cli.replay import replay_html
from grace_dsl.sim.episode import Z_UP, run_episode
from grace_dsl.sim.records import EpisodeConfig
from grace_dsl.sim.replay import ReplayError, failure_frame, first_qpos, render_world, replay
from grace_dsl.sim.report import failure_frame_path

pytestmark = pytest.mark.slow
OPEN = EpisodeConfig("CabinetDrawer", "open")


def _pixels(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), dtype=float)


def test_a_traced_replay_is_the_same_episode_and_moves(tmp_path: Path) -> None:
    record, world = replay(OPEN, 0)
    plain = run_episode(OPEN, 0)
    assert world is not None and len(world.trace) > 20
    assert {**record.to_json(), "wall_seconds": 0} == {**plain.to_json(), "wall_seconds": 0}
    before = render_world(world, record.camera, tmp_path / "before.png", first_qpos(world))
    after = render_world(world, record.camera, tmp_path / "after.png")
    a, b = _pixels(before), _pixels(after)
    assert a.shape == (360, 480, 3) and a.std() > 10  # the object is in the picture
    assert np.abs(a - b).mean() > 1.0  # the drawer came out between the two
    page = replay_html(world, record.joint, "CabinetDrawer open", Z_UP, tmp_path / "r.html")
    text = page.read_text()
    assert '"animation":{"frames":' in text.replace(" ", "") and "slide" in text


def test_a_failed_episode_gets_a_picture_of_its_last_frame(tmp_path: Path) -> None:
    """Out of time before the hand reached the handle: a failure, and bench draws it."""
    short = EpisodeConfig("CabinetDrawer", "open", max_seconds=0.5)
    result = bench([(short, 3)], tmp_path, render=failure_frame, progress=False)
    record = json.loads((tmp_path / "episodes.jsonl").read_text())
    assert not record["strict"] and record["reason"]
    assert result.summary["run"]["failure_pictures"] == 1
    picture = failure_frame_path(tmp_path / "failures", run_episode(short, 3))
    assert picture.is_file() and _pixels(picture).std() > 10


def test_an_episode_the_hand_never_started_is_skipped_with_its_reason(tmp_path: Path) -> None:
    # a shut Laptop opens by a pinch of its lid's edge only (a finger fits under the lid only
    # when it is ajar): a hand that cannot close has no option
    record = run_episode(EpisodeConfig("Laptop", "open", hand="pusher"), 1)
    assert record.reason == "no_feasible_grasp"
    with pytest.raises(ReplayError, match="never moved"):
        failure_frame(record, tmp_path / "x.png")


def test_bench_json_is_the_summary_with_the_picture_count(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["bench", "--categories", "CabinetDrawer", "--episodes", "1", "--out", str(tmp_path)]
    assert grace([*argv, "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["categories"][0]["category"] == "CabinetDrawer"
    run = summary["run"]
    assert run["episodes_total"] == 2 and "failure_pictures" in run
    lines = (tmp_path / "episodes.jsonl").read_text().splitlines()
    failed = 2 - sum(json.loads(line)["strict"] for line in lines)
    assert run["failure_pictures"] + len(run["failure_pictures_skipped"]) == failed
    assert (tmp_path / "success.png").is_file()
