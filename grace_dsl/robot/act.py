"""A whole action as one joint trajectory: approach, insert, interact, retreat.

``plan_action`` takes the grasp postures of ``grasp_candidates`` (every feasible manipulation
function, solved from several starts, best margin first) and tries them in turn. For each, the
hand stops short of the grasp by the finger pads' standoff where their ends would press into the
part, the straight insert is tracked backward from the grasp posture to a pre-grasp pose backed
off along the approach axis, the action's analytic path (``inst.follow`` as its joint moves, or
a straight push along the force for an action that moves no joint) is tracked with the same IK
warm-started from the previous sample, and the hand backs out as far as it can (at least
``MIN_RETREAT``). Every tracked sample must be reached within the IK tolerance and move no joint
by more than ``MAX_JOINT_STEP``; otherwise that posture fails with a reason, never with a jump.
After each sample the arm moves along its self-motion toward mid-range (``_relax``), keeping a
margin to the joint limits. Only for a posture whose tracked phases all succeed is the approach
planned (OMPL) from the start configuration to where the insert begins.

Collisions are checked all the way: the approach against everything; moving in, the interaction
and backing out against everything too, the object posed at the joint value the hand has moved
it to, except that the fingers may press into the grasped link by up to ``FINGER_ALLOWANCE``.
Each phase is then timed by the time-optimal parameterization (``robot.timing``) along a spline
through its waypoints, re-checked at the timed samples; where the spline would touch something
or leave the joint limits, the phase falls back to its polyline, stopping at the corners.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np
import pinocchio as pin

from grace_dsl.robot.choose import GraspChoice, grasp_candidates
from grace_dsl.robot.collision import CollisionScene, collision_scene
from grace_dsl.robot.ik import IKOptions, solve_ik
from grace_dsl.robot.model import Robot, rigid_pose
from grace_dsl.robot.plan import (
    CHECK_RESOLUTION,
    DEFAULT_ACCELERATION,
    PLAN_CHECKS,
    PlanningError,
    PlanningTimeout,
    plan_path,
)
from grace_dsl.robot.timing import Trajectory, time_optimal
from grace_dsl.runtime.errors import GraceError
from grace_dsl.runtime.manipulation import CLEARANCE

FloatArray = np.ndarray
MAX_JOINT_STEP = 0.2  # radians between two tracked samples
APPROACH = 0.10  # metres backed off along the approach axis before and after the grasp
MIN_RETREAT = 0.04  # metres: the finger pads (19 mm) and a handle's depth (at most 2 cm)
RETREATS = (APPROACH, 0.07, MIN_RETREAT)  # metres backed out, the longest the arm can track
PUSH_DISTANCE = 0.10  # metres travelled by an action that moves no joint
MIN_SEGMENT = 1e-3  # metres: tracked segments are halved down to this where joints move fast
RELAX_STEP = 0.05  # radians of self-motion toward mid-range per tracked sample
CANDIDATES = 8  # grasp postures tried per action
FINGERTIP_REACH = 0.0095  # metres the Panda's finger pads reach beyond the gripper frame
STANDOFFS = (0.0, 0.0025, 0.005, 0.0075, FINGERTIP_REACH)  # metres short of the grasp
FINGER_ALLOWANCE = 0.005  # metres the fingers may press into the link they hold
# metres a pinch's closed fingers keep off the links they do not hold, where the hand can stop
# that much further short (a lip as deep as the pads reach: their ends on the body below it)
CLOSED_CLEAR = 0.0005
# metres a pinch's fingers open beyond the part to let go (the flying hand's clearance on each
# side, as it comes in): opened fully, the lower finger under a lid nearly shut meets the body
RELEASE = 2 * CLEARANCE
FINGERS = ("panda_leftfinger", "panda_rightfinger")
GRIP_TIME = 0.5  # seconds the hand rests while the gripper closes or opens
PHASES = ("approach", "insert", "interact", "retreat")


class ActionPlanningError(PlanningError):
    """The action cannot be carried out from this base placement (the reason says where).

    ``phase`` names the stretch that failed (``pre-grasp``, ``moving in``, ``following the
    action``, ``backing out``), ``reason`` is ``unreachable``, ``jump`` or ``collision``, and
    ``value`` the object's joint value there (how far it could be opened), when known."""

    def __init__(
        self,
        message: str,
        *,
        phase: str = "",
        reason: str = "",
        value: float | None = None,
        base: FloatArray | None = None,
    ) -> None:
        super().__init__(message)
        self.phase, self.reason, self.value = phase, reason, value
        self.base = base  # the base pose it was planned from, when a caller tried several


