"""Estimated against oracle: strict success of the flying Panda hand per category (issue 14).

Each episode is run twice with the same ``(config, seed)``: ``oracle`` (``sim.run_episode``: the
agent knows the true parameters and pose) and ``estimated``
(``agent.estimated_episode.run_estimated_episode``: the agent's model comes from the protocol's
RGB-D view through segmentation and ``eac.estimate``, learned start where weights ship), in the
same physical world. The table gives both strict rates per category (open and close pooled),
their difference in points, the estimated mode's failure reasons, the share of estimates
refused, and the accepted estimates' median errors (worst length, pose).

    python bench/bench_sim_estimated.py --small             # 3 categories x 2 tasks x 2 episodes
    python bench/bench_sim_estimated.py --episodes 10 --log bench/results/sim_estimated.jsonl
    python bench/bench_sim_estimated.py --single-view        # the protocol's view only

``--log`` appends one JSON line per record as it finishes; a run given the same log skips the
episodes it already holds (resume after a stop). Episode i of every category and task has
``bench/bench_sim.py``'s seed (``episode_seed``: ``--seed 0`` gives 0, 1, 2 ...).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter, defaultdict
from functools import partial
from pathlib import Path
from statistics import median
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "sim_estimated.json"
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sim import CATEGORIES, SMALL, TASKS, episode_seed  # noqa: E402  (the flying Panda's categories)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--categories", nargs="+", default=None)
    ap.add_argument("--episodes", type=int, default=10, help="episodes per category and task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--single-view", action="store_true", help="refuse instead of looking again")
    ap.add_argument("--looks", type=int, default=None, help="at most this many looks (default 3)")
    ap.add_argument(
        "--no-fuse", action="store_true", help="fit each look alone (no fused fit of the looks)"
    )
    ap.add_argument(
        "--no-frameless",
        action="store_true",
        help="take a frameless leaf's joint from its fit (not from the protocol's upright base)",
    )
    ap.add_argument("--min-confidence", type=float, default=None, help="refuse below (0.7)")
    ap.add_argument("--small", action="store_true", help="3 categories, 2 episodes each")
    ap.add_argument("--smoke", action="store_true", help="1 category, 1 episode per task")
    ap.add_argument("--log", type=Path, default=None, help="JSON lines, appended and resumed")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON summary (default {RESULTS})")
    args = ap.parse_args(argv)
    categories = tuple(args.categories or CATEGORIES)
    episodes = args.episodes
    if args.small:
        categories, episodes = tuple(args.categories or SMALL), 2
    if args.smoke:
        categories, episodes = (categories[0],), 1
    from grace_dsl.agent.estimated import LOOKS, MIN_CONFIDENCE

    looks = 1 if args.single_view else args.looks or LOOKS
    min_confidence = MIN_CONFIDENCE if args.min_confidence is None else args.min_confidence
    started = time.perf_counter()
    done = _read_log(args.log)
    jobs = [
        (c, t, episode_seed(args.seed, i))
        for c in categories
        for t in TASKS
        for i in range(episodes)
    ]
    records = [done[j] for j in jobs if j in done]
    todo = [j for j in jobs if j not in done]
    for category, task, seed in _progress(todo):
        pair = run_pair(
            category, task, seed, looks, min_confidence, not args.no_fuse, not args.no_frameless
        )
        records.append(pair)
        if args.log is not None:
            args.log.parent.mkdir(parents=True, exist_ok=True)
            with args.log.open("a") as f:
                f.write(json.dumps(pair) + "\n")
    rows = summarize(records)
    out = args.out or RESULTS
    out.parent.mkdir(parents=True, exist_ok=True)
    body = {
        "command": " ".join(["python bench/bench_sim_estimated.py", *(argv or sys.argv[1:])]),
        "episodes": episodes,
        "seed": args.seed,
        "looks": looks,
        "min_confidence": min_confidence,
        "fused": not args.no_fuse,
        "frameless": not args.no_frameless,
        "wall_seconds": round(time.perf_counter() - started, 1),
        "summary": rows,
    }
    out.write_text(json.dumps(body, indent=1) + "\n")
    print_table(rows)
    return 0


def run_pair(
    category: str,
    task: str,
    seed: int,
    looks: int = 3,
    min_confidence: float = 0.7,
    fused: bool = True,
    frameless: bool = True,
) -> dict[str, Any]:
    """The oracle and the estimated episode of one (category, task, seed)."""
    from grace_dsl.agent.estimated_episode import estimated_episode
    from grace_dsl.sim.records import EpisodeConfig
    from grace_dsl.sim.runner import guarded

    base = EpisodeConfig(category, task)  # type: ignore[arg-type]
    oracle = guarded(_oracle, base, seed)
    est_config = EpisodeConfig(category, task, mode="estimated")  # type: ignore[arg-type]
    run = partial(
        estimated_episode,
        looks=looks,
        min_confidence=min_confidence,
        fused=fused,
        frameless=frameless,
    )
    estimated = guarded(run, est_config, seed)
    return {
        "concept": category,
        "task": task,
        "seed": seed,
        "oracle": {"strict": oracle.strict, "reason": oracle.reason, "option": oracle.option},
        "estimated": {
            "strict": estimated.strict,
            "lenient": estimated.lenient,
            "reason": estimated.reason,
            "detail": estimated.detail[:300],
            "option": estimated.option,
            "estimate": estimated.estimate,
            "wall_seconds": round(estimated.wall_seconds, 2),
        },
    }


def _oracle(config: Any, seed: int) -> Any:
    from grace_dsl.sim.episode import run_episode

    return run_episode(config, seed)


def summarize(pairs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per category: strict oracle and estimated, the difference, reasons, refusals, errors."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for p in pairs:
        groups[p["concept"]].append(p)
    rows = []
    for concept, ps in groups.items():
        n = len(ps)
        oracle = sum(p["oracle"]["strict"] for p in ps) / n
        est = sum(p["estimated"]["strict"] for p in ps) / n
        estimates = [p["estimated"]["estimate"] for p in ps]
        accepted = [e for e in estimates if e and not e["refused"]]
        looks = [_camera_looks(p["estimated"]["estimate"] or {}) for p in ps]
        rows.append(
            {
                "concept": concept,
                "episodes": n,
                "oracle_strict": round(oracle, 3),
                "estimated_strict": round(est, 3),
                "difference_points": round(100 * (est - oracle), 1),
                "reasons": dict(
                    Counter(p["estimated"]["reason"] for p in ps if not p["estimated"]["strict"])
                ),  # fmt: skip
                "refused": sum(1 for p in ps if (p["estimated"]["estimate"] or {}).get("refused")),
                "second_view": sum(1 for k in looks if k > 1),
                "looks": sum(looks),
                # pairs acted on an estimate of several looks fitted together
                "fused": sum(1 for p in ps if _fused(p["estimated"]["estimate"] or {})),
                "median_length_error_max_mm": _median(accepted, "length_error_max_mm"),
                "median_pose_error_mm": _median(accepted, "pose_error_mm"),
                "median_pose_error_deg": _median(accepted, "pose_error_deg"),
                "worst_params": _worst(accepted),
            }
        )
    return rows


def _camera_looks(estimate: dict[str, Any]) -> int:
    """The camera looks taken (a fused fit of them is an entry of the account, not a look)."""
    return sum(1 for a in estimate.get("looks", []) if "fused" not in a)


def _fused(estimate: dict[str, Any]) -> bool:
    """Whether the accepted estimate came from a fused fit of several looks."""
    looks = estimate.get("looks", [])
    return bool(looks) and "fused" in looks[-1] and "refused" not in looks[-1]


def _median(items: list[dict[str, Any]], key: str) -> float | None:
    values = [float(i[key]) for i in items if key in i]
    return round(median(values), 1) if values else None


def _worst(items: list[dict[str, Any]], k: int = 3) -> dict[str, float]:
    """The ``k`` parameters with the largest median error (mm for lengths, as stored x 1000)."""
    per: dict[str, list[float]] = defaultdict(list)
    for i in items:
        for name, err in i.get("params_error", {}).items():
            per[name].append(float(err))
    medians = {n: median(v) for n, v in per.items()}
    top = sorted(medians, key=lambda n: -medians[n])[:k]
    return {n: round(1000 * medians[n], 1) for n in top}


def print_table(rows: list[dict[str, Any]]) -> None:
    print(
        f"{'concept':14} {'n':>3} {'oracle':>7} {'estim':>6} {'diff':>6} {'refused':>7} "
        f"{'fused':>5}  median errors (worst length mm, pose mm/deg); estimated failures"
    )
    for r in rows:
        reasons = ", ".join(f"{k} {v}" for k, v in sorted(r["reasons"].items()))
        print(
            f"{r['concept']:14} {r['episodes']:3d} {r['oracle_strict']:7.2f} "
            f"{r['estimated_strict']:6.2f} {r['difference_points']:+6.1f} {r['refused']:7d} "
            f"{r.get('fused', 0):5d}  "
            f"{r['median_length_error_max_mm']} mm, {r['median_pose_error_mm']} mm/"
            f"{r['median_pose_error_deg']} deg; {reasons}"
        )
    n = sum(r["episodes"] for r in rows)
    o = sum(r["oracle_strict"] * r["episodes"] for r in rows) / max(n, 1)
    e = sum(r["estimated_strict"] * r["episodes"] for r in rows) / max(n, 1)
    print(f"all: {n} episode pairs, strict oracle {o:.3f}, estimated {e:.3f}")


def _read_log(path: Path | None) -> dict[tuple[str, str, int], dict[str, Any]]:
    if path is None or not path.is_file():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        if line.strip():
            p = json.loads(line)
            out[(p["concept"], p["task"], int(p["seed"]))] = p
    return out


def _progress(jobs: list[tuple[str, str, int]]) -> Any:
    """The jobs with a rich progress bar on stderr."""
    from rich.console import Console
    from rich.progress import track

    return track(jobs, description="episode pairs", console=Console(stderr=True), transient=True)


if __name__ == "__main__":
    t0 = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - t0:.0f} s")
    sys.exit(code)
