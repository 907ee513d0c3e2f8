"""``grace run``: a plan file executed in a scene file, its JSON result and exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import grace_dsl as eac
from grace_dsl.cli.grace import main
from grace_dsl.cli.run_cmd import FAILED, load_plan, plan_from_json

SCENE = {
    "name": "one chest",
    "objects": [{"name": "chest", "concept": "ChestOfDrawers", "joints": {"slide2": 0.25}}],
}
STEP = {
    "text": "close the middle drawer",
    "object": "chest",
    "concept": "ChestOfDrawers",
    "part": "drawer2",
    "action": "close2",
    "joint": "slide2",
    "target": {"kind": "close", "value": 0.0},
    "condition": {"object": "chest", "joint": "slide2", "lo": 0.0, "hi": 0.0175},
}
PLAN = {"instruction": "close the middle drawer", "objects": [], "subtasks": [STEP]}
OPEN = {
    **STEP,
    "text": "open the top drawer",
    "part": "drawer1",
    "action": "open1",
    "joint": "slide1",
    "target": {"kind": "open", "value": 0.0},
    "condition": {"object": "chest", "joint": "slide1", "lo": 0.175, "hi": 0.35},
}


@pytest.fixture
def files(tmp_path: Path, lib: eac.Library, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr("grace_dsl.runtime.library.load_library", lambda: lib)
    (tmp_path / "scene.json").write_text(json.dumps(SCENE))
    (tmp_path / "plan.json").write_text(json.dumps(PLAN))
    (tmp_path / "open.json").write_text(json.dumps({**PLAN, "subtasks": [OPEN]}))
    return tmp_path


def test_a_plan_round_trips_through_json(tmp_path: Path) -> None:
    plan = plan_from_json(PLAN)
    (tmp_path / "again.json").write_text(json.dumps({"plan": plan.to_json()}))
    assert load_plan(tmp_path / "again.json") == plan


@pytest.mark.slow
def test_run_a_plan_file_and_write_pictures(
    files: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["run", "--scene", str(files / "scene.json"), "--plan", str(files / "plan.json")]
    status = main([*args, "--json", "--png", str(files / "png"), "--html", str(files / "r.html")])
    out = json.loads(capsys.readouterr().out)
    assert status == 0 and out["success"], out
    (step,) = out["steps"]
    assert step["verified"] and step["q_before"] == pytest.approx(0.25)
    assert out["joints"]["chest"]["slide2"] < 0.0175
    assert (files / "png" / "before.png").read_bytes()[:4] == b"\x89PNG"
    assert "close the middle drawer" in (files / "r.html").read_text()
    # opening the top drawer with one simulated second per attempt cannot finish: exit code 3
    args[-1] = str(files / "open.json")
    status = main([*args, "--json", "--seconds", "1", "--attempts", "2"])
    out = json.loads(capsys.readouterr().out)
    assert status == FAILED and not out["success"]
    attempts = out["steps"][0]["attempts"]
    assert [a["reason"] for a in attempts] == ["timeout", "timeout"], attempts
    assert attempts[1]["q_after"] < 0.175


def test_bad_input_and_modes_not_built(files: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scene = str(files / "scene.json")
    assert main(["run", "--scene", scene, "--plan", scene]) == 1  # a scene is not a plan
    assert "not a plan" in capsys.readouterr().err
    assert main(["run", "--scene", str(files / "nope.json"), "--plan", scene]) == 1
    assert main(["run", "--scene", scene, "--agent", "arm", "--hand", "pusher"]) == 1
    assert "Panda with its own hand" in capsys.readouterr().err
    arm_estimated = ["--mode", "estimated", "--agent", "arm", "--plan", scene]
    assert main(["run", "--scene", scene, *arm_estimated]) == 2
    assert "flying hand only" in capsys.readouterr().err
    assert main(["bench", "--suite", "tasks", "--mode", "estimated"]) == 2  # the suite's branch
    assert "--suite tasks" in capsys.readouterr().err