@dataclass(frozen=True)
class ActionPlan:
    """Joint waypoints ``q`` (K, n) at times ``t`` (K,); ``phases`` name index ranges
    ``(name, start, stop)``; ``gripper`` the hand's commands ``(time, width in metres)``,
    a width of 0 meaning "close on what is between the fingers". ``joint_values`` (K,) is the
    object's joint ``joint`` at each waypoint (its initial value outside the interaction)."""

    q: FloatArray
    t: FloatArray
    phases: tuple[tuple[str, int, int], ...]
    gripper: tuple[tuple[float, float], ...]
    choice: GraspChoice
    to: float | None
    joint: str | None
    joint_values: FloatArray
    base: FloatArray
    seconds: tuple[tuple[str, float], ...] = ()  # planning time per stage (grasp, approach, ...)
    standoff: float = 0.0  # metres the hand stopped short of the grasp pose (``_standoff``)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def span(self, name: str) -> tuple[float, float]:
        """Start and end time of phase ``name``."""
        for phase, start, stop in self.phases:
            if phase == name:
                return float(self.t[start]), float(self.t[stop - 1])
        raise KeyError(name)

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
    checks: int = PLAN_CHECKS,
    time_limit: float | None = None,
    acceleration: float | FloatArray = DEFAULT_ACCELERATION,
    allowance: float = FINGER_ALLOWANCE,
    candidates: int = CANDIDATES,
    obstacles: Sequence[Any] = (),
    grasps: Sequence[str] | None = None,
    also: Sequence[str] = (),
) -> ActionPlan:
    """The trajectory that performs ``action`` on ``inst`` to joint value ``to`` (default the
    end of the joint's range the action drives toward; for an action that moves no joint, a
    push of ``PUSH_DISTANCE``). The grasp postures of ``grasp_candidates`` are tried best margin
    first (at most ``candidates``) until one carries the whole action. Raises
    :class:`ActionPlanningError` (or ``NoGraspError``) with the reason of the candidate that got
    furthest when this base placement cannot do it. ``obstacles``: the other objects of a room
    (posed instances that stand still), checked in every phase; ``grasps``: only these options
    of ``inst.rank`` (default all); ``also``: grasps tried besides the action's. ``checks``: the
    approach planner's budget of collision checks (a count: the plan does not depend on the
    machine's load); ``time_limit``: its optional wall-clock safety cap (off by default)."""
    base_m = np.eye(4) if base is None else rigid_pose(base, "the robot base pose")
    q0 = robot.home if q_start is None else robot.check_q(q_start)
    clock = [("start", time.perf_counter())]
    found, rejected = grasp_candidates(
        robot,
        inst,
        action,
        base=base_m,
        seed=seed,
        obstacles=obstacles,
        grasps=grasps,
        to=to,
        also=also,
    )
    clock.append(("grasp", time.perf_counter()))
    full = collision_scene(robot, inst, base=base_m, obstacles=obstacles)
    joint = inst.concept.actions[action].joint
    failures: list[ActionPlanningError] = []
    to_value = to
    for k, choice in enumerate(found[:candidates]):
        link = inst.concept.grasps[choice.option.grasp].link
        held = collision_scene(
            robot,
            inst,
            base=base_m,
            touching=[(f, link) for f in FINGERS],
            allowance=allowance,
            obstacles=obstacles,
        )
        path, values, to_value = _action_path(inst, action, choice.ik.grasp_pose, to, steps)
        hand = (robot, inst, choice, base_m, link, allowance, obstacles)
        gripping = _closed_scene(*hand) or held
        releasing = _closed_scene(*hand, RELEASE) or held
        times: list[tuple[str, float]] = []
        try:
            parts, standoff = _phases(
                robot,
                inst,
                choice,
                full,
                (held, gripping, releasing),
                base_m,
                q0,
                path,
                values,
                joint,
                seed,
                (checks, time_limit),
                times,
            )
        except ActionPlanningError as exc:
            failures.append(exc)
            continue
        clock += times
        lost = [(c.option.grasp, _why(e, i)) for i, (c, e) in enumerate(zip(found, failures))]
        others = [(c.option.grasp, f"not tried (margin {c.margin:.3f})") for c in found[k + 1 :]]
        choice = replace(choice, rejected=tuple(rejected + lost + others))
        break
    else:
        goal = f" to {joint} = {to_value:g}" if joint is not None and to_value is not None else ""
        start = float(inst.joints[joint]) if joint is not None else 0.0
        worst = max(failures, key=lambda e: progress(e, start))
        tried = f" ({len(failures)} grasp postures tried; the furthest)" * (len(failures) > 1)
        raise ActionPlanningError(
            f"{inst.concept.name}: cannot {action}{goal} from this base placement{tried}: {worst}",
            phase=worst.phase,
            reason=worst.reason,
            value=worst.value,
        ) from None
    timed = [_time(robot, q, v, scene, acceleration) for q, v, scene in parts]
    clock.append(("timing", time.perf_counter()))
    plan = _assemble(robot, choice, to_value, joint, timed, base_m)
    stages = tuple((name, b - a) for (_, a), (name, b) in zip(clock[:-1], clock[1:]))
    return replace(plan, seconds=stages, standoff=standoff)


