"""Grasp selection: the paper's choice of manipulation function, done with the robot in the loop.

``choose_grasp`` takes the action's manipulation functions that ``inst.rank`` calls feasible for
the robot's hand, solves grasp-manifold IK for each (arm and palm clear of everything, fingers
allowed on the object) and keeps the reachable one with the best margin:

    margin = min_i min(q_i − lo_i, hi_i − q_i) / (hi_i − lo_i)  +  ½ · m_f

the first term the normalized distance to the nearest joint limit (0 at a limit, ½ mid-range),
``m_f = (fᵀ (J_v J_vᵀ)⁻¹ f)^(−½)`` the hand's velocity manipulability along the action's force
direction ``f`` (metres per second per unit joint speed; how freely the arm can follow the pull).
Options that lose say why.

One IK solution per option is one arm posture among many: the same grasp is reached with the
elbow up or down, the wrist turned either way, and the free parameters elsewhere, and an action
that must then follow a path may be feasible from one and run into a joint limit from another.
``grasp_candidates`` therefore solves each option from several starts (home, then the seed
bank's configurations whose gripper lies nearest the grasp) and returns every distinct solution,
best margin first; ``plan_action`` tries them in that order until one carries the whole action.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.grasp_ik import GraspIKResult, solve_grasp_ik
from grace_dsl.robot.ik import IKOptions
from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.robot.seeds import seed_bank
from grace_dsl.runtime.errors import GraceError

FloatArray = np.ndarray
STARTS = 6  # IK starts per option beyond home: the seed bank's nearest configurations
DISTINCT = 0.3  # radians on some joint between two candidates that count as different postures
FINGERS = ("panda_leftfinger", "panda_rightfinger")


class NoGraspError(GraceError):
    """No manipulation function of the action is both feasible for the hand and reachable."""


@dataclass(frozen=True)
class GraspChoice:
    """The chosen option of ``inst.rank``, its IK, its margin and why every other option lost."""

    option: Any  # grace_dsl.runtime.manipulation.Option
    ik: GraspIKResult
    margin: float
    rejected: tuple[tuple[str, str], ...]  # (grasp, reason)


def choose_grasp(
    robot: Robot,
    inst: Any,
    action: str,
    *,
    base: Any = None,
    seed: int = 0,
    options: IKOptions | None = None,
    fingers: Sequence[str] = FINGERS,
) -> GraspChoice:
    """The best reachable manipulation function of ``action`` (see the module docstring).

    Raises :class:`NoGraspError` listing every option's reason when none is usable.
    """
    found, rejected = grasp_candidates(
        robot, inst, action, base=base, seed=seed, options=options, fingers=fingers, starts=0
    )
    best = found[0]
    lost = [(c.option.grasp, f"smaller margin ({c.margin:.3f})") for c in found[1:]]
    return GraspChoice(best.option, best.ik, best.margin, tuple(rejected + lost))


def grasp_candidates(
    robot: Robot,
    inst: Any,
    action: str,
    *,
    base: Any = None,
    seed: int = 0,
    options: IKOptions | None = None,
    fingers: Sequence[str] = FINGERS,
    starts: int = STARTS,
    obstacles: Sequence[Any] = (),
    grasps: Sequence[str] | None = None,
    to: float | None = None,
    also: Sequence[str] = (),
) -> tuple[list[GraspChoice], list[tuple[str, str]]]:
    """Every distinct reachable, collision-free solution of the action's feasible options (from
    home, then from ``starts`` seed-bank configurations near the option's grasp), best margin
    first, and the options that gave none with their reasons. Raises :class:`NoGraspError`
    when there is no solution at all. ``obstacles``: other posed instances to keep clear of
    (``collision_scene``); ``grasps``: only these options (an agent's retry skips the ones it
    has tried); ``to``: the joint value the action goes to (``inst.rank`` judges the path that
    far); ``also``: grasps tried besides the action's (``inst.rank``'s ``also``)."""
    base_m = np.eye(4) if base is None else rigid_pose(base, "the robot base pose")
    scene = collision_scene(robot, inst, ignore=fingers, base=base_m, obstacles=obstacles)
    rejected: list[tuple[str, str]] = []
    found: list[GraspChoice] = []
    for option in inst.rank(action, gripper=robot.gripper, to=to, also=also):
        if grasps is not None and option.grasp not in grasps:
            continue
        if not option.feasible:
            rejected.append((option.grasp, "; ".join(option.reasons) or "infeasible for the hand"))
            continue
        solutions = _solutions(robot, inst, option.grasp, base_m, scene, seed, options, starts)
        if not solutions[0].success:
            ik = solutions[0]
            rejected.append((option.grasp, f"IK: {ik.reason} ({ik.error_pos * 1e3:.1f} mm off)"))
            continue
        for ik in solutions:
            found.append(GraspChoice(option, ik, _margin(robot, inst, action, ik, base_m), ()))
    if not found:
        why = "; ".join(f"{g}: {r}" for g, r in rejected) or "the action has no grasps"
        raise NoGraspError(f"no usable grasp for {action} of {inst.concept.name}: {why}")
    found.sort(key=lambda c: -c.margin)
    return found, rejected


def _solutions(
    robot: Robot,
    inst: Any,
    grasp: str,
    base: FloatArray,
    scene: Any,
    seed: int,
    options: IKOptions | None,
    starts: int,
) -> list[GraspIKResult]:
    """The solution from home (first, even when it failed), then those from the seed bank's
    configurations nearest it that differ from every one before by ``DISTINCT`` on some joint."""
    first = solve_grasp_ik(robot, inst, grasp, base=base, scene=scene, seed=seed, options=options)
    if not first.success or starts <= 0:
        return [first]
    out = [first]
    goal = np.linalg.inv(base) @ first.grasp_pose
    once = replace(options or IKOptions(), max_restarts=0)  # a start that stalls is dropped
    for q0 in seed_bank(robot).nearest(goal, starts):
        ik = solve_grasp_ik(robot, inst, grasp, q0, base=base, scene=scene, options=once)
        if ik.success and all(np.max(np.abs(ik.q - o.q)) > DISTINCT for o in out):
            out.append(ik)
    return out


def _margin(robot: Robot, inst: Any, action: str, ik: GraspIKResult, base: FloatArray) -> float:
    span = robot.upper - robot.lower
    limits = float(np.min(np.minimum(ik.q - robot.lower, robot.upper - ik.q) / span))
    try:
        force = base[:3, :3].T @ inst.force(action, grasp=ik.grasp_pose)
    except GraceError:  # a twist about the grasp axis: no linear force to follow
        return limits
    jv = robot.jacobian(ik.q)[:3]
    inverse = np.linalg.pinv(jv @ jv.T)
    return limits + 0.5 * float(1.0 / np.sqrt(max(force @ inverse @ force, 1e-12)))
