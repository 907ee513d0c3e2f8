"""The full verification of the standard library: every concept, 200 valid draws each.

Run: ``.venv/bin/python bench/bench_verify.py [--draws 200] [--seed 0] [--concepts NAME ...]
[--out FILE] [--smoke]`` (``make verify``). Prints one line per concept and writes
bench/results/verify.json: the time per concept, the draws made and accepted, the number of
checks evaluated per kind, the failures, the machine and the load. Exits 1 when a check fails,
like ``eacc verify``. ``--smoke``: two draws of three concepts (the test suite runs it).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.verify import concept_seed, verifiable, verify_concept

RESULTS = Path(__file__).resolve().parent / "results" / "verify.json"
SMOKE = ("CabinetDrawer", "RoundKnob", "LidBox")  # a joint with a part, a knob, a hinge


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--concepts", nargs="+", help="verify only these (default: every concept)")
    ap.add_argument("--out", type=Path, default=RESULTS, help="where the JSON goes")
    ap.add_argument("--smoke", action="store_true", help="2 draws of 3 concepts: checks it runs")
    args = ap.parse_args()
    if args.smoke:
        args.draws, args.concepts = 2, args.concepts or list(SMOKE)
    started = time.perf_counter()
    lib = eac.load_library()
    load = time.perf_counter() - started
    rows = []
    gripper = Gripper.panda()
    for name in args.concepts or verifiable(lib):
        t0 = time.perf_counter()
        report = verify_concept(lib[name], args.draws, concept_seed(args.seed, name), gripper)
        seconds = time.perf_counter() - t0
        checks = sum(report.evaluated.values())
        rows.append(
            {
                "concept": name,
                "seconds": round(seconds, 2),
                "draws": report.draws,
                "attempts": report.attempts,
                "checks": checks,
                "evaluated": report.evaluated,
                "failures": len(report.failures),
                "note": report.note,
            }
        )
        print(
            f"{name:16s} {seconds:6.1f} s  {report.draws:4d}/{report.attempts:5d} draws  "
            f"{checks:7d} checks  {len(report.failures)} failures {report.note}",
            flush=True,
        )
    total = time.perf_counter() - started
    summary = {
        "command": " ".join(["bench/bench_verify.py", *sys.argv[1:]]),
        "draws": args.draws,
        "seed": args.seed,
        "gripper": gripper.name,
        "concepts": len(rows),
        "checks": sum(r["checks"] for r in rows),
        "failures": sum(r["failures"] for r in rows),
        "seconds_load_library": round(load, 1),
        "seconds_total": round(total, 1),
        "median_seconds_per_concept": float(np.median([r["seconds"] for r in rows])),
        "machine": {
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_average": os.getloadavg(),
        },
        "per_concept": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    print(
        f"{summary['concepts']} concepts, {summary['checks']} checks, {summary['failures']} "
        f"failures in {total:.0f} s (library load {load:.0f} s) -> {args.out}"
    )
    return 1 if summary["failures"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