def _why(exc: ActionPlanningError, k: int) -> str:
    return f"posture {k + 1}: {exc.phase}: {exc.reason}"


def progress(exc: ActionPlanningError, start: float = 0.0) -> tuple[int, float]:
    """How far a failed plan got: the phase (in the order they are planned), then how far the
    object's joint moved from ``start`` (either way: an open and a close alike)."""
    order = ("moving in", "following the action", "backing out", "approach")
    rank = order.index(exc.phase) if exc.phase in order else -1
    return rank, abs(exc.value - start) if exc.value is not None else 0.0


def _phases(
    robot: Robot,
    inst: Any,
    choice: GraspChoice,
    full: CollisionScene,
    scenes: tuple[CollisionScene, CollisionScene, CollisionScene],
    base: FloatArray,
    q0: FloatArray,
    path: FloatArray,
    values: FloatArray,
    joint: str | None,
    seed: int,
    budget: tuple[int, float | None],
    clock: list[tuple[str, float]],
) -> tuple[list[tuple[FloatArray, FloatArray, _Object]], float]:
    """The four phases' joint waypoints, object joint values and collision scenes, checked
    (``clock`` gets the times the tracked phases and the approach were done), and the standoff.
    ``scenes``: the hand open on the grasped link (moving in), as it holds it during the
    interaction (a pinch's fingers closed on the part) and as it lets go (a pinch's fingers
    opened ``RELEASE`` wider than the part, backing out).

    The cheap, decisive part first: from the grasp posture, the insert tracked backwards to the
    pre-grasp pose, then the interaction and the retreat; only then the approach (OMPL) from
    ``q0`` to the pre-grasp configuration the insert started from."""
    to_base = np.linalg.inv(base)
    start_value = float(inst.joints[joint]) if joint is not None else 0.0
    held, gripping, releasing = scenes
    moving = _Object(held, inst, joint)
    grasp = to_base @ choice.ik.grasp_pose
    holding = _Object(gripping, inst, joint)
    hands = (moving,) if gripping is held else (moving, holding)
    off, q_grasp = _standoff(robot, grasp, choice.ik.q, hands, start_value)
    path = path @ _back(off)
    grasp = to_base @ path[0]
    pre = grasp @ _back(APPROACH)
    backwards, _ = _track(robot, _line(grasp, pre, 8), q_grasp, "moving in")
    insert = backwards[::-1].copy()
    _check(moving, insert, np.full(len(insert), start_value), "moving in")
    interact, held_values = _track(
        robot, to_base @ path, q_grasp, "following the action", values, joint
    )
    _check(holding, interact, held_values, "following the action")
    try:
        retreat = _retreat(robot, to_base @ path[-1], interact[-1])
    except ActionPlanningError as exc:  # the object was moved all the way: say how far
        exc.value = float(held_values[-1]) if joint is not None else None
        raise
    letting_go = _Object(releasing, inst, joint)
    _check(letting_go, retreat, np.full(len(retreat), held_values[-1]), "backing out")
    clock.append(("tracking", time.perf_counter()))
    try:
        approach = plan_path(full, q0, insert[0], checks=budget[0], time_limit=budget[1], seed=seed)
    except PlanningError as exc:
        reason = "time limit" if isinstance(exc, PlanningTimeout) else "no path"
        raise ActionPlanningError(f"the approach: {exc}", phase="approach", reason=reason) from None
    clock.append(("approach", time.perf_counter()))
    return [
        (approach, np.full(len(approach), start_value), _Object(full, inst, None)),
        (insert, np.full(len(insert), start_value), moving),
        (interact, held_values, holding),
        (retreat, np.full(len(retreat), held_values[-1]), letting_go),
    ], off


