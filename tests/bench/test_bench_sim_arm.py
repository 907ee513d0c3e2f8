"""The arm bench's runner: episodes on a process pool give the records one process gives, and a
run with a log resumes where the log ends instead of running its episodes again."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))

from bench_sim_arm import read_log, run_all  # noqa: E402

from grace_dsl.sim.records import EpisodeRecord  # noqa: E402


def _timeless(record: EpisodeRecord) -> EpisodeRecord:
    return replace(record, wall_seconds=0.0)


@pytest.mark.slow
def test_workers_give_one_process_records_and_a_log_resumes(tmp_path: Path) -> None:
    log = tmp_path / "arm.jsonl"
    one = run_all(("CabinetDrawer",), ("open",), 2, 0, log=log, workers=1)
    two = run_all(("CabinetDrawer",), ("open",), 2, 0, workers=2)
    assert [r.seed for r in one] == [0, 1] == [r.seed for r in two]
    assert [_timeless(r) for r in one] == [_timeless(r) for r in two]
    assert all(r.bases for r in one)  # each stage's base is in the record
    lines = log.read_text().splitlines()
    again = run_all(("CabinetDrawer",), ("open",), 2, 0, log=log, workers=1)
    assert log.read_text().splitlines() == lines  # nothing ran again
    assert again == one == read_log(log)
