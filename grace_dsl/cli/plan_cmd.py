"""``grace plan CONCEPT --action open``: plan an action for the Panda in a default scene; show it.

The instance (default parameters) stands in front of the robot facing it
(``grace_dsl.robot.placement``); ``--base X,Y,YAW`` moves the robot instead. The summary names the
grasp chosen and its free parameters, the phases with their times, and the gripper's commands;
``--json`` prints the same and the whole trajectory; ``--png`` draws the arm at the key frames,
``--html`` writes the viewer with the trajectory playable. Every error a user can cause (an
unknown concept or action, a bad number, an action this placement cannot do) is one line and
exit code 1.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.cli.files import atomic_write, staged
from grace_dsl.cli.output import error, print_json, print_text
from grace_dsl.cli.units import UnitSyntaxError, quantity
from grace_dsl.runtime.errors import GraceError, ParameterError

PNG_SIZE = (1200, 900)
DEFAULT_FRACTION = 0.9  # of the joint's range, the default --to (a range's very end is a stop)
SHORTFALL = 0.95  # of the value reached, the retry when the default --to is out of reach


def add_plan_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("concept", help="a concept of the standard library, e.g. SunkenDoor")
    p.add_argument("--action", default="open", help="the action to plan (default open)")
    p.add_argument(
        "--to",
        metavar="Q",
        help="the joint value to move to (rad or 45deg; m or 100mm); default: 90%% of its range, "
        "or as far as this placement allows",
    )
    p.add_argument(
        "--base", metavar="X,Y,YAW", help="the robot base on the floor (m, m, rad or 30deg)"
    )
    p.add_argument("--seed", type=int, default=0, help="for IK restarts and the planner (0)")
    p.add_argument("--png", metavar="FILE", help="the arm at pre-grasp, grasp, mid and end")
    p.add_argument("--html", metavar="FILE", help="a viewer page with the trajectory playable")
    p.add_argument("--json", action="store_true", help="print the plan and trajectory as JSON")


def run_plan(args: Any) -> int:
    """The body of ``grace plan``; 0 on success, 1 with one line on stderr otherwise."""
    try:
        return _run(args)
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        return 1


def _run(args: Any) -> int:
    import grace_dsl as eac
    from grace_dsl.robot.act import plan_action
    from grace_dsl.robot.placement import base_pose, default_instance

    concept = eac.load_library()[args.concept]  # an unknown name: UnknownNameError, suggesting
    robot = eac.Robot.panda()
    inst = default_instance(robot, concept, args.action)
    to = _joint_value(concept, args.action, args.to)
    base = base_pose(*_base(args.base)) if args.base else None
    started = time.perf_counter()
    if to is None:
        plan = _as_far_as_allowed(robot, inst, args.action, base, args.seed)
    else:
        plan = plan_action(robot, inst, args.action, to=to, base=base, seed=args.seed)
    seconds = time.perf_counter() - started
    written = []
    if args.png:
        from grace_dsl.render.robot import write_plan_png

        png = Path(args.png)
        staged(png, lambda p: write_plan_png(robot, inst, plan, p, *PNG_SIZE))
        written.append(str(png))
    if args.html:
        from grace_dsl.render.html import scene_html
        from grace_dsl.render.robot import plan_animation

        scene, animation = plan_animation(robot, inst, plan)
        atomic_write(args.html, scene_html(scene, _headline(inst, args.action, plan), animation))
        written.append(str(args.html))
    if args.json:
        print_json({**summary(robot, inst, args.action, plan, seconds), "written": written})
    else:
        print_text(_text(inst, args.action, plan, seconds, written))
    return 0


def _as_far_as_allowed(robot: Any, inst: Any, action: str, base: Any, seed: int) -> Any:
    """The default ``--to``: ``DEFAULT_FRACTION`` of the joint's range the action drives along;
    when this placement cannot get that far, ``SHORTFALL`` of the value the failed plan reached
    (its error says where it stopped). An action that moves no joint: its push."""
    from grace_dsl.robot.act import ActionPlanningError, plan_action

    joint = inst.concept.actions[action].joint
    if joint is None:
        return plan_action(robot, inst, action, base=base, seed=seed)
    lo, hi = inst.joint_limits()[joint]
    start = float(inst.joints[joint])
    end = hi if inst.concept.actions[action].opening else lo
    try:
        return plan_action(
            robot, inst, action, to=start + DEFAULT_FRACTION * (end - start), base=base, seed=seed
        )
    except ActionPlanningError as exc:
        if exc.value is None or abs(exc.value - start) < 1e-6:
            raise
        reached = start + SHORTFALL * (exc.value - start)
    return plan_action(robot, inst, action, to=reached, base=base, seed=seed)


def _joint_value(concept: Any, action: str, text: str | None) -> float | None:
    if text is None:
        return None
    spec = concept.actions.get(action)
    joint = None if spec is None else spec.joint
    kind = concept.joints[joint].kind if joint is not None else None
    dim = "length" if kind == "prismatic" else "angle"
    try:
        return quantity(text, dim)
    except UnitSyntaxError as exc:
        raise ParameterError(f"--to takes a number ({dim}): {exc}") from None


def _base(text: str) -> tuple[float, float, float]:
    parts = [p for p in text.replace(",", " ").split() if p]
    if len(parts) != 3:
        raise ParameterError(f"--base takes X,Y,YAW (three numbers), not {text!r}")
    try:
        x, y, yaw = (quantity(p, d) for p, d in zip(parts, ("length", "length", "angle")))
    except UnitSyntaxError as exc:
        raise ParameterError(f"--base takes X,Y,YAW in m, m and rad (or deg): {exc}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ParameterError(f"--base: every number must be finite, not {text!r}")
    return x, y, yaw


def summary(robot: Any, inst: Any, action: str, plan: Any, seconds: float) -> dict[str, Any]:
    """The plan, JSON-ready: grasp and free parameters, phases, gripper, trajectory."""
    ik = plan.choice.ik
    return {
        "concept": inst.concept.name,
        "action": action,
        "joint": plan.joint,
        "to": plan.to,
        "grasp": plan.choice.option.grasp,
        "mode": plan.choice.option.mode,
        "free": dict(ik.free),
        "spin": ik.spin if _symmetric(inst, plan) else None,
        "margin": plan.choice.margin,
        "rejected": [{"grasp": g, "reason": r} for g, r in plan.choice.rejected],
        "base": plan.base.tolist(),
        "instance_pose": inst.pose.tolist(),
        "duration": plan.duration,
        "phases": [
            {"phase": name, "start": plan.span(name)[0], "end": plan.span(name)[1]}
            for name, _, _ in plan.phases
        ],
        "gripper": [{"time": t, "width": w} for t, w in plan.gripper],
        "planning_seconds": {**dict(plan.seconds), "total": seconds},
        "trajectory": {
            "joints": list(robot.joint_names),
            "t": plan.t.tolist(),
            "q": np.round(plan.q, 6).tolist(),
            "object_joint": np.round(plan.joint_values, 6).tolist(),
        },
    }


def _symmetric(inst: Any, plan: Any) -> bool:
    return bool(inst.concept.grasps[plan.choice.option.grasp].symmetric)


def _headline(inst: Any, action: str, plan: Any) -> str:
    goal = f" to {plan.joint} = {plan.to:.3g}" if plan.joint and plan.to is not None else ""
    return (
        f"{action}{goal} with {plan.choice.option.grasp} ({plan.choice.option.mode}), "
        f"{plan.duration:.2f} s"
    )


def _text(inst: Any, action: str, plan: Any, seconds: float, written: list[str]) -> str:
    ik = plan.choice.ik
    free = ", ".join(f"{k} = {v:.3f}" for k, v in ik.free.items()) or "none"
    lines = [
        f"{inst.concept.name}: {_headline(inst, action, plan)}; free parameters {free}"
        + (f", spin {ik.spin:.3f} rad" if _symmetric(inst, plan) else "")
    ]
    for name, start, stop in plan.phases:
        begin, end = plan.span(name)
        lines.append(f"  {name:<9} {begin:6.2f} - {end:6.2f} s  ({stop - start} samples)")
    grip = ", ".join(f"{w * 1000:.0f} mm at {t:.2f} s" for t, w in plan.gripper)
    lines.append(f"  gripper: {grip}")
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in plan.seconds)
    lines.append(f"  planned in {seconds:.2f} s ({stages})")
    if written:
        lines.append(f"  -> {', '.join(written)}")
    return "\n".join(lines)