def _closed_scene(
    robot: Robot,
    inst: Any,
    choice: GraspChoice,
    base: FloatArray,
    link: str,
    allowance: float,
    obstacles: Sequence[Any],
    wider: float = 0.0,
) -> CollisionScene | None:
    """The scene of a Panda whose fingers have closed on the part for a pinch (``wider`` metres
    more apart), as they do before the interaction: a thin lid's open fingers straddle the body
    under it, and the lower one, lifted with the lid, would seem to run into that body while the
    closed one stays under the lid. None when the hand stays open (hooks and pushes), would be
    open fully, or is not the Panda's."""
    if choice.option.mode != "pinch" or robot.name != "panda":
        return None
    width = inst.grasp_width(choice.option.grasp)
    if width is None or not 0.0 <= float(width) + wider < robot.gripper.max_width:
        return None
    return collision_scene(
        _closed_panda(round(float(width) + wider, 4)),
        inst,
        base=base,
        touching=[(f, link) for f in FINGERS],
        allowance=allowance,
        obstacles=obstacles,
    )


@lru_cache(maxsize=8)
def _closed_panda(opening: float) -> Robot:
    """The Panda with its fingers ``opening`` apart (loaded once per opening and process)."""
    return Robot.panda(opening)


def _retreat(robot: Robot, end: FloatArray, q: FloatArray) -> FloatArray:
    """The hand backed out along its approach axis from the pose ``end`` where the action left
    it: ``APPROACH`` when the arm can, else the longest of ``RETREATS`` it can track (at least
    ``MIN_RETREAT``, which takes the finger pads and a handle's depth off the part)."""
    failure: ActionPlanningError | None = None
    for length in RETREATS:
        try:
            qs, _ = _track(robot, _line(end, end @ _back(length), 8), q, "backing out")
        except ActionPlanningError as exc:
            failure = failure or exc
            continue
        return qs
    assert failure is not None
    raise failure


