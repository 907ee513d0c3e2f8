"""Grasp selection: the paper's choice of manipulation function, done with the robot in the loop.

``choose_grasp`` takes the action's manipulation functions that ``inst.rank`` calls feasible for
the robot's hand, solves grasp-manifold IK for each (arm and palm clear of everything, fingers
allowed on the object) and keeps the reachable one with the best margin:

    margin = min_i min(q_i − lo_i, hi_i − q_i) / (hi_i − lo_i)  +  ½ · m_f

the first term the normalized distance to the nearest joint limit (0 at a limit, ½ mid-range),
``m_f = (fᵀ (J_v J_vᵀ)⁻¹ f)^(−½)`` the hand's velocity manipulability along the action's force
direction ``f`` (metres per second per unit joint speed; how freely the arm can follow the pull).
Options that lose say why.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.grasp_ik import GraspIKResult, solve_grasp_ik
from grace_dsl.robot.ik import IKOptions
from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.runtime.errors import GraceError

FloatArray = np.ndarray


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
    fingers: Sequence[str] = ("panda_leftfinger", "panda_rightfinger"),
) -> GraspChoice:
    """The best reachable manipulation function of ``action`` (see the module docstring).

    Raises :class:`NoGraspError` listing every option's reason when none is usable.
    """
    base_m = np.eye(4) if base is None else rigid_pose(base, "the robot base pose")
    scene = collision_scene(robot, inst, ignore=fingers, base=base_m)
    rejected: list[tuple[str, str]] = []
    best: GraspChoice | None = None
    for option in inst.rank(action, gripper=robot.gripper):
        if not option.feasible:
            rejected.append((option.grasp, "; ".join(option.reasons) or "infeasible for the hand"))
            continue
        ik = solve_grasp_ik(
            robot, inst, option.grasp, base=base_m, scene=scene, seed=seed, options=options
        )
        if not ik.success:
            rejected.append((option.grasp, f"IK: {ik.reason} ({ik.error_pos * 1e3:.1f} mm off)"))
            continue
        margin = _margin(robot, inst, action, ik, base_m)
        if best is None or margin > best.margin:
            if best is not None:
                rejected.append((best.option.grasp, f"smaller margin ({best.margin:.3f})"))
            best = GraspChoice(option, ik, margin, ())
        else:
            rejected.append((option.grasp, f"smaller margin ({margin:.3f})"))
    if best is None:
        why = "; ".join(f"{g}: {r}" for g, r in rejected) or "the action has no grasps"
        raise NoGraspError(f"no usable grasp for {action} of {inst.concept.name}: {why}")
    return GraspChoice(best.option, best.ik, best.margin, tuple(rejected))


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
