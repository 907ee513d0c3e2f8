"""Pose IK on the Panda: grace_dsl's sequential QP against pin-pink and mink, same targets.

Targets are the forward kinematics of seeded random configurations within the joint limits, so
every one is reachable. Every solver must reach 1 mm and 1 degree, checked by an independent
forward-kinematics call (Pinocchio's, on the returned joint values). pink (Pinocchio) and mink
(MuJoCo, the same URDF) integrate their frame task from the Panda's home pose for at most 200
steps; both solve their QPs with OSQP, and mink also with daqp, the solver it installs with.
grace_dsl's ``solve_ik`` starts from its seed bank (built on the first call, inside the timing).
Times are wall-clock per target; the CPU time of the process is reported beside them, since the
machine is shared.

    python bench/bench_ik.py                 # 1,000 targets (docs/benchmarks.md)
    python bench/bench_ik.py --smoke         # 20 targets, no result file, no targets enforced
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "bench" / "results" / "ik.json"


@dataclass(frozen=True)
class Figures:
    solver: str
    targets: int
    success: float
    median_ms: float
    p99_ms: float
    max_ms: float
    cpu_median_ms: float
    cpu_p99_ms: float


def targets(robot, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [robot.fk(robot.random_q(rng)) for _ in range(n)]


def within(robot, q: np.ndarray, target: np.ndarray) -> bool:
    """1 mm and 1 degree, measured with a fresh forward-kinematics call."""
    pose = robot.fk(q)
    cos = (np.trace(target[:3, :3].T @ pose[:3, :3]) - 1) / 2
    angle = math.acos(min(1.0, max(-1.0, cos)))
    return bool(np.linalg.norm(pose[:3, 3] - target[:3, 3]) <= 1e-3 and angle <= math.radians(1))


def grace_solver(robot) -> Callable[[np.ndarray, int], np.ndarray]:
    from grace_dsl.robot.ik import solve_ik

    return lambda target, seed: solve_ik(robot, target, seed=seed).q


def pink_solver(robot, max_iterations: int = 200) -> Callable[[np.ndarray, int], np.ndarray]:
    """pin-pink's frame task from the home pose, integrated until within tolerance (OSQP)."""
    import logging
    import warnings

    import pink
    import pinocchio as pin
    from pink.tasks import FrameTask

    logging.getLogger().setLevel(logging.ERROR)  # pink logs every clipped joint value
    warnings.filterwarnings("ignore", module="qpsolvers")

    frame = robot.model.frames[robot.tcp_frame].name
    dt = 0.1

    def solve(target: np.ndarray, seed: int) -> np.ndarray:
        config = pink.Configuration(robot.model, robot.model.createData(), robot.home.copy())
        task = FrameTask(frame, position_cost=1.0, orientation_cost=1.0, lm_damping=1e-4)
        task.set_target(pin.SE3(target[:3, :3], target[:3, 3]))
        for _ in range(max_iterations):
            err = task.compute_error(config)
            if np.linalg.norm(err[:3]) <= 1e-3 and np.linalg.norm(err[3:]) <= math.radians(1):
                break
            velocity = pink.solve_ik(config, [task], dt, solver="osqp", safety_break=False)
            config.integrate_inplace(velocity, dt)
        return np.clip(config.q, robot.lower, robot.upper)

    return solve


def panda_mjcf(robot):  # type: ignore[no-untyped-def]
    """The Panda as a MuJoCo model for mink: example-robot-data's URDF (the one ``robot`` was
    loaded from) without its meshes (MuJoCo reads no .dae; kinematics is what matters), the
    fingers fixed (they do not move the TCP), fixed links kept as bodies and a site ``tcp`` on
    ``panda_hand_tcp``: the same TCP as ``Robot.panda()`` (tests/bench/test_mink_model.py)."""
    import xml.etree.ElementTree as ET

    import mujoco

    root = ET.parse(robot.urdf).getroot()
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    for joint in root.findall("joint"):
        if "finger" in joint.get("name", ""):
            joint.set("type", "fixed")
            for tag in ("limit", "axis", "mimic", "dynamics", "safety_controller"):
                for element in joint.findall(tag):
                    joint.remove(element)
    ET.SubElement(ET.SubElement(root, "mujoco"), "compiler", fusestatic="false")
    spec = mujoco.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    spec.body("panda_hand_tcp").add_site(name="tcp")
    return spec.compile()