def _standoff(
    robot: Robot, grasp: FloatArray, q: FloatArray, hands: Sequence[_Object], value: float
) -> tuple[float, FloatArray]:
    """How far short of the grasp pose (along its approach axis) the hand stops, and its joints
    there: the first of ``STANDOFFS`` at which the fingers press into nothing deeper than the
    allowance, open and (``hands[1:]``) closed on the part; the closed fingers ``CLOSED_CLEAR``
    off every other link where a standoff allows, if need be ``2 * CLOSED_CLEAR`` beyond the
    pads' reach (a lid's lower finger right under its lip, its end on the body below: the
    first sample that lifts the lid would touch it). The grasp
    frame's origin is the middle of the finger pads, which reach ``FINGERTIP_REACH`` beyond it:
    a hand pushing an edge or pinching a lip touches with the pads' ends, and stopping at most
    that much short keeps the pads on the part (0 when nothing is free: the insert's check then
    names the contact)."""
    free: tuple[float, FloatArray] | None = None
    for off in STANDOFFS + (FINGERTIP_REACH + 2 * CLOSED_CLEAR,) * (len(hands) > 1):
        if off == 0.0:
            q_off = np.asarray(q)
        else:
            result = solve_ik(robot, grasp @ _back(off), q0=q, options=IKOptions(max_restarts=0))
            if not result.success:
                continue
            q_off = np.asarray(result.q)
        if any(hand.collides(q_off, value) for hand in hands):
            continue
        if all(hand.clear(q_off, value) >= CLOSED_CLEAR for hand in hands[1:]):
            return off, q_off
        free = free or (off, q_off)
    return free or (0.0, np.asarray(q))


@dataclass(frozen=True)
class _Object:
    """A collision scene whose object moves with its joint ``joint`` (None: it stays put)."""

    scene: CollisionScene
    inst: Any
    joint: str | None

    def collides(self, q: FloatArray, value: float) -> bool:
        if self.joint is not None:
            self.scene.place(self.inst.with_joints({self.joint: value}))
        return self.scene.collides(q)

    def clear(self, q: FloatArray, value: float) -> float:
        """The robot's distance to the object's links it may not touch (metres)."""
        if self.joint is not None:
            self.scene.place(self.inst.with_joints({self.joint: value}))
        return self.scene.object_distance(q)

    def contact(self, q: FloatArray, value: float) -> str:
        self.collides(q, value)
        hit = self.scene.contacts(q)
        return f"{hit[0].first} touches {hit[0].second}" if hit else "a contact"


def _check(
    moving: _Object, qs: FloatArray, values: FloatArray, what: str, *, fail: bool = True
) -> bool:
    """Every configuration on the straight segments between the waypoints ``qs`` (the object at
    the interpolated joint ``values``) free, every ``CHECK_RESOLUTION`` on the arm's joints and
    the object's; else :class:`ActionPlanningError` naming the contact (or False)."""
    for k in range(len(qs) - 1):
        dq, dv = qs[k + 1] - qs[k], values[k + 1] - values[k]
        n = max(1, int(np.ceil(max(float(np.max(np.abs(dq))), abs(dv)) / CHECK_RESOLUTION)))
        for w in np.linspace(0.0, 1.0, n + 1)[(1 if k else 0) :]:
            q, value = qs[k] + w * dq, values[k] + w * dv
            if moving.collides(q, value):
                if not fail:
                    return False
                at = f" with {moving.joint} at {value:.3f}" if moving.joint else ""
                raise ActionPlanningError(
                    f"{what}: {moving.contact(q, value)}{at}",
                    phase=what,
                    reason="collision",
                    value=values[k] if moving.joint else None,
                )
    return True


