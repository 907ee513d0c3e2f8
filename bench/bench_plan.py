"""Planning whole actions on the library's concepts with the Panda, and the collision checks' cost.

Every concept with an ``open`` action, at its default parameters, stands in the default scene
(``grace_dsl.robot.placement``: facing the robot, the action's grasps 0.6 m ahead at 0.5 m);
``--seeds`` starting base placements per concept (seed 0 the default, others moved by up to 5 cm
and 0.15 rad, seeded); ``plan_placed`` opens it to ``--fraction`` of its joint's range from the
first of ``--placements`` base poses that can (the starting one first; the figures report how
often that alone worked):

- approach: the grasp is chosen, the pre-grasp pose reached and a collision-free path found
  (success rate and planning time, grasp choice included);
- action: the whole trajectory (approach, insert, interact, retreat) planned, collision-checked
  through the interaction and timed (success rate, planning time, trajectory duration), with the
  reasons of the failures.

Then the cost of one collision query per configuration: the median microseconds of
``collides(q)`` and ``distance(q)`` over seeded random configurations, for the robot alone and
with each concept's instance.

    python bench/bench_plan.py                # every concept, 2 seeds, 0.3 of the range
    python bench/bench_plan.py --smoke        # 2 concepts, 1 seed, no result file
    python bench/bench_plan.py --fraction 1 --placements 1 --seeds 1 --out F   # how far each
                                              # concept opens from the default placement
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "plan.json"


def plan_concepts(
    names: list[str], seeds: int, fraction: float, quiet: bool, placements: int = 12
) -> dict:
    import grace_dsl as eac
    from grace_dsl.robot.placement import default_instance, jitter, plan_placed

    lib = eac.load_library()
    robot = eac.Robot.panda()
    rows = []
    for name in names:
        concept = lib[name]
        inst = default_instance(robot, concept, "open")
        joint = concept.actions["open"].joint
        lo, hi = inst.joint_limits()[joint] if joint else (0.0, 0.0)
        to = lo + fraction * (hi - lo) if joint else None
        for seed in range(seeds):
            start = time.perf_counter()
            row = {"concept": name, "seed": seed, "to": to}
            try:
                placed = plan_placed(
                    robot, inst, "open", to, base=jitter(seed), seed=seed, count=placements
                )
            except eac.GraceError as exc:
                phase = getattr(exc, "phase", "") or "grasp"
                row.update(ok=False, approach=phase not in ("grasp", "pre-grasp", "approach"))
                row.update(phase=phase, reason=getattr(exc, "reason", "") or "no grasp")
                row["error"] = str(exc)[:300]
                row["value"] = getattr(exc, "value", None)  # the joint value reached
            else:
                plan = placed.plan
                stages = dict(plan.seconds)
                row.update(ok=True, approach=True, grasp=plan.choice.option.grasp)
                row.update(placements_tried=placed.tried)
                row["approach_s"] = stages["grasp"] + stages["approach"]
                row["duration_s"] = plan.duration
                row["stages_s"] = stages
            if joint:  # how far it was opened (planned) or could be (the failure's value)
                value = to if row["ok"] else row["value"]
                row["reached"] = 0.0 if value is None else abs(value - lo) / (hi - lo)
            row["seconds"] = time.perf_counter() - start
            rows.append(row)
            if not quiet:
                verdict = (
                    f"ok (placement {row['placements_tried']})"
                    if row["ok"]
                    else f"{row['phase']}: {row['reason']}"
                )
                print(f"  {name:<16} seed {seed}: {verdict} ({row['seconds']:.1f} s)", flush=True)
    return _summary(rows)


def _summary(rows: list[dict]) -> dict:
    ok = [r for r in rows if r["ok"]]
    approach = [r for r in rows if r["approach"]]
    return {
        "plans": len(rows),
        "approach_success": len(approach) / len(rows),
        "action_success": len(ok) / len(rows),
        "first_placement_success": sum(r.get("placements_tried") == 1 for r in rows) / len(rows),
        "median_approach_s": statistics.median(r["approach_s"] for r in ok) if ok else None,
        "median_action_s": statistics.median(r["seconds"] for r in ok) if ok else None,
        "max_action_s": max((r["seconds"] for r in ok), default=None),
        "median_trajectory_s": statistics.median(r["duration_s"] for r in ok) if ok else None,
        "failures": dict(Counter(f"{r['phase']}: {r['reason']}" for r in rows if not r["ok"])),
        "reached": _reached(rows),
        "rows": rows,
    }


def _reached(rows: list[dict]) -> dict:
    """Per concept, the largest fraction of its joint's range opened or reached before failing
    (a plan to the range's end, ``--fraction 1``, measures how far each can be opened)."""
    out: dict[str, float] = {}
    for r in rows:
        if "reached" in r:
            out[r["concept"]] = max(out.get(r["concept"], 0.0), r["reached"])
    return out


def collision_cost(names: list[str], configurations: int, seed: int) -> dict:
    import grace_dsl as eac
    from grace_dsl.robot.collision import collision_scene
    from grace_dsl.robot.placement import default_instance

    lib = eac.load_library()
    robot = eac.Robot.panda()
    rng = np.random.default_rng(seed)
    qs = [robot.random_q(rng) for _ in range(configurations)]
    scenes = {"robot alone": collision_scene(robot)}
    for name in names:
        scenes[name] = collision_scene(robot, default_instance(robot, lib[name], "open"))
    out = {}
    for label, scene in scenes.items():
        row = {}
        for query in ("collides", "distance"):
            fn = getattr(scene, query)
            fn(qs[0])  # warm
            times = []
            for q in qs:
                start = time.perf_counter()
                fn(q)
                times.append(time.perf_counter() - start)
            row[f"{query}_us"] = statistics.median(times) * 1e6
        row["pairs"] = len(scene.geometry.collisionPairs)
        out[label] = row
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seeds", type=int, default=None, help="base placements per concept (2)")
    ap.add_argument("--fraction", type=float, default=0.3, help="of the joint range (0.3)")
    ap.add_argument(
        "--placements", type=int, default=12, help="base poses tried per plan (12; 1: no search)"
    )
    ap.add_argument("--configs", type=int, default=None, help="per collision scene (20)")
    ap.add_argument("--only", nargs="*", default=None, help="concept names")
    ap.add_argument("--smoke", action="store_true", help="no result file")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help=f"result file (default {RESULTS})")
    args = ap.parse_args(argv)
    import grace_dsl as eac

    lib = eac.load_library()
    names = args.only or [n for n in lib if "open" in lib[n].actions]
    if args.smoke:
        names = args.only or ["CabinetDrawer", "SunkenDoor"]
    seeds = args.seeds or (1 if args.smoke else 2)
    started = time.perf_counter()
    report = plan_concepts(names, seeds, args.fraction, args.quiet, args.placements)
    report["collision"] = collision_cost(names, args.configs or (5 if args.smoke else 20), seed=0)
    report.update(concepts=names, seeds=seeds, fraction=args.fraction, placements=args.placements)
    report["wall_s"] = time.perf_counter() - started
    print(
        f"{report['plans']} plans ({len(names)} concepts x {seeds} seeds, opened to "
        f"{args.fraction:g} of the range): approach {report['approach_success'] * 100:.0f}%, "
        f"whole action {report['action_success'] * 100:.0f}% (from the first base placement "
        f"{report['first_placement_success'] * 100:.0f}%); median planning "
        f"{_s(report['median_approach_s'])} per approach, {_s(report['median_action_s'])} per "
        f"action; median trajectory {_s(report['median_trajectory_s'])}"
    )
    reached = sorted(report["reached"].values())
    if reached:
        quartiles = np.percentile(reached, [0, 25, 50, 75, 100])
        print(
            "  fraction of the range reached per concept (min, quartiles, max): "
            + ", ".join(f"{v:.2f}" for v in quartiles)
        )
    for label, row in report["collision"].items():
        print(
            f"  {label:<16} collides {row['collides_us']:7.0f} us   distance "
            f"{row['distance_us']:7.0f} us   ({row['pairs']} pairs)"
        )
    out = args.out or (None if args.smoke else RESULTS)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=1, default=float) + "\n")
    return 0


def _s(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f} s"


if __name__ == "__main__":
    sys.exit(main())
