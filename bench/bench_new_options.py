"""Which episodes would a hand's chosen option change by grasp families added to the library?
No physics needed.

An episode (``bench/bench_sim.py``) acts with the first feasible option of ``inst.rank``. A grasp
family added to a concept changes no other option's verdict, so the option a library without it
would choose is the first feasible one of the others. This draws every episode of a run as the
bench does and counts, per category and task, the episodes whose option the added families
change (for the Panda, the check that families added for other hands leave its choices alone).

    python bench/bench_new_options.py --categories Drawer --new hook_top[0] --episodes 25
    python bench/bench_new_options.py --smoke
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sim import plan  # noqa: E402  (the flying Panda's episodes)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "new_options.json"
# the families condfam added (issue 13, the other hands), per concept
ADDED = {
    "MirrorCabinet": ("hook_side", "hook_top"),
    "CabinetDrawer": ("hook_top",),
    "Drawer": ("hook_top[0]",),
    "LidBox": ("lift_under",),
    "Laptop": ("lift_under",),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--categories", nargs="+", default=list(ADDED))
    ap.add_argument("--episodes", type=int, default=25, help="episodes per category and task")
    ap.add_argument("--hand", default="panda")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--smoke", action="store_true", help="1 category, 1 episode per task")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON result (default {RESULTS})")
    args = ap.parse_args(argv)
    categories = tuple(args.categories)
    episodes = args.episodes
    if args.smoke:
        categories, episodes = (categories[0],), 1
    rows = compare(plan(categories, episodes, args.hand, args.seed), args.hand)
    out = args.out or RESULTS
    out.parent.mkdir(parents=True, exist_ok=True)
    header = {"command": " ".join(["python bench/bench_new_options.py", *sys.argv[1:]])}
    out.write_text(json.dumps({**header, "seed": args.seed, "rows": rows}, indent=1) + "\n")
    for r in rows:
        moves = ", ".join(f"{k} {n}" for k, n in r["moves"].items())
        print(f"{r['concept']:16} {r['task']:6} {r['changed']:3d} of {r['episodes']:3d}  {moves}")
    return 0


def compare(jobs: list[tuple[Any, int]], hand: str) -> list[dict[str, Any]]:
    """Per (concept, task): episodes, how many change option, and ``old -> new`` counts."""
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
        added = ADDED.get(config.concept, ())
        options = start.inst.rank(start.task.action, gripper=gripper)
        new = next((o.grasp for o in options if o.feasible), None)
        old = next((o.grasp for o in options if o.feasible and o.grasp not in added), None)
        row.setdefault("options", Counter())[str(new)] += 1
        if new != old:
            row["changed"] += 1
            row.setdefault("moves", Counter())[f"{old} -> {new}"] += 1
            row.setdefault("seeds", []).append(seed)
    for row in rows.values():
        row["moves"] = dict(row.get("moves", {}))
        row["options"] = dict(row["options"])
    return list(rows.values())


if __name__ == "__main__":
    t0 = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - t0:.0f} s")
    sys.exit(code)