def _time(
    robot: Robot,
    qs: FloatArray,
    values: FloatArray,
    moving: _Object,
    acceleration: float | FloatArray,
) -> Trajectory:
    """The phase timed time-optimally along a spline through ``qs``, when the spline stays
    inside the limits and free; else along the (already checked) polyline."""
    smooth = time_optimal(qs, robot.velocity_limit, acceleration, extra=values)
    inside = np.all(smooth.q >= robot.lower) and np.all(smooth.q <= robot.upper)
    if inside and _check(moving, smooth.q, smooth.extra[:, 0], "", fail=False):
        return smooth
    return time_optimal(qs, robot.velocity_limit, acceleration, extra=values, smooth=False)


def _back(distance: float) -> FloatArray:
    m = np.eye(4)
    m[2, 3] = -distance
    return m


def _line(a: FloatArray, b: FloatArray, n: int) -> FloatArray:
    """Poses from ``a`` to ``b`` moving the origin straight, the orientation held (a's)."""
    out = np.repeat(a[None], n + 1, axis=0)
    out[:, :3, 3] = a[:3, 3] + np.linspace(0.0, 1.0, n + 1)[:, None] * (b[:3, 3] - a[:3, 3])
    return out


def _track(
    robot: Robot,
    poses: FloatArray,
    q: FloatArray,
    what: str,
    values: FloatArray | None = None,
    joint: str | None = None,
) -> tuple[FloatArray, FloatArray]:
    """IK of each pose warm-started from the last, without restarts (no jump to another branch).
    Where one sample moves a joint more than ``MAX_JOINT_STEP``, the segment is halved (down to
    ``MIN_SEGMENT`` of travel): a fast-turning stretch gets denser samples, a true jump fails.
    ``values`` (one per pose: the object's joint) are interpolated into the halved segments;
    returns the joint waypoints and the values at them. A failure names the last value reached."""
    opts = IKOptions(max_restarts=0)
    carried = np.zeros(len(poses)) if values is None else np.asarray(values, float)
    out, out_values = [np.asarray(q)], [float(carried[0])]
    pending = list(zip(poses[:0:-1], carried[:0:-1]))  # a stack: the next target on top
    last = poses[0]
    while pending:
        pose, value = pending.pop()
        result = solve_ik(robot, pose, q0=out[-1], options=opts)
        step = float(np.max(np.abs(result.q - out[-1])))
        travel = float(np.linalg.norm(pose[:3, 3] - last[:3, 3]))
        if (not result.success or step > MAX_JOINT_STEP) and travel > MIN_SEGMENT:
            middle = pose.copy()
            middle[:3, 3] = (pose[:3, 3] + last[:3, 3]) / 2  # orientations of a path differ little
            middle[:3, :3] = _mid_rotation(last[:3, :3], pose[:3, :3])
            pending += [(pose, value), (middle, (value + out_values[-1]) / 2)]
            continue
        at = f" at {joint} = {value:.3f}" if joint else ""
        if not result.success:
            raise ActionPlanningError(
                f"{what}: a pose{at} is out of reach ({result.error_pos * 1e3:.1f} mm off; a "
                "joint limit or the workspace's edge)",
                phase=what,
                reason="unreachable",
                value=out_values[-1] if joint else None,
            )
        if step > MAX_JOINT_STEP:
            raise ActionPlanningError(
                f"{what}: a joint must jump {step:.2f} rad{at} (a singularity or a joint limit)",
                phase=what,
                reason="jump",
                value=out_values[-1] if joint else None,
            )
        out.append(_relax(robot, pose, np.asarray(result.q), out[-1], opts))
        out_values.append(float(value))
        last = pose
    return np.stack(out), np.asarray(out_values)


