"""``grace bench``: the articulated-object benchmark: open and close each category N times.

Every episode is ``run_episode(config, seed)`` with a seed from ``--seed`` by the documented rule
(``grace_dsl.sim.runner.episode_seed``), run here, in ``--workers`` processes, or on Ray
(``--ray``: a new local instance; ``--ray auto``: the running cluster; ``--ray ray://HOST:PORT``).
``--out DIR`` receives ``episodes.jsonl`` (one record per episode), ``summary.json`` (the table
and the run's settings and speed), ``table.txt``, ``success.png`` (the bar chart) and
``failures/`` (a picture of each failed episode's last frame, the episode run again); the table
is printed (or the summary, with ``--json``). Categories default to ``DEFAULT_CATEGORIES``:
drawers, doors, lids and windows of the standard library, every one with an ``open`` and a
``close`` action on one joint.

Exit codes: 0 the run finished (whatever its success rates), 1 a bad argument or a failure to
start, 2 a mode that does not exist yet (``--mode estimated --agent arm``). ``--mode estimated``
runs ``grace_dsl.agent.estimated_episode`` (the agent's model of the object from the camera; the
records carry the estimate's errors under ``estimate``); it has no failure pictures.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from grace_dsl.cli.output import error, print_json, print_text
from grace_dsl.runtime.errors import GraceError, ParameterError

#: Articulated categories with ``open`` and ``close`` on one joint: three drawers, six hinged
#: doors (one with a knob, a sunken handle, appliance doors), three lids, three windows (sash,
#: sliding, casement). Fifteen, so that the issue's "at least 12 categories" holds with margin.
DEFAULT_CATEGORIES = (
    "Drawer",
    "CabinetDrawer",
    "DishDrawer",
    "HingedCabinet",
    "KnobWardrobeDoor",
    "SunkenDoor",
    "Refrigerator",
    "Microwave",
    "Dishwasher",
    "LidBox",
    "TrashCan",
    "Laptop",
    "SashWindow",
    "SlidingWindow",
    "CasementWindow",
)
#: What ``grace demo`` runs: a drawer and a door, open and close, with the flying gripper.
DEMO_CATEGORIES = ("CabinetDrawer", "SunkenDoor")


class NotBuiltError(GraceError):
    """A bench mode whose layer is not built yet; exit code 2, not a pretend result."""


@dataclass(frozen=True)
class BenchResult:
    """What a run wrote and how fast it went."""

    summary: dict[str, Any]
    table: str
    files: dict[str, Path]


def add_bench_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--categories",
        nargs="+",
        metavar="CONCEPT",
        help=f"concepts to test (default: {len(DEFAULT_CATEGORIES)} drawers, doors, lids, windows)",
    )
    p.add_argument("--episodes", type=int, default=100, help="per category and task (100)")
    p.add_argument(
        "--mode",
        choices=("oracle", "estimated"),
        default="oracle",
        help="oracle: the true concept and parameters; estimated: from the camera (perception)",
    )
    p.add_argument(
        "--agent",
        choices=("gripper", "arm"),
        default="gripper",
        help="gripper: a flying Panda hand (default); arm: the whole Panda on a base",
    )
    p.add_argument("--hand", default="panda", help="a shipped hand or a hand file (panda)")
    p.add_argument(
        "--engine",
        choices=("mujoco", "sapien"),
        default="mujoco",
        help="physics: mujoco (default) or sapien (SAPIEN 3's PhysX on CPU, the sapien extra)",
    )
    p.add_argument("--scale", default="1,1", metavar="LO,HI", help="object size factor (1,1)")
    p.add_argument("--seed", type=int, default=0, help="the run's seed (0)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (1)")
    p.add_argument(
        "--ray",
        nargs="?",
        const="local",
        metavar="ADDRESS",
        help="run on Ray: alone a new local instance; `auto` or ray://HOST:PORT a cluster",
    )
    p.add_argument("--out", default="out/bench", help="where the report goes (out/bench)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument(
        "--suite",
        choices=("objects", "tasks"),
        default="objects",
        help="objects: open and close each category (default); tasks: the instruction suite, "
        "parsed and carried out (grace_dsl.cli.run_cmd.run_suite)",
    )


def run_bench(args: Any, *, fn: Any = None, render: Any = None) -> int:
    """The body of ``grace bench``. ``fn`` replaces the episode function (default the simulated
    episode); ``render`` draws each failure's final frame (``grace_dsl.sim.report.FrameRenderer``;
    default, for the simulated episode: the episode run again and its last frame drawn,
    ``grace_dsl.sim.replay.failure_frame``; none for another ``fn`` without one)."""
    if getattr(args, "suite", "objects") == "tasks":
        from grace_dsl.cli.run_cmd import run_suite

        return run_suite(args)
    try:
        jobs = _jobs(args)
        if fn is None and args.mode == "estimated":  # the agent's model from the camera
            from grace_dsl.agent.estimated_episode import run_estimated_episode

            fn = run_estimated_episode
        if render is None and fn is None:
            from grace_dsl.sim.replay import failure_frame

            render = failure_frame
        result = bench(
            jobs,
            Path(args.out),
            fn=fn,
            workers=args.workers,
            ray_address=args.ray,
            render=render,
            settings=_settings(args),
        )
    except NotBuiltError as exc:
        error(str(exc))
        return 2
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return 1
    if args.json:
        print_json(result.summary)
    else:
        print_text(result.table)
        print_text("\n".join(f"{k}: {v}" for k, v in result.files.items()))
    return 0


def bench(
    jobs: Sequence[tuple[Any, int]],
    out: Path,
    *,
    fn: Any = None,
    workers: int = 1,
    ray_address: str | None = None,
    render: Any = None,
    settings: dict[str, Any] | None = None,
    progress: bool = True,
) -> BenchResult:
    """Run ``jobs`` and write the report into ``out``: the part of ``grace bench`` after argument
    checking, for ``grace demo`` and scripts (``demo_jobs`` gives the demo's set)."""
    from grace_dsl.sim.report import (
        format_table,
        save_failure_frames,
        summarize,
        summary_json,
        write_bar_chart,
        write_jsonl,
    )
    from grace_dsl.sim.runner import run_episodes

    started = time.perf_counter()
    records = run_episodes(jobs, fn=fn, workers=workers, ray_address=ray_address, progress=progress)
    seconds = time.perf_counter() - started
    rows = summarize(records)
    table = format_table(rows)
    rate = 60.0 * len(records) / seconds if seconds > 0 else math.inf
    summary = {
        **summary_json(rows),
        "run": {
            **(settings or {}),
            "episodes_total": len(records),
            "wall_seconds": round(seconds, 3),
            "episodes_per_minute": round(rate, 2),
        },
    }
    files = {
        "episodes": write_jsonl(records, out / "episodes.jsonl"),
        "table": _write(out / "table.txt", table + "\n"),
        "chart": write_bar_chart(rows, out / "success.png", _title(settings)),
    }
    if render is not None:
        frames, skipped = save_failure_frames(records, out / "failures", render)
        files["failures"] = out / "failures"
        summary["run"]["failure_pictures"] = len(frames)
        summary["run"]["failure_pictures_skipped"] = skipped
    files["summary"] = _write(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    return BenchResult(summary, table, files)


def demo_jobs(seed: int = 0, episodes: int = 1) -> list[tuple[Any, int]]:
    """The demo's episodes: ``DEMO_CATEGORIES``, open and close, the flying Panda hand."""
    from grace_dsl.sim.runner import plan_episodes

    return plan_episodes(DEMO_CATEGORIES, episodes, seed)


def _jobs(args: Any) -> list[tuple[Any, int]]:
    """Checked arguments as (config, seed) pairs; cheap checks first, the library last."""
    from grace_dsl.sim.records import EpisodeConfig
    from grace_dsl.sim.runner import plan_episodes

    if args.mode == "estimated" and args.agent != "gripper":
        raise NotBuiltError("--mode estimated runs with --agent gripper (the arm's: not built)")
    scale = _scale(args.scale)
    if args.workers < 1:
        raise ParameterError(f"--workers must be at least 1, got {args.workers}")
    _check_hand(args.hand)
    categories = tuple(args.categories or DEFAULT_CATEGORIES)
    _check_categories(categories)
    engine = getattr(args, "engine", "mujoco")
    _check_engine(engine, args.agent)
    base = EpisodeConfig(
        concept="",
        agent=args.agent,
        hand=args.hand,
        mode=args.mode,
        scale=scale,
        engine=engine,  # type: ignore[arg-type]  # checked: argparse's choices
    )
    return plan_episodes(categories, args.episodes, args.seed, base)


def _scale(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(x) for x in text.split(","))
    except ValueError:
        raise ParameterError(f"--scale takes LO,HI (two numbers), got {text!r}") from None
    if not (0 < lo <= hi and math.isfinite(hi)):
        raise ParameterError(f"--scale needs 0 < LO <= HI, got {lo:g},{hi:g}")
    return lo, hi


def _check_engine(engine: str, agent: str) -> None:
    """SAPIEN drives the flying hand only, and only when its optional extra is installed."""
    if engine == "mujoco":
        return
    if agent != "gripper":
        raise ParameterError(f"--engine {engine} drives the flying hand: use --agent gripper")
    from grace_dsl.sim.sapien_world import available

    if not available():
        raise ParameterError("--engine sapien needs SAPIEN 3: pip install -e '.[sapien]'")


def _check_hand(hand: str) -> None:
    from grace_dsl.runtime.hands import load_hand

    load_hand(hand)  # an unknown name or a bad file: ParameterError naming the shipped hands


def _check_categories(categories: Sequence[str]) -> None:
    """Every category a library concept with ``open`` and ``close`` acting on a joint."""
    from grace_dsl.sim.runner import shared_library

    library = shared_library()
    for name in categories:
        concept = library[name]  # UnknownNameError with a suggestion
        missing = [a for a in ("open", "close") if a not in concept.actions]
        if missing or any(concept.actions[a].joint is None for a in ("open", "close")):
            raise ParameterError(
                f"{name} cannot be a bench category: it needs `open` and `close` actions that "
                f"move a joint ({', '.join(missing) or 'one acts in a fixed direction'})"
            )


def _settings(args: Any) -> dict[str, Any]:
    return {
        "categories": list(args.categories or DEFAULT_CATEGORIES),
        "episodes": args.episodes,
        "mode": args.mode,
        "agent": args.agent,
        "hand": args.hand,
        "engine": getattr(args, "engine", "mujoco"),
        "scale": list(_scale(args.scale)),
        "seed": args.seed,
        "workers": args.workers,
        "ray": args.ray,
    }


def _title(settings: dict[str, Any] | None) -> str:
    if not settings:
        return "success rate by category"
    s = settings
    return (
        f"success by category: {s['agent']} ({s['hand']}), {s['mode']}, "
        f"{s['episodes']} episodes per task, seed {s['seed']}"
    )


def _write(path: Path, text: str) -> Path:
    from grace_dsl.cli.files import atomic_write

    return atomic_write(path, text).path
