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
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "osmesa")

from grace_dsl.agent.task_bench import SMALL, run_tasks  # noqa: E402
from grace_dsl.runtime.library import load_library  # noqa: E402

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
    args = parser.parse_args()
    ids = list(SMALL) if args.small else args.ids
    out = args.out if args.out != OUT or args.agent == "gripper" else ARM_OUT
    report = run_tasks(load_library(), ids=ids, progress=sys.stderr.isatty(), agent=args.agent)
    print(report.table())
    result = {
        **report.to_json(),
        "command": " ".join(["bench/bench_tasks.py", *sys.argv[1:]]),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores",
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
