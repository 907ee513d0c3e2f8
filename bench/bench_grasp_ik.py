"""Grasp IK on random instances of every library concept in front of the Panda.

For each concept, ``--draws`` instances with random parameters (the verifier's sampler, seeded)
are placed facing the robot at a random spot of a box in front of it (x 0.45-0.75 m, y ±0.3 m,
z 0.2-0.7 m). For every grasp family of the instance two solvers try to put the hand on it:

- ``fixed``: pose IK to the family's default grasp (its free parameters at their defaults);
- ``manifold``: grasp-manifold IK over the joints and the free parameters together.

An instance counts as reachable when some family is; the report gives both fractions, how many
instances only the manifold version reaches, and the time per instance.

    python bench/bench_grasp_ik.py               # 8 draws per concept (docs/benchmarks.md)
    python bench/bench_grasp_ik.py --smoke       # 1 draw of 3 concepts, no result file
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "grasp_ik.json"
FACING_ROBOT = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


def placement(rng: np.random.Generator) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = FACING_ROBOT
    m[:3, 3] = (rng.uniform(0.45, 0.75), rng.uniform(-0.3, 0.3), rng.uniform(0.2, 0.7))
    return m


def run(draws: int, seed: int, only: list[str] | None, quiet: bool) -> dict:
    from rich.progress import Progress

    import grace_dsl as eac
    from grace_dsl.robot.ik import IKOptions
    from grace_dsl.runtime.verify import draw_params, verifiable

    lib = eac.load_library()
    robot = eac.Robot.panda()
    names = only or [n for n in verifiable(lib) if lib[n].grasps]
    opts = IKOptions()
    rows = {}
    with Progress(transient=True, disable=quiet) as bar:
        task = bar.add_task("grasp IK", total=len(names) * draws)
        for name in names:
            rng = np.random.default_rng([seed, len(name), sum(map(ord, name))])
            fixed = manifold = only_manifold = 0
            seconds, cpu = [], []
            for _ in range(draws):
                inst = _instance(lib[name], rng, draw_params, placement)
                start, clock = time.perf_counter(), time.process_time()
                hit_m = any(
                    eac.solve_grasp_ik(robot, inst, g, options=opts).success
                    for g in inst.concept.grasps
                )
                seconds.append(time.perf_counter() - start)
                cpu.append(time.process_time() - clock)
                hit_f = any(
                    eac.solve_ik(robot, inst.grasp(g), options=opts).success
                    for g in inst.concept.grasps
                )
                fixed += hit_f
                manifold += hit_m
                only_manifold += hit_m and not hit_f
                bar.advance(task)
            rows[name] = {
                "draws": draws,
                "fixed": fixed,
                "manifold": manifold,
                "only_manifold": only_manifold,
                "median_ms": float(np.median(seconds) * 1e3),
                "cpu_median_ms": float(np.median(cpu) * 1e3),
            }
    total = draws * len(names)
    return {
        "draws_per_concept": draws,
        "concepts": len(names),
        "fixed": sum(r["fixed"] for r in rows.values()) / total,
        "manifold": sum(r["manifold"] for r in rows.values()) / total,
        "only_manifold": sum(r["only_manifold"] for r in rows.values()),
        "instances": total,
        "median_ms_per_instance": float(np.median([r["median_ms"] for r in rows.values()])),
        "cpu_median_ms_per_instance": float(np.median([r["cpu_median_ms"] for r in rows.values()])),
        "load_average": os.getloadavg()[0],
        "rows": rows,
    }


def _instance(concept, rng, draw_params, place):  # type: ignore[no-untyped-def]
    """A random valid instance: parameter draws that break a requirement are drawn again."""
    import grace_dsl as eac

    for _ in range(200):
        try:
            return concept.instantiate(pose=place(rng), **draw_params(concept, rng))
        except eac.RequirementError:
            continue
    return concept.instantiate(pose=place(rng))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--draws", type=int, default=None, help="per concept (8; --smoke 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="*", default=None, help="concept names")
    ap.add_argument("--smoke", action="store_true", help="no result file")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help=f"result file (default {RESULTS})")
    args = ap.parse_args(argv)
    if args.smoke:
        args.draws = args.draws or 1
        args.only = args.only or ["CabinetDrawer", "SunkenDoor", "RoundKnob"]
    report = run(args.draws or 8, args.seed, args.only, args.json)
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(
            f"{report['instances']} instances of {report['concepts']} concepts: some grasp reached "
            f"by fixed-grasp IK {report['fixed'] * 100:.1f}%, by grasp-manifold IK "
            f"{report['manifold'] * 100:.1f}% ({report['only_manifold']} only by the manifold); "
            f"median {report['median_ms_per_instance']:.1f} ms per instance (manifold, all grasps; "
            f"CPU {report['cpu_median_ms_per_instance']:.1f} ms; load {report['load_average']:.1f})"
        )
    out = args.out or (None if args.smoke else RESULTS)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
