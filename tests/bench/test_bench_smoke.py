"""Every script in bench/ runs at a tiny size (``--smoke``) and writes its result, so a library
change that breaks a benchmark fails the suite instead of rotting until someone runs
``make bench`` (bench_eval.py stopped on CurveHandle's new parameter that way)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = sorted(p.name for p in (ROOT / "bench").glob("bench_*.py"))


def test_every_script_is_smoke_tested() -> None:
    assert SCRIPTS == [
        "bench_adversarial.py",
        "bench_arm_time.py",
        "bench_draw_yield.py",
        "bench_eval.py",
        "bench_furniture_fit.py",
        "bench_geometry.py",
        "bench_grasp_ik.py",
        "bench_ik.py",
        "bench_learned.py",
        "bench_new_options.py",
        "bench_perception.py",
        "bench_plan.py",
        "bench_rank_agreement.py",
        "bench_rank_order.py",
        "bench_render.py",
        "bench_repeat.py",
        "bench_runtime.py",
        "bench_sim.py",
        "bench_sim_arm.py",
        "bench_sim_estimated.py",
        "bench_sim_hands.py",
        "bench_sim_throughput.py",
        "bench_tasks.py",
        "bench_verify.py",
    ]


@pytest.mark.bench
@pytest.mark.slow
@pytest.mark.parametrize("script", SCRIPTS)
def test_smoke_run(script: str, tmp_path: Path) -> None:
    out = tmp_path / "result.json"
    run = _smoke(script, out, tmp_path)
    result = json.loads(out.read_text())
    assert result, script
    assert run.stdout.strip()
    committed = ROOT / "bench" / "results"
    assert not any(p.stat().st_mtime > out.stat().st_mtime for p in committed.glob("*.json"))


@pytest.mark.bench
@pytest.mark.slow
def test_perception_labels_smoke(tmp_path: Path) -> None:
    """bench_perception's part-labelled rows (``--labels``) at the smoke size."""
    out = tmp_path / "result.json"
    _smoke("bench_perception.py", out, tmp_path, "--labels")
    result = json.loads(out.read_text())
    assert result["modes"] == ["fit"] and "StraightHandle" in result["concepts"]


@pytest.mark.bench
@pytest.mark.slow
def test_hands_rank_only_smoke(tmp_path: Path) -> None:
    """bench_sim_hands' ``--rank-only``: each draw ranked for its hand, no physics; every row
    names an option or says why there is none."""
    out = tmp_path / "rank.json"
    run = _smoke("bench_sim_hands.py", out, tmp_path, "--rank-only", "--setups", "pusher", "panda")
    rows = json.loads(out.read_text())["ranked"]
    assert {r["setup"] for r in rows} == {"pusher", "panda"}
    assert len(rows) == 4  # 1 category x 2 tasks x 2 set-ups
    assert all(bool(r["option"]) != bool(r["why"]) for r in rows)
    assert "pusher" in run.stdout


@pytest.mark.bench
@pytest.mark.slow
def test_hands_log_resumes(tmp_path: Path) -> None:
    """bench_sim_hands' ``--log``: a rerun takes every episode from the log and runs none, and
    its tables are the first run's."""
    log, out = tmp_path / "hands.jsonl", tmp_path / "result.json"
    _smoke("bench_sim_hands.py", out, tmp_path, "--setups", "pusher", "--log", str(log))
    lines = log.read_text().splitlines()
    first = json.loads(out.read_text())
    assert len(lines) == 2 and "records" not in first and first["log"] == log.name
    run = _smoke("bench_sim_hands.py", out, tmp_path, "--setups", "pusher", "--log", str(log))
    assert log.read_text().splitlines() == lines
    assert "2 of 2 episodes" in run.stdout and "running 0" in run.stdout
    assert json.loads(out.read_text())["summary"] == first["summary"]


def _smoke(script: str, out: Path, cwd: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    """``bench/<script> --smoke [extra] --out <out>`` with this checkout's grace_dsl (and the
    test cache), asserting it exits 0."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    run = subprocess.run(
        [sys.executable, str(ROOT / "bench" / script), "--smoke", *extra, "--out", str(out)],
        capture_output=True,
        text=True,
        env=env,
        cwd=cwd,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-4000:]
    return run
