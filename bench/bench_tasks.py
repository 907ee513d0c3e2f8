"""The long-horizon task suite: parse accuracy and task success in MuJoCo (issue 15's targets).

Run: ``.venv/bin/python bench/bench_tasks.py [--ids ID ...] [--out FILE] [--small] [--agent arm]``
(writes bench/results/tasks.json; with ``--agent arm``, bench/results/tasks_arm.json). Every
suite task is parsed by the offline parser in its shipped scene and compared with its expected
plan (parse accuracy), then executed by the flying Panda hand (``--agent arm``: the full Panda
on a base placed beside each object in turn) with oracle parameters in a fresh world of the
scene and verified (task success: every sub-task's condition held when checked, and each joint's
last condition at the end). ``--small`` (also
``--smoke``): two tasks, a one-step and a three-step one. ``grace bench --suite tasks`` runs the
same function.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "osmesa")

from grace_dsl.agent.suite import load_suite  # noqa: E402
from grace_dsl.agent.task_bench import SMALL, TaskReport, TaskRun, run_tasks  # noqa: E402
from grace_dsl.runtime.library import Library, load_library  # noqa: E402

OUT = Path(__file__).parent / "results" / "tasks.json"
ARM_OUT = OUT.with_name("tasks_arm.json")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ids", nargs="+", help="suite task ids (default: all)")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--small", "--smoke", action="store_true", help=f"tasks {SMALL} only")
    parser.add_argument(
        "--agent", choices=("gripper", "arm"), default="gripper", help="flying hand or full arm"
    )
    parser.add_argument(
        "--log",
        type=Path,
        help="a JSON-lines log: one task per line, written as each ends; "
        "a run with the same log skips the tasks it holds (resume)",
    )
    args = parser.parse_args()
    ids = list(SMALL) if args.small else args.ids
    out = args.out if args.out != OUT or args.agent == "gripper" else ARM_OUT
    lib = load_library()
    report = (
        _logged(lib, ids, args.agent, args.log)
        if args.log
        else run_tasks(lib, ids=ids, progress=sys.stderr.isatty(), agent=args.agent)
    )
    print(report.table())
    result = {
        **report.to_json(),
        "command": " ".join(["bench/bench_tasks.py", *sys.argv[1:]]),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 0


def _logged(lib: Library, ids: list[str] | None, agent: str, log: Path) -> TaskReport:
    """The tasks one at a time, each appended to ``log`` as it ends; those already in ``log``
    are taken from it, not run again."""
    done = {}
    if log.is_file():
        for line in log.read_text(encoding="utf-8").splitlines():
            if line.strip():
                run = TaskRun(**json.loads(line))
                done[run.id] = run
    todo = ids or [t.id for t in load_suite()]
    started = time.perf_counter()
    log.parent.mkdir(parents=True, exist_ok=True)
    for task in todo:
        if task in done:
            continue
        run = run_tasks(lib, ids=[task], progress=False, agent=agent).runs[0]
        with log.open("a", encoding="utf-8") as f:
            f.write(json.dumps(asdict(run)) + "\n")
        done[task] = run
        print(f"{task}: {'ok' if run.success else run.problem}", flush=True)
    runs = tuple(done[t] for t in todo if t in done)
    return TaskReport(runs, "offline", time.perf_counter() - started, agent)


if __name__ == "__main__":
    raise SystemExit(main())
