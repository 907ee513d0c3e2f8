"""Physical success of the full Panda on a base beside the object, per category and task.

Each episode is ``grace_dsl.sim.run_episode(EpisodeConfig(concept, task, agent="arm"), seed)``:
the protocol's draw (as for the flying hand), a base placed by the robot layer, the whole action
planned (IK, collision checks, OMPL) and executed in MuJoCo by joint torques, the interaction
with a Cartesian impedance re-anchored on the measured joint value. The table has the flying
gripper's columns (``bench/bench_sim.py``): strict and lenient success and the failure reasons.

    python bench/bench_sim_arm.py                    # 12 categories x 2 tasks x 20 episodes
    python bench/bench_sim_arm.py --small            # 3 categories x 2 tasks x 2 episodes
    python bench/bench_sim_arm.py --smoke            # 1 category x 1 task x 1 episode (the tests)
    python bench/bench_sim_arm.py --episodes 5 --categories Drawer Oven
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from rich.progress import Progress

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sim import CATEGORIES, SMALL, TASKS, print_table, summarize  # noqa: E402

from grace_dsl.sim.episode import run_episode  # noqa: E402
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "sim_arm.json"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--categories", nargs="+", default=None)
    ap.add_argument("--tasks", nargs="+", default=list(TASKS), choices=TASKS)
    ap.add_argument("--episodes", type=int, default=20, help="episodes per category and task")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--small", action="store_true", help="3 categories, 2 episodes each")
    ap.add_argument("--smoke", action="store_true", help="1 category, 1 episode of 1 task")
    ap.add_argument("--out", type=Path, default=None, help=f"JSON result (default {RESULTS})")
    ap.add_argument("--log", type=Path, default=None, help="append each record here (JSON lines)")
    ap.add_argument(
        "--summarize", type=Path, default=None, help="no episodes: the table of a --log file"
    )
    args = ap.parse_args(argv)
    categories = tuple(args.categories or CATEGORIES)
    tasks, episodes = tuple(args.tasks), args.episodes
    if args.small:
        categories, episodes = tuple(args.categories or SMALL), 2
    if args.smoke:
        categories, tasks, episodes = (args.categories or ["CabinetDrawer"])[:1], ("open",), 1
    if args.summarize is not None:
        records = read_log(args.summarize)
    else:
        records = run_all(categories, tasks, episodes, args.seed, args.log)
    summary = summarize(records)
    print_table(summary)
    out = args.out or RESULTS
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(
            {
                "command": " ".join(["python bench/bench_sim_arm.py", *(argv or sys.argv[1:])]),
                "agent": "arm",
                "episodes": episodes,
                "seed": args.seed,
                "summary": summary,
                "records": [r.to_json() for r in records],
            },
            indent=1,
        )
        + "\n"
    )
    return 0


def run_all(
    categories: tuple[str, ...],
    tasks: tuple[str, ...],
    episodes: int,
    seed: int,
    log: Path | None = None,
) -> list[EpisodeRecord]:
    """Every (category, task, episode) in a plain loop, with a progress bar; seed by seed, so
    that an interrupted run (its ``log`` kept) has covered every category evenly."""
    jobs = [(c, t, seed + i) for i in range(episodes) for c in categories for t in tasks]
    records = []
    with Progress() as bar:
        task = bar.add_task("arm episodes", total=len(jobs))
        for concept, kind, s in jobs:
            config = EpisodeConfig(concept, kind, agent="arm")  # type: ignore[arg-type]
            record = run_episode(config, s)
            records.append(record)
            if log is not None:
                with log.open("a") as f:
                    f.write(json.dumps(record.to_json()) + "\n")
            bar.advance(task)
    return records


def read_log(path: Path) -> list[EpisodeRecord]:
    """The records of a ``--log`` file (an interrupted run's, too)."""
    records = []
    for line in path.read_text().splitlines():
        data = json.loads(line)
        config = data.pop("config")
        config["scale"] = tuple(config["scale"])
        data["q_range"] = tuple(data["q_range"])
        records.append(EpisodeRecord(config=EpisodeConfig(**config), **data))
    return records


if __name__ == "__main__":
    started = time.perf_counter()
    code = main()
    print(f"{time.perf_counter() - started:.0f} s")
    sys.exit(code)
