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
    python bench/bench_sim_arm.py --episodes 10 --workers 2 --log arm.jsonl   # resumable
    python bench/bench_sim_arm.py --fixed-base ...   # the base never moves between stages

With ``--log``, episodes already in the log are not run again (an interrupted run resumes) and
the table covers every requested episode of the log.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_sim import (  # noqa: E402
    CATEGORIES,
    SMALL,
    TASKS,
    episode_seed,
    print_table,
    summarize,
)

from grace_dsl.sim.arm_episode import run_arm_episode_fixed_base  # noqa: E402
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord  # noqa: E402
from grace_dsl.sim.runner import run_episodes  # noqa: E402

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
    ap.add_argument(
        "--log", type=Path, default=None, help="append each record here (JSON lines); resumes"
    )
    ap.add_argument("--workers", type=int, default=1, help="episodes in parallel (processes)")
    ap.add_argument(
        "--fixed-base",
        action="store_true",
        help="keep the base where the first stage put it (the figure before bases moved)",
    )
    ap.add_argument(
        "--like",
        type=Path,
        default=None,
        help="with --fixed-base: take from this log (a run with moving bases) every episode it "
        "ended in one stage without planning a second (the flag changes nothing there)",
    )
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
        reuse = one_stage(read_log(args.like)) if args.like is not None and args.fixed_base else {}
        records = run_all(
            categories, tasks, episodes, args.seed, args.log, args.workers, args.fixed_base, reuse
        )
    summary = summarize(records)
    print_table(summary)
    out = args.out or RESULTS
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(
        json.dumps(
            {
                "command": " ".join(["python bench/bench_sim_arm.py", *(argv or sys.argv[1:])]),
                "agent": "arm",
                "fixed_base": args.fixed_base,
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
    workers: int = 1,
    fixed_base: bool = False,
    reuse: dict[tuple[str, str, int], EpisodeRecord] | None = None,
) -> list[EpisodeRecord]:
    """Every (category, task, episode), seed by seed (so that an interrupted run, its ``log``
    kept, has covered every category evenly), on ``workers`` processes with a progress bar.
    Episodes already in ``log`` or in ``reuse`` are taken from there, not run again."""
    jobs = [
        (c, t, episode_seed(seed, i)) for i in range(episodes) for c in categories for t in tasks
    ]
    done = {_key(r): r for r in read_log(log)} if log is not None and log.exists() else {}
    done = {**(reuse or {}), **done}
    todo = [
        (EpisodeConfig(c, t, agent="arm"), s)  # type: ignore[arg-type]
        for c, t, s in jobs
        if (c, t, s) not in done
    ]

    def write(_: int, record: EpisodeRecord) -> None:
        done[_key(record)] = record
        if log is not None:
            with log.open("a") as f:
                f.write(json.dumps(record.to_json()) + "\n")

    fn = run_arm_episode_fixed_base if fixed_base else None
    run_episodes(todo, fn=fn, workers=workers, warm=True, on_record=write)
    return [done[job] for job in jobs]


def one_stage(records: list[EpisodeRecord]) -> dict[tuple[str, str, int], EpisodeRecord]:
    """The records of a run with moving bases that a fixed base would repeat exactly: those
    that ended after one stage (or none) without planning a second (a base moves only for a
    later stage; a later stage that could not be planned says so, ``stage N:``, in the
    detail)."""
    return {k: r for k, r in ((_key(r), r) for r in records) if _single(r)}


def _single(record: EpisodeRecord) -> bool:
    return len(record.bases) <= 1 and not record.detail.startswith("stage ")


def _key(record: EpisodeRecord) -> tuple[str, str, int]:
    return record.config.concept, record.config.task, record.seed


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
