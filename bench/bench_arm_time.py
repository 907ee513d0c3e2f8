"""CPU seconds per arm episode, in one process after a warm-up episode (the figure of
"Deterministic budgets and the time of an episode" in docs/benchmarks.md).

CPU seconds, not wall seconds: on a shared machine the wall clock measures the load. The episodes'
final joint values are printed too, so two versions of the code can be checked to give the same
outcomes on the same seeds.

    python bench/bench_arm_time.py            # four episodes (drawer, door, microwave, laptop)
    python bench/bench_arm_time.py --smoke    # one episode (the tests)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from rich.progress import track

EPISODES = (
    ("CabinetDrawer", "open", 0),
    ("HingedCabinet", "close", 0),
    ("Microwave", "open", 0),
    ("Laptop", "open", 0),
)
WARM_UP = ("CabinetDrawer", "close", 1)  # loads the library, the Panda and its seed bank


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--smoke", action="store_true", help="one episode")
    ap.add_argument("--out", type=Path, default=None, help="JSON result")
    args = ap.parse_args(argv)
    from grace_dsl.sim.arm_episode import run_arm_episode
    from grace_dsl.sim.records import EpisodeConfig

    concept, task, seed = WARM_UP
    run_arm_episode(EpisodeConfig(concept, task, agent="arm"), seed)
    rows = []
    for concept, task, seed in track(EPISODES[:1] if args.smoke else EPISODES, "episodes"):
        cpu, wall = time.process_time(), time.perf_counter()
        record = run_arm_episode(EpisodeConfig(concept, task, agent="arm"), seed)
        rows.append(
            {
                "concept": concept,
                "task": task,
                "seed": seed,
                "cpu_seconds": time.process_time() - cpu,
                "wall_seconds": time.perf_counter() - wall,
                "load": os.getloadavg()[0],
                "strict": record.strict,
                "q_final": record.q_final,
            }
        )
        print(json.dumps(rows[-1]), flush=True)
    total = sum(r["cpu_seconds"] for r in rows)
    print(f"{len(rows)} episodes, {total:.2f} s of CPU, {total / len(rows):.2f} s each")
    if args.out is not None:
        args.out.write_text(json.dumps({"episodes": rows, "cpu_seconds": total}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