def mink_solver(
    robot, solver: str = "osqp", max_iterations: int = 200
) -> Callable[[np.ndarray, int], np.ndarray]:
    """mink's frame task on the MuJoCo model of the same Panda, from the home pose, integrated
    until within tolerance: the same budget and gains as :func:`pink_solver`."""
    import logging
    import warnings

    import mink

    logging.getLogger().setLevel(logging.ERROR)  # mink warns on every clipped joint value
    warnings.filterwarnings("ignore", module="qpsolvers")
    model = panda_mjcf(robot)
    site = model.site("tcp").id
    dt = 0.1

    def solve(target: np.ndarray, seed: int) -> np.ndarray:
        config = mink.Configuration(model, robot.home.copy())
        task = mink.FrameTask(
            "tcp", "site", position_cost=1.0, orientation_cost=1.0, lm_damping=1e-4
        )
        task.set_target(mink.SE3.from_matrix(target))
        limits = [mink.ConfigurationLimit(model)]
        for _ in range(max_iterations):
            data = config.data
            rot = data.site_xmat[site].reshape(3, 3)
            cos = (np.trace(target[:3, :3].T @ rot) - 1) / 2
            if np.linalg.norm(data.site_xpos[site] - target[:3, 3]) <= 1e-3 and math.acos(
                min(1.0, max(-1.0, cos))
            ) <= math.radians(1):
                break
            velocity = mink.solve_ik(config, [task], dt, solver=solver, limits=limits)
            config.integrate_inplace(velocity, dt)
        return np.clip(config.q, robot.lower, robot.upper)

    return solve


def measure(name: str, robot, solve, goals: list[np.ndarray], quiet: bool) -> Figures:
    from rich.progress import Progress

    times, cpu, ok = [], [], 0
    with Progress(transient=True, disable=quiet) as bar:
        task = bar.add_task(name, total=len(goals))
        for i, target in enumerate(goals):
            start, clock = time.perf_counter(), time.process_time()
            q = solve(target, i)
            times.append(time.perf_counter() - start)
            cpu.append(time.process_time() - clock)
            ok += within(robot, q, target)
            bar.advance(task)
    ms, cpu_ms = np.asarray(times) * 1e3, np.asarray(cpu) * 1e3
    return Figures(
        name,
        len(goals),
        ok / len(goals),
        float(np.median(ms)),
        float(np.percentile(ms, 99)),
        float(ms.max()),
        float(np.median(cpu_ms)),
        float(np.percentile(cpu_ms, 99)),
    )


SOLVERS = {
    "grace_dsl": grace_solver,
    "pin-pink (osqp)": pink_solver,
    "mink (osqp)": lambda robot: mink_solver(robot, "osqp"),
    "mink (daqp)": lambda robot: mink_solver(robot, "daqp"),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--n", type=int, default=None, help="number of targets (1000; --smoke 20)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--smoke", action="store_true", help="no result file, no targets enforced")
    ap.add_argument(
        "--solvers", default=",".join(SOLVERS), help=f"comma-separated, of: {', '.join(SOLVERS)}"
    )
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help=f"result file (default {RESULTS})")
    args = ap.parse_args(argv)
    args.n = args.n or (20 if args.smoke else 1000)
    names = [n.strip() for n in args.solvers.split(",") if n.strip()]
    unknown = [n for n in names if n not in SOLVERS]
    if unknown:
        ap.error(f"unknown solver(s) {unknown}; choose from {list(SOLVERS)}")

    from grace_dsl.robot.model import Robot

    robot = Robot.panda()
    goals = targets(robot, args.n, args.seed)
    load = [os.getloadavg()[0]]
    rows, missing = [], []
    for name in names:
        try:
            solve = SOLVERS[name](robot)
        except ImportError as exc:  # pink and mink come with the dev extra
            missing.append(f"{name}: {exc}")
            continue
        rows.append(measure(name, robot, solve, goals, args.json))
        load.append(os.getloadavg()[0])
    report = {
        "targets": args.n,
        "seed": args.seed,
        "load_average": load,  # 1-minute load before the first solver and after each
        "missing": missing,
        "rows": [asdict(r) for r in rows],
    }
    if args.json:
        print(json.dumps(report, indent=1))
    else:
        print(f"Panda pose IK, {args.n} random reachable targets, 1 mm / 1 degree")
        for r in rows:
            print(
                f"  {r.solver:16} success {r.success * 100:6.2f}%  median {r.median_ms:7.2f} ms"
                f"  p99 {r.p99_ms:7.2f} ms  max {r.max_ms:7.1f} ms"
                f"  (CPU median {r.cpu_median_ms:.2f} ms, p99 {r.cpu_p99_ms:.2f} ms)"
            )
        for m in missing:
            print(f"  skipped {m}")
        print(f"  load average {' -> '.join(f'{x:.1f}' for x in load)}")
    out = args.out or (None if args.smoke else RESULTS)
    if out is not None:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=1) + "\n")
    if args.smoke or not rows or rows[0].solver != "grace_dsl":
        return 0  # a smoke run proves the script works; its timings mean nothing
    ours = rows[0]
    met = ours.success >= 0.995 and ours.median_ms <= 2.0 and ours.p99_ms <= 20.0
    return 0 if met else 1


if __name__ == "__main__":
    sys.exit(main())
