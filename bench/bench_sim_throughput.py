"""Episodes per minute of the simulated benchmark, and how they scale with workers and with Ray.

Run: ``.venv/bin/python bench/bench_sim_throughput.py [--categories NAME ...] [--episodes N]
[--out FILE] [--small]`` (writes bench/results/sim_throughput.json). The same episodes (the
categories, open and close, N each, seeds by ``grace_dsl.sim.runner.episode_seed`` from seed 0)
run four ways through ``grace_dsl.sim.runner.run_episodes``: in this process (``--workers 1``), a
local pool of 2 processes, and a new local Ray instance with 1 and with 2 worker processes (a
second Ray worker stands in for a second machine). A rate counts the wall time of the whole call,
process start and library warm-up included, since a bench run pays them too; ``episode_seconds``
is the mean time inside one episode (as the episode reports it). ``--fn MODULE:NAME`` runs another
episode function, e.g. a trivial one to measure the runner's own cost. ``--small`` (also
``--smoke``): 1 category, 1 episode per task, a pool of 2 and Ray with 2 (as the tests run it).
Ray runs are skipped, and said so, without the ``ray`` extra.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "osmesa")

from grace_dsl.sim.runner import plan_episodes, run_episodes, shared_library  # noqa: E402

OUT = Path(__file__).parent / "results" / "sim_throughput.json"
BACKENDS = (("local", 1), ("local", 2), ("ray", 1), ("ray", 2))  # local 1: this process


def measure(jobs: list[Any], backend: str, workers: int, fn: Any) -> dict[str, Any]:
    """One backend's wall time over ``jobs`` and what the episodes reported."""
    address = "local" if backend == "ray" else None
    started = time.perf_counter()
    records = run_episodes(
        jobs, fn=fn, workers=workers, ray_address=address, progress=False, warm=True
    )
    wall = time.perf_counter() - started
    inside = [r.wall_seconds for r in records if r.wall_seconds > 0]
    return {
        "backend": backend,
        "workers": workers,
        "episodes": len(records),
        "wall_seconds": round(wall, 3),
        "episodes_per_minute": round(60.0 * len(records) / wall, 2),
        "episode_seconds": round(sum(inside) / len(inside), 3) if inside else None,
        "strict": sum(r.strict for r in records),
        "raised": sum(r.detail.startswith("raised ") for r in records),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--categories", nargs="+", default=["CabinetDrawer", "SunkenDoor"])
    parser.add_argument("--episodes", type=int, default=5, help="per category and task (5)")
    parser.add_argument("--out", type=Path, default=OUT, help="where the JSON goes")
    parser.add_argument("--small", "--smoke", action="store_true", help="a tiny run")
    parser.add_argument(
        "--fn",
        metavar="MODULE:NAME",
        help="another episode function (a trivial one measures the runner's own cost)",
    )
    args = parser.parse_args()
    fn = _function(args.fn) if args.fn else None
    if fn is None and not importlib.util.find_spec("grace_dsl.sim.episode"):
        print("this grace_dsl has no simulated episode (grace_dsl.sim.episode)", file=sys.stderr)
        return 2
    if args.small:
        args.categories, args.episodes = args.categories[:1], 1
    jobs = plan_episodes(args.categories, args.episodes, seed=0)
    started = time.perf_counter()
    shared_library()  # the cache built before any timing, so no backend pays the compile
    warm = time.perf_counter() - started
    has_ray = importlib.util.find_spec("ray") is not None
    rows, skipped = [], []
    backends = (BACKENDS[1], BACKENDS[3]) if args.small else BACKENDS
    for backend, workers in backends:
        if backend == "ray" and not has_ray:
            skipped.append(f"{backend} x{workers}: the ray extra is not installed")
            continue
        row = measure(jobs, backend, workers, fn)
        rows.append(row)
        print(
            f"{backend:<4} x{workers}: {row['episodes']} episodes in {row['wall_seconds']:.1f} s"
            f" = {row['episodes_per_minute']:.1f} per minute"
            f" (inside an episode {row['episode_seconds']} s; strict {row['strict']})"
        )
    result = {
        "episode_function": args.fn or "grace_dsl.sim.episode:run_episode",
        "categories": args.categories,
        "episodes_per_task": args.episodes,
        "library_load_seconds": round(warm, 3),
        "cpus": os.cpu_count(),
        "platform": platform.platform(),
        "runs": rows,
        "skipped": skipped,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


def _function(spec: str) -> Any:
    module, _, name = spec.partition(":")
    return getattr(importlib.import_module(module), name)


if __name__ == "__main__":
    raise SystemExit(main())
