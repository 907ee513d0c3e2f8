"""Physical success of the flying Panda hand, per category and task (the paper's appendix B).

Each episode is ``grace_dsl.sim.run_episode(EpisodeConfig(concept, task), seed)``: the object's
parameters, initial joint value and camera drawn from the seed, the manipulation function picked
by ``inst.rank``, the hand driven in MuJoCo by the compliant path follower. The table gives strict
and lenient success per concept and task, and the failure reasons.

    python bench/bench_sim.py                    # 12 categories x 2 tasks x 20 episodes
    python bench/bench_sim.py --small            # 3 categories x 2 tasks x 3 episodes
    python bench/bench_sim.py --smoke            # 1 category x 2 tasks x 1 episode (the tests)
    python bench/bench_sim.py --episodes 100 --categories CabinetDrawer DoorLeaf
    python bench/bench_sim.py --episodes 100 --workers 2   # the target run (2 processes)
    python bench/bench_sim.py --engine sapien    # the same episodes on SAPIEN 3's PhysX (CPU)
    python bench/bench_sim.py --compare mujoco.json sapien.json   # the two side by side

Episode i of every category and task has seed ``--seed * SEED_STRIDE + i`` (``episode_seed``):
``--seed 0`` gives seeds 0, 1, 2 ... as every figure recorded so far, and another ``--seed`` a
block of its own that no other ``--seed`` reaches (``--seed + i`` made ``--seed 1`` rerun
episodes 1 ... of ``--seed 0``). Where an episode runs (``--workers``) does not change its
record.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord
from grace_dsl.sim.runner import run_episodes

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "sim.json"
CATEGORIES = (
    "CabinetDrawer",
    "Drawer",
    "DishDrawer",
    "HingedCabinet",
    "MirrorCabinet",
    "DoorLeaf",
    "Microwave",
    "Oven",
    "Dishwasher",
    "Refrigerator",
    "Laptop",
    "LidBox",
)
SMALL = ("CabinetDrawer", "HingedCabinet", "Microwave")
TASKS = ("open", "close")
#: Seeds per ``--seed``: a run of at most this many episodes per category and task never meets
#: another ``--seed``'s episodes.
SEED_STRIDE = 1_000_000


def episode_seed(seed: int, index: int) -> int:
    """The seed of episode ``index`` (of every category and task) in a run with ``--seed``."""
    if seed < 0 or not 0 <= index < SEED_STRIDE:
        raise ValueError(
            f"--seed must be >= 0 and an episode index in [0, {SEED_STRIDE}), "
            f"got --seed {seed}, index {index}"
        )
    return seed * SEED_STRIDE + index


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--categories", nargs="+", default=None)
    ap.add_argument("--episodes", type=int, default=20, help="episodes per category and task")
    ap.add_argument("--hand", default="panda")
    ap.add_argument(
        "--engine",
        choices=("mujoco", "sapien"),
        default="mujoco",
        help="the physics engine (sapien: the optional extra, PhysX on CPU)",
    )
    ap.add_argument(
        "--seed", type=int, default=0, help="episode i has seed SEED * 1,000,000 + i (default 0)"
    )
    ap.add_argument("--workers", type=int, default=1, help="episode processes (default 1)")
    ap.add_argument(
        "--self-collision",
        action="store_true",
        help="the object's own bodies collide with each other (in this process: --workers 1)",
    )
    ap.add_argument("--small", action="store_true", help="3 categories, 3 episodes each")
    ap.add_argument("--smoke", action="store_true", help="1 category, 1 episode per task")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON result (default {RESULTS})")
    ap.add_argument(
        "--merge",
        nargs="+",
        type=Path,
        metavar="JSON",
        help="no run: the records of these result files as one result (--out) and one table",
    )
    ap.add_argument(
        "--compare",
        nargs=2,
        type=Path,
        metavar=("A", "B"),
        help="no run: strict success of the episodes both result files hold, side by side",
    )
    args = ap.parse_args(argv)
    if args.compare:
        return compare(*args.compare, args.out)
    if args.merge:
        return merge(args.merge, args.out or RESULTS)
    categories = tuple(args.categories or CATEGORIES)
    episodes = args.episodes
    if args.small:
        categories, episodes = args.categories or SMALL, 3
    if args.smoke:
        categories, episodes = (categories[0],), 1
    if args.self_collision:
        if args.workers != 1:
            ap.error("--self-collision runs in this process: use --workers 1")
        import grace_dsl.sim.world as world

        world.SELF_COLLISION = True
    started = time.perf_counter()
    out = args.out or RESULTS
    header = {
        "command": " ".join(["python bench/bench_sim.py", *(argv or sys.argv[1:])]),
        "hand": args.hand,
        "engine": args.engine,
        "episodes": episodes,
        "seed": args.seed,
        "workers": args.workers,
        "self_collision": args.self_collision,
    }
    records: list[EpisodeRecord] = []
    for category in categories:  # the JSON rewritten after each: a long run keeps what it did
        records += run_all((category,), episodes, args.hand, args.seed, args.workers, args.engine)
        write(out, header, records, time.perf_counter() - started)
    print_table(summarize(records))
    return 0


def merge(parts: list[Path], out: Path) -> int:
    """One result from several runs' files (a long run split across processes): the records in
    the order given (an episode two files hold counted once: the first), the commands kept,
    the summary recomputed."""
    from grace_dsl.sim.report import record_from_json

    loaded = [json.loads(p.read_text()) for p in parts]
    unique = {}
    for r in (record_from_json(r) for d in loaded for r in d["records"]):
        unique.setdefault((r.config, r.seed), r)
    records = list(unique.values())
    header = {
        "command": [d["command"] for d in loaded],
        "hand": loaded[0]["hand"],
        "engine": loaded[0].get("engine", "mujoco"),
        "episodes": loaded[0]["episodes"],
        "seed": loaded[0]["seed"],
        "workers": sum(d.get("workers", 1) for d in loaded),
        "parts": [str(p) for p in parts],
    }
    write(out, header, records, max(d["wall_seconds"] for d in loaded))
    print_table(summarize(records))
    from grace_dsl.sim import report

    title = f"flying Panda hand, oracle, {header['episodes']} episodes per task"
    if header["engine"] != "mujoco":
        title += f", {header['engine']}"
    print(report.write_bar_chart(report.summarize(records), out.with_suffix(".png"), title))
    return 0


def compare(a: Path, b: Path, out: Path | None) -> int:
    """Strict and lenient success per (concept, task) over the episodes (config but the engine,
    and seed) that both result files hold, and B minus A; the table printed, JSON to ``out``."""
    from grace_dsl.sim.report import record_from_json

    def load(path: Path) -> dict[tuple[str, str, int], EpisodeRecord]:
        records = map(record_from_json, json.loads(path.read_text())["records"])
        return {(r.config.concept, r.config.task, r.seed): r for r in records}

    left, right = load(a), load(b)
    common = [k for k in left if k in right]
    groups: dict[tuple[str, str], list[tuple[str, str, int]]] = defaultdict(list)
    for key in common:
        groups[key[:2]].append(key)
    rows = []
    for (concept, task), keys in groups.items():
        n = len(keys)
        sa = sum(left[k].strict for k in keys) / n
        sb = sum(right[k].strict for k in keys) / n
        differ = [k[2] for k in keys if left[k].strict != right[k].strict]
        rows.append(
            {
                "concept": concept,
                "task": task,
                "episodes": n,
                "strict_a": sa,
                "strict_b": sb,
                "lenient_a": sum(left[k].lenient for k in keys) / n,
                "lenient_b": sum(right[k].lenient for k in keys) / n,
                "difference": sb - sa,
                "seeds_that_differ": differ,
            }
        )
    print(f"A = {a}, B = {b}")
    print(f"{'concept':16} {'task':6} {'n':>4} {'A':>6} {'B':>6} {'B-A':>6}  seeds that differ")
    for r in rows:
        print(
            f"{r['concept']:16} {r['task']:6} {r['episodes']:4d} {r['strict_a']:6.2f} "
            f"{r['strict_b']:6.2f} {r['difference']:+6.2f}  {r['seeds_that_differ'] or ''}"
        )
    n = len(common)
    both = [sum(side[k].strict for k in common) / max(n, 1) for side in (left, right)]
    print(f"all: {n} episodes, strict A {both[0]:.3f}, B {both[1]:.3f}")
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        body = {
            "a": str(a),
            "b": str(b),
            "episodes": n,
            "strict_a": both[0],
            "strict_b": both[1],
            "rows": rows,
        }
        out.write_text(json.dumps(body, indent=1) + "\n")
    return 0


def write(out: Path, header: dict[str, Any], records: list[EpisodeRecord], wall: float) -> None:
    """The result file: the run's settings, the summary rows and every record."""
    out.parent.mkdir(parents=True, exist_ok=True)
    body = {
        **header,
        "wall_seconds": round(wall, 1),
        "summary": summarize(records),
        "records": [r.to_json() for r in records],
    }
    out.write_text(json.dumps(body, indent=1) + "\n")


