"""``grace parse``: the plan as a table or JSON, and the parser's question with exit 1."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import grace_dsl as eac
from grace_dsl.cli.grace import main


@pytest.fixture(autouse=True)
def session_library(lib: eac.Library, monkeypatch: pytest.MonkeyPatch) -> None:
    """The command loads the standard library; hand it the session's (loading again re-runs
    the front end over every file, seconds each)."""
    monkeypatch.setattr(eac, "load_library", lambda *args, **kwargs: lib)


@pytest.fixture(scope="module", autouse=True)
def placed(lib: eac.Library) -> None:
    """The kitchen placed in the world once (its objects are meshed to stand on the floor)."""
    from grace_dsl.agent.grounding import ground_scene
    from grace_dsl.agent.scene_file import load_scene

    ground_scene(load_scene("kitchen", lib), lib)


def test_parse_prints_the_plan(lib: eac.Library, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["parse", "open the top drawer, then close it", "--scene", "kitchen"]) == 0
    out = capsys.readouterr().out
    assert "open1" in out and "close1" in out and "slide1" in out


def test_parse_json_and_a_scene_file(
    lib: eac.Library, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from grace_dsl.agent.scene_file import load_scene, save_scene

    path = save_scene(load_scene("bathroom", lib), tmp_path / "bath.yaml")
    assert main(["parse", "flush the toilet", "--scene", str(path), "--json"]) == 0
    plan = json.loads(capsys.readouterr().out)
    step = plan["subtasks"][0]
    assert (step["object"], step["action"], step["target"]["kind"]) == ("toilet", "flush", "open")


def test_parse_refusal_exits_1(lib: eac.Library, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["parse", "open the drawer", "--scene", "kitchen"]) == 1
    assert "Which one?" in capsys.readouterr().err