def _relax(
    robot: Robot, pose: FloatArray, q: FloatArray, previous: FloatArray, opts: IKOptions
) -> FloatArray:
    """``q`` moved along the arm's self-motion (the null space of its Jacobian, which leaves the
    hand where it is to first order) toward the middle of the joint ranges, then put back on
    ``pose`` by IK: redundancy resolution that keeps a margin to the joint limits, so that a
    tracked path does not run a joint into its limit while another posture of the same hand pose
    had room. The gradient step is ``RELAX_STEP`` at most on any joint; the relaxed
    configuration is kept only when IK reaches the pose from it within ``MAX_JOINT_STEP`` of
    ``previous``."""
    middle, half = (robot.upper + robot.lower) / 2, (robot.upper - robot.lower) / 2
    jac = robot.jacobian(q)
    null = np.eye(robot.nq) - np.linalg.pinv(jac) @ jac
    step = null @ ((middle - q) / half)
    largest = float(np.max(np.abs(step)))
    if largest < 1e-9:
        return q
    nudged = np.clip(q + step * min(1.0, RELAX_STEP / largest), robot.lower, robot.upper)
    result = solve_ik(robot, pose, q0=nudged, options=opts)
    if result.success and float(np.max(np.abs(result.q - previous))) <= MAX_JOINT_STEP:
        return np.asarray(result.q)
    return q


def _mid_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rotation half-way from ``a`` to ``b`` (geodesic)."""
    return np.asarray(a @ pin.exp3(pin.log3(a.T @ b) / 2))


def _action_path(
    inst: Any, action: str, grasp: FloatArray, to: float | None, steps: int
) -> tuple[FloatArray, FloatArray, float | None]:
    """The hand's poses along the action, the object's joint value at each, and the target."""
    spec = inst.concept.actions[action]
    joint = spec.joint
    if joint is None:
        force = inst.force(action, grasp=grasp)
        shifts = np.linspace(0.0, PUSH_DISTANCE, steps)[:, None] * force
        path = np.repeat(grasp[None], steps, axis=0)
        path[:, :3, 3] += shifts
        return path, np.zeros(steps), None
    lo, hi = inst.joint_limits()[joint]
    target = (hi if spec.opening else lo) if to is None else float(to)
    try:
        path = inst.follow(action, grasp=grasp, to=target, steps=steps)
    except GraceError as exc:
        raise ActionPlanningError(f"{action} cannot move {joint} to {target:g}: {exc}") from None
    return path, np.linspace(float(inst.joints[joint]), target, steps), target


def _assemble(
    robot: Robot,
    choice: GraspChoice,
    to: float | None,
    joint: str | None,
    parts: list[Trajectory],
    base: FloatArray,
) -> ActionPlan:
    """One trajectory from the timed phases, resting ``GRIP_TIME`` where the gripper changes."""
    width = robot.gripper.max_width
    grip = 0.0 if choice.option.mode == "pinch" else width
    pause = {"interact": GRIP_TIME if grip != width else 0.0}
    pause["retreat"] = pause["interact"]
    qs, ts, values, phases = [parts[0].q], [parts[0].t], [parts[0].extra[:, 0]], []
    phases.append((PHASES[0], 0, len(parts[0].t)))
    size, end = len(parts[0].t), float(parts[0].t[-1])
    for name, part in zip(PHASES[1:], parts[1:]):
        wait = pause.get(name, 0.0)
        begin = size - 1
        if wait:  # hold the pose while the hand closes or opens: one more sample, later
            qs.append(part.q[:1])
            ts.append(np.array([end + wait]))
            values.append(part.extra[:1, 0])
            begin, size, end = size, size + 1, end + wait
        qs.append(part.q[1:])
        ts.append(part.t[1:] + end)
        values.append(part.extra[1:, 0])
        size += len(part.t) - 1
        end += float(part.t[-1])
        phases.append((name, begin, size))
    q, t = np.concatenate(qs), np.concatenate(ts)
    at = {name: float(t[begin]) for name, begin, _ in phases}
    commands = (
        (0.0, width),
        (at["interact"] - pause["interact"], grip),
        (at["retreat"] - pause["retreat"], width),
    )
    arrays = [q, t, np.concatenate(values)]
    for a in arrays:
        a.setflags(write=False)
    return ActionPlan(arrays[0], t, tuple(phases), commands, choice, to, joint, arrays[2], base)
