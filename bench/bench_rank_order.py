"""Which flying-gripper episodes does ``rank``'s listed order change? No physics needed.

An episode (``bench/bench_sim.py``) is a pure function of its seed and the option it acts with,
``usable[0]`` of ``inst.rank``: where the first feasible option is the same under ``rank``'s key
and under the key without the action's ``using`` order (feasible, mode, rotation: the key before
``Option.listed``), the episode's record is the same. This draws every episode of a run as the
bench does and counts, per category and task, the episodes whose option differs, with both names.

    python bench/bench_rank_order.py --categories Drawer DoorLeaf --episodes 25
    python bench/bench_rank_order.py --episodes 50      # the bench's 12 categories
    python bench/bench_rank_order.py --smoke            # 1 category, 1 episode per task
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sim import CATEGORIES, plan  # noqa: E402  (the flying Panda's episodes)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "rank_order.json"


def main(argv: list[str] | None = None) -> int:
    return run(argv, __doc__, "bench_rank_order.py", RESULTS, CATEGORIES, listed_order_choices)


def listed_order_choices(concept: str, options: list[Any]) -> tuple[str | None, str | None]:
    """The first feasible option under the key before ``Option.listed``, and under ``rank``'s."""
    from grace_dsl.runtime.manipulation import MODE_ORDER

    before = sorted(options, key=lambda o: (not o.feasible, MODE_ORDER.get(o.mode, 3), o.rotation))
    old = next((o.grasp for o in before if o.feasible), None)
    return old, next((o.grasp for o in options if o.feasible), None)


Choices = Callable[[str, list[Any]], tuple[Any, Any]]


def run(
    argv: list[str] | None,
    doc: str | None,
    script: str,
    results: Path,
    categories: tuple[str, ...] | list[str],
    choices: Choices,
) -> int:
    """The command line shared by the benches that compare two choices of option per draw."""
    ap = argparse.ArgumentParser(description=(doc or "").split("\n")[0])
    ap.add_argument("--categories", nargs="+", default=list(categories))
    ap.add_argument("--episodes", type=int, default=25, help="episodes per category and task")
    ap.add_argument("--hand", default="panda")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--smoke", action="store_true", help="1 category, 1 episode per task")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON result (default {results})")
    args = ap.parse_args(argv)
    chosen = tuple(args.categories)
    episodes = args.episodes
    if args.smoke:
        chosen, episodes = (chosen[0],), 1
    rows = compare(plan(chosen, episodes, args.hand, args.seed), args.hand, choices)
    out = args.out or results
    out.parent.mkdir(parents=True, exist_ok=True)
    header = {"command": " ".join([f"python bench/{script}", *(argv or sys.argv[1:])])}
    out.write_text(json.dumps({**header, "seed": args.seed, "rows": rows}, indent=1) + "\n")
    for r in rows:
        moves = ", ".join(f"{k} {n}" for k, n in r["moves"].items())
        print(f"{r['concept']:16} {r['task']:6} {r['changed']:3d} of {r['episodes']:3d}  {moves}")
    return 0


def compare(jobs: list[tuple[Any, int]], hand: str, choices: Choices) -> list[dict[str, Any]]:
    """Per (concept, task): episodes, the options chosen, how many change and ``old -> new``."""
    from rich.console import Console
    from rich.progress import track

    from grace_dsl import Gripper
    from grace_dsl.sim.episode import Start, start_episode

    gripper = Gripper.load(hand)
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for config, seed in track(jobs, description="draws", console=Console(stderr=True)):
        row = rows.setdefault(
            (config.concept, config.task),
            {"concept": config.concept, "task": config.task, "episodes": 0, "changed": 0},
        )
        row["episodes"] += 1
        start = start_episode(config, seed, time.perf_counter())
        if not isinstance(start, Start):  # an invalid draw: no option either way
            continue
        options = start.inst.rank(start.task.action, gripper=gripper)
        old, new = choices(config.concept, options)
        row.setdefault("options", Counter())[str(new)] += 1
        if new != old:
            row["changed"] += 1
            row.setdefault("moves", Counter())[f"{old} -> {new}"] += 1
            row.setdefault("seeds", []).append(seed)
    for row in rows.values():
        row["moves"] = dict(row.get("moves", {}))
        row["options"] = dict(row.get("options", {}))
    return list(rows.values())


if __name__ == "__main__":
    t0 = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - t0:.0f} s")
    sys.exit(code)
