"""A whole action as one joint trajectory: approach, insert, interact, retreat.

``plan_action`` chooses the manipulation function with the robot in the loop (``choose_grasp``),
plans a collision-free approach to a pre-grasp pose backed off along the approach axis (OMPL),
moves straight in to the grasp, follows the action's analytic path (``inst.follow`` as its joint
moves, or a straight push along the force for an action that moves no joint) by tracking it with
the same IK warm-started from the previous sample, and backs out. Every tracked sample must be
reached within the IK tolerance and move no joint by more than ``MAX_JOINT_STEP``; otherwise the
plan fails with a reason, never with a jump.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from grace_dsl.robot.choose import GraspChoice, choose_grasp
from grace_dsl.robot.collision import CollisionScene, collision_scene
from grace_dsl.robot.ik import IKOptions, solve_ik
from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.robot.plan import PlanningError, plan_path, time_path
from grace_dsl.runtime.errors import GraceError

FloatArray = np.ndarray
MAX_JOINT_STEP = 0.2  # radians between two tracked samples
APPROACH = 0.10  # metres backed off along the approach axis before and after the grasp
PUSH_DISTANCE = 0.10  # metres travelled by an action that moves no joint
MIN_SEGMENT = 1e-3  # metres: tracked segments are halved down to this where joints move fast
REACH_ATTEMPTS = 8


class ActionPlanningError(PlanningError):
    """The action cannot be carried out from this base placement (the reason says where)."""


@dataclass(frozen=True)
class ActionPlan:
    """Joint waypoints ``q`` (K, n) at times ``t`` (K,); ``phases`` name index ranges
    ``(name, start, stop)``; ``gripper`` the hand's commands ``(time, width in metres)``,
    a width of 0 meaning "close on what is between the fingers"."""

    q: FloatArray
    t: FloatArray
    phases: tuple[tuple[str, int, int], ...]
    gripper: tuple[tuple[float, float], ...]
    choice: GraspChoice
    to: float | None

    def phase(self, name: str) -> FloatArray:
        for phase, start, stop in self.phases:
            if phase == name:
                return self.q[start:stop]
        raise KeyError(name)


def plan_action(
    robot: Robot,
    inst: Any,
    action: str,
    to: float | None = None,
    *,
    base: Any = None,
    q_start: Any = None,
    steps: int = 24,
    seed: int = 0,
    time_limit: float = 2.0,
) -> ActionPlan:
    """The trajectory that performs ``action`` on ``inst`` to joint value ``to`` (default the
    end of the joint's range the action drives toward; for an action that moves no joint, a
    push of ``PUSH_DISTANCE``). Raises :class:`ActionPlanningError` (or ``NoGraspError``) with
    the reason when this base placement cannot do it."""
    base_m = np.eye(4) if base is None else rigid_pose(base, "the robot base pose")
    to_base = np.linalg.inv(base_m)
    q0 = robot.home if q_start is None else robot.check_q(q_start)
    choice = choose_grasp(robot, inst, action, base=base_m, seed=seed)
    grasp = choice.ik.grasp_pose
    full = collision_scene(robot, inst, base=base_m)
    pre = grasp @ _back(APPROACH)
    q_pre = _reach(robot, to_base @ pre, choice.ik.q, full, "the pre-grasp pose", seed)
    approach = plan_path(full, q0, q_pre, time_limit=time_limit, seed=seed)
    insert = _track(robot, _line(to_base @ pre, to_base @ grasp, 8), q_pre, "moving in")
    path, to = _action_path(inst, action, grasp, to, steps)
    interact = _track(robot, to_base @ path, insert[-1], "following the action")
    retreat_poses = _line(to_base @ path[-1], to_base @ path[-1] @ _back(APPROACH), 8)
    retreat = _track(robot, retreat_poses, interact[-1], "backing out")
    return _assemble(robot, choice, to, [approach, insert, interact, retreat])


def _back(distance: float) -> FloatArray:
    m = np.eye(4)
    m[2, 3] = -distance
    return m


def _line(a: FloatArray, b: FloatArray, n: int) -> FloatArray:
    """Poses from ``a`` to ``b`` moving the origin straight, the orientation held (a's)."""
    out = np.repeat(a[None], n + 1, axis=0)
    out[:, :3, 3] = a[:3, 3] + np.linspace(0.0, 1.0, n + 1)[:, None] * (b[:3, 3] - a[:3, 3])
    return out


def _reach(
    robot: Robot, target: FloatArray, q0: FloatArray, scene: CollisionScene, what: str, seed: int
) -> FloatArray:
    """A collision-free IK solution near ``q0``, else from seeded random starts."""
    rng = np.random.default_rng(seed)
    reason = "out of reach"
    for attempt in range(REACH_ATTEMPTS):
        start = q0 if attempt == 0 else robot.random_q(rng)
        result = solve_ik(robot, target, q0=start, seed=seed + attempt)
        if not result.success:
            reason = f"out of reach ({result.error_pos * 1e3:.1f} mm off)"
            continue
        if not scene.collides(result.q):
            return np.asarray(result.q)
        hit = scene.contacts(result.q)[0]
        reason = f"in collision ({hit.first} touches {hit.second})"
    raise ActionPlanningError(f"{what} is {reason}")


def _track(robot: Robot, poses: FloatArray, q: FloatArray, what: str) -> FloatArray:
    """IK of each pose warm-started from the last, without restarts (no jump to another branch).
    Where one sample moves a joint more than ``MAX_JOINT_STEP``, the segment is halved (down to
    ``MIN_SEGMENT`` of travel): a fast-turning stretch gets denser samples, a true jump fails."""
    opts = IKOptions(max_restarts=0)
    out = [np.asarray(q)]
    pending = list(poses[:0:-1])  # a stack: the next target on top
    last = poses[0]
    while pending:
        pose = pending.pop()
        result = solve_ik(robot, pose, q0=out[-1], options=opts)
        step = float(np.max(np.abs(result.q - out[-1])))
        travel = float(np.linalg.norm(pose[:3, 3] - last[:3, 3]))
        if (not result.success or step > MAX_JOINT_STEP) and travel > MIN_SEGMENT:
            middle = pose.copy()
            middle[:3, 3] = (pose[:3, 3] + last[:3, 3]) / 2  # orientations of a path differ little
            middle[:3, :3] = _mid_rotation(last[:3, :3], pose[:3, :3])
            pending += [pose, middle]
            continue
        if not result.success:
            raise ActionPlanningError(
                f"{what}: a pose is out of reach ({result.error_pos * 1e3:.1f} mm off; a joint "
                "limit or the workspace's edge)"
            )
        if step > MAX_JOINT_STEP:
            raise ActionPlanningError(
                f"{what}: a joint must jump {step:.2f} rad (a singularity or a joint limit)"
            )
        out.append(np.asarray(result.q))
        last = pose
    return np.stack(out)


def _mid_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rotation half-way from ``a`` to ``b`` (geodesic)."""
    return np.asarray(a @ pin.exp3(pin.log3(a.T @ b) / 2))


def _action_path(
    inst: Any, action: str, grasp: FloatArray, to: float | None, steps: int
) -> tuple[FloatArray, float | None]:
    spec = inst.concept.actions[action]
    joint = spec.joint
    if joint is None:
        force = inst.force(action, grasp=grasp)
        shifts = np.linspace(0.0, PUSH_DISTANCE, steps)[:, None] * force
        path = np.repeat(grasp[None], steps, axis=0)
        path[:, :3, 3] += shifts
        return path, None
    lo, hi = inst.joint_limits()[joint]
    target = (hi if spec.opening else lo) if to is None else float(to)
    try:
        return inst.follow(action, grasp=grasp, to=target, steps=steps), target
    except GraceError as exc:
        raise ActionPlanningError(f"{action} cannot move {joint} to {target:g}: {exc}") from None


def _assemble(
    robot: Robot, choice: GraspChoice, to: float | None, parts: list[FloatArray]
) -> ActionPlan:
    names = ("approach", "insert", "interact", "retreat")
    waypoints = [parts[0]] + [p[1:] for p in parts[1:]]  # each part starts where the last ended
    q = np.concatenate(waypoints)
    timed = time_path(q, robot.velocity_limit)
    phases, start = [], 0
    for name, part in zip(names, waypoints):
        phases.append((name, max(0, start - 1) if name != "approach" else 0, start + len(part)))
        start += len(part)
    at = {name: float(timed.t[begin]) for name, begin, _ in phases}
    width = robot.gripper.max_width
    grip = 0.0 if choice.option.mode == "pinch" else width
    commands = ((0.0, width), (at["interact"], grip), (at["retreat"], width))
    return ActionPlan(timed.q, timed.t, tuple(phases), commands, choice, to)