def run_all(
    categories: tuple[str, ...],
    episodes: int,
    hand: str,
    seed: int,
    workers: int = 1,
    engine: str = "mujoco",
) -> list[EpisodeRecord]:
    """Every (category, task, episode) through the runner (``workers`` processes), with a
    progress bar; records in the order asked."""
    return run_episodes(plan(categories, episodes, hand, seed, engine), workers=workers)


def plan(
    categories: tuple[str, ...], episodes: int, hand: str, seed: int, engine: str = "mujoco"
) -> list[tuple[EpisodeConfig, int]]:
    """The (config, seed) of every episode of a run, category by category, task, index."""
    return [
        (EpisodeConfig(c, t, hand=hand, engine=engine), episode_seed(seed, i))  # type: ignore[arg-type]
        for c in categories
        for t in TASKS
        for i in range(episodes)
    ]


def summarize(records: list[EpisodeRecord]) -> list[dict[str, Any]]:
    """Per (concept, task): episodes, strict and lenient rates, failure reasons, wall time."""
    groups: dict[tuple[str, str], list[EpisodeRecord]] = defaultdict(list)
    for r in records:
        groups[(r.config.concept, r.config.task)].append(r)
    rows = []
    for (concept, task), rs in groups.items():
        n = len(rs)
        rows.append(
            {
                "concept": concept,
                "task": task,
                "episodes": n,
                "strict": sum(r.strict for r in rs) / n,
                "lenient": sum(r.lenient for r in rs) / n,
                "reasons": dict(Counter(r.reason for r in rs if not r.strict)),
                "options": dict(Counter(r.option for r in rs)),
                "wall_s_per_episode": round(sum(r.wall_seconds for r in rs) / n, 2),
            }
        )
    return rows


def print_table(rows: list[dict[str, Any]]) -> None:
    print(f"{'concept':16} {'task':6} {'n':>4} {'strict':>7} {'lenient':>8}  failures")
    for row in rows:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(row["reasons"].items()))
        print(
            f"{row['concept']:16} {row['task']:6} {row['episodes']:4d} {row['strict']:7.2f} "
            f"{row['lenient']:8.2f}  {reasons}"
        )
    n = sum(r["episodes"] for r in rows)
    strict = sum(r["strict"] * r["episodes"] for r in rows) / max(n, 1)
    print(f"all: {n} episodes, strict {strict:.3f}")


if __name__ == "__main__":
    started = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - started:.0f} s")
    sys.exit(code)
