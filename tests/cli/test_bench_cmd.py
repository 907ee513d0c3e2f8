"""``grace bench``: argument errors and their exit codes, and a whole run with a real, pure
episode function (the simulated one where it exists) writing every report file."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from grace_dsl.cli.bench_cmd import DEFAULT_CATEGORIES, add_bench_arguments, run_bench
from grace_dsl.cli.grace import main as grace
from grace_dsl.sim.records import FAILURE_REASONS, EpisodeConfig, EpisodeRecord
from grace_dsl.sim.report import read_jsonl
from grace_dsl.sim.runner import episode_seed, shared_library


def coin_episode(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """Strict success on a seeded coin; a failure otherwise, with a reason."""
    rng = np.random.default_rng(seed)
    ok = bool(rng.random() < 0.5)
    return EpisodeRecord(
        config=config,
        seed=seed,
        joint="hinge",
        q_range=(0.0, 1.5),
        q_initial=0.0,
        q_final=1.0 if ok else 0.0,
        lenient=ok,
        strict=ok,
        reason="" if ok else "slip",
    )


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_bench_arguments(parser)
    return parser.parse_args(list(argv))


def test_estimated_mode_with_the_arm_says_it_is_not_built(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert grace(["bench", "--mode", "estimated", "--agent", "arm"]) == 2
    assert "not built" in capsys.readouterr().err


@pytest.mark.slow
def test_estimated_mode_runs_and_records_the_estimate(tmp_path: Path) -> None:
    """``--mode estimated``: the agent's model from the camera; each record says how it looked
    and, when it accepted an estimate, how far that estimate was from the truth."""
    argv = ["--mode", "estimated", "--categories", "CabinetDrawer", "--episodes", "1"]
    assert run_bench(_args(*argv, "--out", str(tmp_path))) == 0
    records = read_jsonl(tmp_path / "episodes.jsonl")
    assert [r.config.mode for r in records] == ["estimated", "estimated"]
    for r in records:
        assert r.reason in FAILURE_REASONS and r.estimate["looks"]
        assert r.estimate["refused"] or "pose_error_mm" in r.estimate


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scale", "2,1"], "0 < LO <= HI"),
        (["--scale", "big"], "LO,HI"),
        (["--workers", "0"], "--workers"),
        (["--hand", "claw"], "no shipped hand 'claw'"),
    ],
)
def test_bad_arguments_are_one_line_and_exit_1(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert grace(["bench", *argv]) == 1
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow  # loads the standard library
def test_default_categories_open_and_close_a_joint() -> None:
    library = shared_library()
    assert len(DEFAULT_CATEGORIES) >= 12
    for name in DEFAULT_CATEGORIES:
        actions = library[name].actions
        assert actions["open"].joint and actions["close"].joint, name


@pytest.mark.slow  # loads the standard library
def test_unknown_or_unfit_category(capsys: pytest.CaptureFixture[str]) -> None:
    assert grace(["bench", "--categories", "Drawr"]) == 1
    assert "did you mean 'Drawer'" in capsys.readouterr().err
    assert run_bench(_args("--categories", "CookingPot"), fn=coin_episode) == 1
    assert "cannot be a bench category" in capsys.readouterr().err


@pytest.mark.slow  # loads the standard library
def test_a_run_writes_the_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    drawn: list[int] = []

    def render(record: EpisodeRecord, path: Path) -> None:
        drawn.append(record.seed)
        Image.new("RGB", (8, 8), "gray").save(path)

    argv = ("--categories", "Drawer", "SunkenDoor", "--episodes", "3", "--seed", "4")
    args = _args(*argv, "--scale", "0.5,2", "--out", str(tmp_path), "--json")
    assert run_bench(args, fn=coin_episode, render=render) == 0
    summary = json.loads(capsys.readouterr().out)
    records = read_jsonl(tmp_path / "episodes.jsonl")
    assert [(r.config.concept, r.config.task) for r in records[:4]] == [
        ("Drawer", "open"),
        ("Drawer", "open"),
        ("Drawer", "open"),
        ("Drawer", "close"),
    ]
    assert len(records) == 12
    assert records[4].seed == episode_seed(4, "Drawer", "close", 1)
    assert all(r.config.scale == (0.5, 2.0) and r.config.hand == "panda" for r in records)
    assert drawn == [r.seed for r in records if not r.strict]
    assert summary["run"]["episodes_total"] == 12 and summary["run"]["seed"] == 4
    door = summary["categories"][1]
    expected = sum(r.strict for r in records[6:9]) / 3
    assert door["category"] == "SunkenDoor" and door["open"]["strict"] == pytest.approx(expected)
    assert (
        json.loads((tmp_path / "summary.json").read_text())["categories"] == summary["categories"]
    )
    assert "SunkenDoor" in (tmp_path / "table.txt").read_text()
    assert Image.open(tmp_path / "success.png").width > 100
    assert len(list((tmp_path / "failures").glob("*.png"))) == len(drawn)
    # the same run again: the same records (a run is a pure function of its arguments)
    assert (
        run_bench(
            _args(*argv, "--scale", "0.5,2", "--out", str(tmp_path / "again")), fn=coin_episode
        )
        == 0
    )
    assert "Drawer" in capsys.readouterr().out
    assert read_jsonl(tmp_path / "again" / "episodes.jsonl") == records


@pytest.mark.slow
def test_two_real_episodes_through_the_cli(tmp_path: Path) -> None:
    """The simulated episode end to end: a drawer opened and closed, one episode each."""
    argv = ["bench", "--categories", "CabinetDrawer", "--episodes", "1", "--out", str(tmp_path)]
    assert grace([*argv, "--json"]) == 0
    records = read_jsonl(tmp_path / "episodes.jsonl")
    assert [r.config.task for r in records] == ["open", "close"]
    assert [r.seed for r in records] == [
        episode_seed(0, "CabinetDrawer", t, 0) for t in ("open", "close")
    ]
    for r in records:
        assert r.reason in FAILURE_REASONS and not r.detail.startswith("raised "), r.detail
        assert r.joint == "slide" and r.q_range[1] > r.q_range[0]
        assert r.q_range[0] - 1e-6 <= r.q_initial <= r.q_range[1] + 1e-6
        assert r.strict <= r.lenient  # strict success implies lenient success
    assert (tmp_path / "success.png").is_file()


def test_demo_episodes_hook_runs_the_demo_set(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from grace_dsl.cli.bench_cmd import DEMO_CATEGORIES
    from grace_dsl.cli.grace import demo_episodes

    summary = demo_episodes(tmp_path, fn=coin_episode)
    assert [c["category"] for c in summary["categories"]] == list(DEMO_CATEGORIES)
    assert summary["run"]["episodes_total"] == 4
    assert "CabinetDrawer" in capsys.readouterr().out
    assert len(read_jsonl(tmp_path / "episodes.jsonl")) == 4
