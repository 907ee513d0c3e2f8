"""One physical episode with the full Panda: a pure function of (config, seed).

The protocol draws the object, its joint value and the camera as for the flying hand
(``grace_dsl.sim.episode``). The robot layer then does what it does on a real arm: the base
stands where ``default_instance`` would put the object in front of it (0.6 m ahead, the grasps
0.5 m above the base; the base is a pedestal, there is no floor to hit), ``plan_placed`` plans
the whole action from there (grasp postures by IK, collision-checked insert, interaction and
retreat, an OMPL approach; other base placements when that one cannot), and MuJoCo executes it:

1. the approach and the move in, tracked in joint space (``JointTracker``);
2. a pinch closes the fingers (70 N, the flying hand's fingers);
3. the interaction with compliance: the hand a Cartesian spring through the arm's Jacobian,
   its target the path follower's, re-anchored on the measured joint value as for the flying
   hand; the arm's self-motion held near the plan's posture at that joint value;
4. release and a straight retreat along the approach axis.

Failure reasons: no grasp the arm can take (``no_feasible_grasp``), no plan from any
placement (``ik_failure``), the arm stopped on its way in (``collision``), then as for the
flying hand (slip, wrong direction, timeout).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from grace_dsl.robot.act import ActionPlan
from grace_dsl.robot.model import Robot
from grace_dsl.robot.plan import PLAN_CHECKS
from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.manipulation import CLEARANCE
from grace_dsl.sim.arm import FINGER_SPEED, ArmWorld
from grace_dsl.sim.arm_control import HandImpedance, JointTrajectory, track_torque
from grace_dsl.sim.control import PathFollower, blend, rotation_angle
from grace_dsl.sim.episode import (
    ARRIVED,
    ARRIVED_ROT,
    CLOSE_TIME,
    CONTROL_EVERY,
    EMPTY,
    FOLLOW_TO,
    PRESS_PAST,
    RETREAT,
    SETTLE,
    SLIP,
    SLIP_TIME,
    Outcome,
    _early,
    deeper,
    outcome_record,
    start_episode,
)
from grace_dsl.sim.protocol import (
    CLOSE_GOAL,
    TaskAction,
    strict_success,
)
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord

PLACEMENTS = 6  # base placements plan_placed may try (the given one, the centred one, shifts)
REPLAN_AT = 0.95  # an action that plans only part of the way is replanned to this much of it
# A plan that moves the part less than this fraction of the range is not worth executing
MIN_STAGE = 0.08
# Plans executed one after another at most: each follows the part as far as the arm reaches,
# lets go and backs off; the next is planned from where the part and the arm then are (a wide
# door brushed on the way in and closed part-way may take a fourth)
STAGES = 4
# Collision checks OMPL may spend on the approach of a partial plan or a later stage (a first
# plan has the planner's default): its start is near the object, where paths are harder to find
LATER = 3 * PLAN_CHECKS
PARTIAL_TRIES = 3  # partial plans tried, each shorter than the last failure's reach
# Fractions of the way a stage is planned to when no grasp carries the part all the way
SHORTER = (0.5,)
PATH_FIRST = 3  # base poses scored on the hand's path tried (interleaved with the fixed shifts)
OPEN_ENOUGH = 0.55  # fraction of the range past which an open stops staging (strict: half)
CLOSE_ENOUGH = 0.025  # fraction of the range within which a close stops staging (strict: 5 %)
# An open is planned to this fraction of the range (strict success needs half): the further a
# door swings, the more often the arm's workspace ends first, and the gripper's 0.9 buys nothing
OPEN_TO = 0.7
PINCH_IN_TIME = 0.3  # s to move from the planned grasp to the flying hand's pinch depth
DONE_SHORT = 0.03  # fraction of the range short of an open's goal at which it is done


@lru_cache(maxsize=1)
def panda() -> Robot:
    """The robot layer's Panda, loaded once per process."""
    return Robot.panda()


def run_arm_episode(config: EpisodeConfig, seed: int, *, move_base: bool = True) -> EpisodeRecord:
    """Run one arm episode of ``config`` with ``seed``; the same pair gives the same record.
    ``move_base`` False keeps the base where the first stage put it (the comparison figure)."""
    from grace_dsl.robot.choose import NoGraspError

    if config.hand != "panda":
        raise ParameterError(
            f"agent 'arm' is the Panda with its own hand; hand {config.hand!r} runs with "
            "agent='gripper'"
        )
    started = time.perf_counter()
    start = start_episode(config, seed, started)
    if isinstance(start, EpisodeRecord):
        return start
    task, draw, inst = start.task, start.draw, start.inst
    try:
        plan = plan_episode(inst, task, seed)
    except NoGraspError as exc:
        return _early(config, seed, task, "no_feasible_grasp", str(exc), started, draw, inst)
    except GraceError as exc:
        return _early(config, seed, task, "ik_failure", str(exc), started, draw, inst)
    staged = execute_stages(inst, task, plan, config.max_seconds, seed, move_base=move_base)
    record = outcome_record(
        config, seed, task, draw, inst, staged.outcome, plan.choice.option, started
    )
    record = replace(record, bases=[_base_xyzyaw(b) for b in staged.bases])
    if len(staged.options) > 1:
        record = replace(record, option=" + ".join(staged.options))
    if not record.strict and staged.unplanned:  # the arm stopped because no stage planned
        reason = "no_feasible_grasp" if staged.no_grasp else "ik_failure"
        record = replace(record, reason=reason, detail=staged.unplanned)
    return record


def run_arm_episode_fixed_base(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """``run_arm_episode`` with the base kept where the first stage put it (a module-level
    function, so that a process pool can run it by name)."""
    return run_arm_episode(config, seed, move_base=False)


def _base_xyzyaw(base: np.ndarray) -> list[float]:
    """A base pose as the record keeps it: x, y, z (m) and yaw (rad), rounded to 0.1 mm."""
    yaw = math.atan2(float(base[1, 0]), float(base[0, 0]))
    return [round(float(v), 4) for v in (*base[:3, 3], yaw)]


def robot_base(robot: Robot, inst: Instance, action: str) -> np.ndarray:
    """The base's world pose as ``default_instance`` places robot and object, for the object as
    it stands now (a door that starts wide open has its handle far out to the side): the
    action's grasps ``REACH`` ahead of the base and ``HEIGHT`` above it, the base facing the
    object's front (world -x), stepped back while the home posture would touch the object."""
    from grace_dsl.robot.collision import collision_scene
    from grace_dsl.robot.placement import (
        HEIGHT,
        MAX_STEPS_BACK,
        REACH,
        STEP_BACK,
        _grasp_centre,
        base_pose,
    )

    centre = _grasp_centre(inst, action)
    base = base_pose(float(centre[0]) + REACH, float(centre[1]), math.pi)
    base[2, 3] = float(centre[2]) - HEIGHT
    for _ in range(MAX_STEPS_BACK):
        if not collision_scene(robot, inst, base=base).collides(robot.home):
            break
        base[0, 3] += STEP_BACK
    return base


def plan_episode(
    inst: Instance,
    task: TaskAction,
    seed: int,
    *,
    base: np.ndarray | None = None,
    q_start: np.ndarray | None = None,
    to: float | None = None,
    also: tuple[str, ...] = (),
) -> ActionPlan:
    """The robot layer's plan for the task from where the object stands: an open to
    ``OPEN_TO`` of the range, a close to the closed end; where the arm cannot get that far,
    to ``REPLAN_AT`` of how far it can, when that moves the part ``MIN_STAGE`` of the range
    (the next stage goes on from there); where no grasp the arm can take carries the part to
    the end at all, ``SHORTER`` of the way (``_plan_shorter``). ``to``: plan to this joint
    value instead (and no shorter); ``also``: grasps tried besides the action's.

    Without ``base`` (the first stage) the base is placed for the object as it stands and
    ``plan_placed`` may move it; a partial plan is made from the placement that got furthest.
    With ``base`` (a later stage: the base stands where it stood) the arm starts at ``q_start``.
    """
    from grace_dsl.robot.act import ActionPlanningError, plan_action
    from grace_dsl.robot.choose import NoGraspError
    from grace_dsl.robot.placement import _centred, path_bases, placements, plan_placed

    robot = panda()
    shorter = to is None
    if to is None:
        to = _plan_to(inst, task)
    try:
        if base is None:
            first = robot_base(robot, inst, task.action)
            scored = path_bases(robot, inst, task.action, to, first)
            fixed = placements(inst, task.action, first, seed=seed, count=PLACEMENTS)
            centred = _centred(inst, task.action, to, first)
            fixed[1:1] = [centred] if centred is not None else []
            poses = _interleave(scored[:PATH_FIRST], fixed, PLACEMENTS)
            return plan_placed(
                robot, inst, task.action, to, seed=seed, count=PLACEMENTS, poses=poses, also=also
            ).plan
        return plan_action(
            robot,
            inst,
            task.action,
            to,
            base=base,
            q_start=q_start,
            seed=seed,
            checks=LATER,
            also=also,
        )
    except ActionPlanningError as exc:
        where = base if base is not None else exc.base
        try:
            return _plan_partial(robot, inst, task, exc, where, q_start, seed, also)
        except GraceError as failure:
            if not shorter:
                raise
            try:  # the part's other grasps, half way (a wide-open lid's side edge)
                return _plan_shorter(inst, task, to, seed, base, q_start)
            except GraceError:
                raise failure from None
    except NoGraspError:
        if not shorter:
            raise
        return _plan_shorter(inst, task, to, seed, base, q_start)


def _plan_shorter(
    inst: Instance,
    task: TaskAction,
    to: float,
    seed: int,
    base: np.ndarray | None,
    q_start: np.ndarray | None,
) -> ActionPlan:
    """A stage to ``SHORTER`` of the way to ``to``, the other grasps on the part the action
    moves tried too (``_link_grasps``), when no grasp the arm can take carries the part all the
    way: a wide-open laptop lid's front edge is out of reach from anywhere, its side edge is
    not, and the next stage takes the front edge half way down. Raises the stage's failure
    when none plans either."""
    from grace_dsl.robot.choose import NoGraspError

    lo, hi = inst.joint_limits()[task.joint]
    start = float(inst.joints[task.joint])
    failure: GraceError | None = None
    for fraction in SHORTER:
        partial = start + fraction * (to - start)
        if abs(partial - start) < MIN_STAGE * (hi - lo):
            break
        try:
            return plan_episode(
                inst,
                task,
                seed,
                base=base,
                q_start=q_start,
                to=partial,
                also=_link_grasps(inst, task.action),
            )
        except GraceError as exc:
            failure = failure or exc
    raise failure or NoGraspError(
        f"no usable grasp for {task.action} of {inst.concept.name} from {start:.3g}"
    )


def _link_grasps(inst: Instance, action: str) -> tuple[str, ...]:
    """The grasps on the link ``action`` moves that it does not name: ways to hold the part
    that the action's own do not list (a lid's side edges, which a flying hand, choosing by
    rank alone, would take even where they hold less than the front edge)."""
    spec = inst.concept.actions[action]
    if spec.joint is None:
        return ()
    child = inst.concept.joints[spec.joint].child
    using = set(spec.using)
    return tuple(
        g for g in inst.grasp_names if g not in using and inst.concept.grasps[g].link == child
    )


def _plan_to(inst: Instance, task: TaskAction) -> float:
    """Where a plan for ``task`` aims from the object as it stands: an open to ``OPEN_TO`` of
    the range (at least a tenth further than it is), a close to the closed end."""
    lo, hi = inst.joint_limits()[task.joint]
    start = float(inst.joints[task.joint])
    span = hi - lo
    to = min(max(lo + OPEN_TO * span, start + 0.1 * span), max(lo + FOLLOW_TO * span, start), hi)
    return to if task.sign > 0 else lo


def next_stage(
    inst: Instance,
    task: TaskAction,
    seed: int,
    base: np.ndarray,
    here: np.ndarray,
    *,
    move_base: bool = True,
) -> ActionPlan:
    """The plan of a later stage, the object at its measured joint value: the rest of the
    action from ``base`` with the arm at ``here`` when it plans all the way; else, with
    ``move_base``, from a base placed anew for the rest of the path (as for the first stage:
    ``path_bases`` scores bases on the hand's remaining path; the arm starts at home, as it
    would after the base drove there, which is not simulated); else (or when no placement
    plans at all) part of the way from ``base``, by the action's grasps or else the part's
    others (``_plan_shorter``). A second grasp of a wide door's handle from the first stage's
    base meets the same workspace edge the first did."""
    from grace_dsl.robot.act import ActionPlanningError, plan_action
    from grace_dsl.robot.choose import NoGraspError

    robot = panda()
    to = _plan_to(inst, task)
    try:
        return plan_action(
            robot, inst, task.action, to, base=base, q_start=here, seed=seed, checks=LATER
        )
    except (ActionPlanningError, NoGraspError) as kept:
        if move_base:
            try:
                return plan_episode(inst, task, seed)
            except GraceError:
                pass
        failure: GraceError = kept
        if isinstance(kept, ActionPlanningError):
            try:
                return _plan_partial(robot, inst, task, kept, base, here, seed)
            except GraceError as partial:
                failure = partial
        try:  # the part's other grasps, part of the way (a wide-open lid's side edge)
            return _plan_shorter(inst, task, to, seed, base, here)
        except GraceError:
            raise failure from None


def _plan_partial(
    robot: Robot,
    inst: Instance,
    task: TaskAction,
    failure: Exception,
    base: np.ndarray | None,
    q_start: np.ndarray | None,
    seed: int,
    also: tuple[str, ...] = (),
) -> ActionPlan:
    """A plan to ``REPLAN_AT`` of how far ``failure`` got; a partial plan may itself stop
    earlier (its samples fall elsewhere on the path), so up to ``PARTIAL_TRIES`` times, each to
    ``REPLAN_AT`` of the last failure's reach. Raises the last failure when a plan would move
    the part less than ``MIN_STAGE`` of the range, unless it ends where the task is done (a
    laptop lid 0.18 rad open whose last 0.004 rad the fingers cannot follow: a stage to 0.013
    rad closes it)."""
    from grace_dsl.robot.act import ActionPlanningError, plan_action

    lo, hi = inst.joint_limits()[task.joint]
    start = float(inst.joints[task.joint])
    for _ in range(PARTIAL_TRIES):
        value = getattr(failure, "value", None)
        if not isinstance(failure, ActionPlanningError) or value is None:
            raise failure
        partial = start + REPLAN_AT * (float(value) - start)
        if (partial - start) * task.sign < MIN_STAGE * (hi - lo) and not _finishes(
            task, partial, lo, hi
        ):
            raise failure
        try:
            return plan_action(
                robot,
                inst,
                task.action,
                partial,
                base=base,
                q_start=q_start,
                seed=seed,
                checks=LATER,
                also=also,
            )
        except ActionPlanningError as exc:
            failure = exc
    raise failure


def _finishes(task: TaskAction, value: float, lo: float, hi: float) -> bool:
    """Whether the part at ``value`` is where the stages stop: past ``OPEN_ENOUGH`` of the
    range for an open, within ``CLOSE_ENOUGH`` of the closed end for a close."""
    if task.sign > 0:
        return value >= lo + OPEN_ENOUGH * (hi - lo)
    return value <= lo + CLOSE_ENOUGH * (hi - lo)


def _interleave(scored: list[np.ndarray], fixed: list[np.ndarray], count: int) -> list[np.ndarray]:
    """``count`` base poses alternating between the path-scored ones and the fixed shifts
    (the best-scored first), none twice."""
    out: list[np.ndarray] = []
    for k in range(max(len(scored), len(fixed))):
        for pose in scored[k : k + 1] + fixed[k : k + 1]:
            if not any(np.allclose(pose, o) for o in out):
                out.append(pose)
    return out[:count]


@dataclass(frozen=True)
class Staged:
    """What the stages left behind: the last outcome, the options executed in turn, and why
    the arm stopped early when a stage could not be planned ("" when none was missing)."""

    outcome: Outcome
    options: tuple[str, ...]
    unplanned: str = ""
    no_grasp: bool = False
    bases: tuple[np.ndarray, ...] = ()  # each executed stage's base (world pose)


def execute_stages(
    inst: Instance,
    task: TaskAction,
    plan: ActionPlan,
    budget: float,
    seed: int,
    *,
    move_base: bool = True,
) -> Staged:
    """Execute ``plan`` and, while the part is short of the task's goal, plan again from the
    measured state (``next_stage``: the same base when the rest plans from there, else with
    ``move_base`` a base placed for the rest of the path) and execute that, up to ``STAGES``
    plans: as a person closes a wide door, follow it as far as the arm reaches, let go, step
    nearer, take it again. ``budget`` simulated seconds of interaction over all stages.

    A base that moves is a mobile manipulator's drive, not simulated: the world is built again
    with the object at its measured joint value (at rest: the hand let go and backed off) and
    the arm at the new plan's start."""
    from grace_dsl.robot.choose import NoGraspError

    robot = panda()
    world = ArmWorld.build(inst, plan.base, plan.q[0], robot.gripper)
    lo, hi = inst.joint_limits()[task.joint]
    span = hi - lo
    options = [f"{plan.choice.option.grasp} ({plan.choice.option.mode})"]
    bases = [np.asarray(plan.base, float)]
    left = budget
    for stage in range(STAGES):
        began = world.time
        outcome = execute_plan(inst, task, plan, left, world=world)
        left -= max(world.time - began - float(plan.t[-1]), 0.0)
        q = outcome.q_final
        done = q >= lo + OPEN_ENOUGH * span if task.sign > 0 else q <= lo + CLOSE_ENOUGH * span
        moved = abs(q - float(inst.joints[task.joint]))
        if done or outcome.unstable or stage == STAGES - 1:
            break
        # an arm stopped on its way in that still moved the part (a wide door it brushed, then
        # pushed part-way) plans again from where the part is, as after a stage that ended,
        # unless the task already counts as done
        reached = strict_success("open" if task.sign > 0 else "close", q, lo, hi)
        if (not outcome.arrived and reached) or moved < 0.01 * span or left <= 0.0:
            break
        inst = inst.with_joints({task.joint: q})
        here = np.clip(world.arm_q(), robot.lower, robot.upper)  # a motor may overshoot
        try:
            plan = next_stage(inst, task, seed, bases[-1], here, move_base=move_base)
        except NoGraspError as exc:
            return Staged(outcome, tuple(options), f"stage {stage + 2}: {exc}", True, tuple(bases))
        except GraceError as exc:
            return Staged(outcome, tuple(options), f"stage {stage + 2}: {exc}", False, tuple(bases))
        if not np.allclose(plan.base, bases[-1]) or not np.allclose(plan.q[0], here):
            world = ArmWorld.build(inst, plan.base, plan.q[0], robot.gripper)
        options.append(f"{plan.choice.option.grasp} ({plan.choice.option.mode})")
        bases.append(np.asarray(plan.base, float))
    return Staged(outcome, tuple(options), bases=tuple(bases))


@dataclass(frozen=True)
class _Phases:
    """The plan cut where the execution changes its controller."""

    move_in: JointTrajectory  # from the start to the grasp (the approach and the insert)
    interact_q: np.ndarray  # (K, 7) the planned interaction
    interact_values: np.ndarray  # (K,) the object's joint along it
    pinch: bool


def _cut(plan: ActionPlan) -> _Phases:
    spans = {name: (a, b) for name, a, b in plan.phases}
    _, stop = spans["insert"]
    a, b = spans["interact"]
    pinch = any(width == 0.0 for _, width in plan.gripper)
    return _Phases(
        JointTrajectory(np.asarray(plan.q[:stop]), np.asarray(plan.t[:stop])),
        np.asarray(plan.q[a:b]),
        np.asarray(plan.joint_values[a:b]),
        pinch,
    )


def execute_plan(
    inst: Instance,
    task: TaskAction,
    plan: ActionPlan,
    budget: float,
    *,
    world: ArmWorld | None = None,
    goal: float | None = None,
) -> Outcome:
    """Run ``plan`` on the simulated arm; ``budget`` simulated seconds of interaction. ``world``:
    an arm world already standing at ``plan.base`` and ``plan.q[0]`` (a previous stage's, or a
    room of several objects; default a fresh one of ``inst`` alone); ``goal``: the joint value
    to drive to (default the episode's). A plan that stops short of the task's end
    (``plan.to``) is followed to there and let go of where the hand is."""
    robot = panda()
    phases = _cut(plan)
    if world is None:
        world = ArmWorld.build(inst, plan.base, plan.q[0], robot.gripper)
    aimed = goal
    track = phases.move_in
    if plan.choice.option.mode == "hook":  # the closed fingertips go into a pocket, as the
        world.set_fingers(0.0, at_once=True)  # flying hand's do: open, they straddle it
    touched = [False]  # an arm link (not the hand) met the object on the way in

    def move_in(t: float) -> np.ndarray:
        touched[0] = touched[0] or world.arm_contact()
        return track_torque(world, *track.at(t))

    _run(world, float(track.t[-1]) + SETTLE, move_in)
    grasp = plan.base @ robot.fk(track.q[-1])
    now = world.hand_pose()
    arrived = not touched[0] and bool(
        np.linalg.norm(now[:3, 3] - grasp[:3, 3]) < ARRIVED
        and rotation_angle(now, grasp) < ARRIVED_ROT
    )
    hand = HandImpedance()
    if phases.pinch:  # in until the pads' middle, not their tips, closes on the part
        grasp = _pinch_in(world, inst, plan, grasp, hand)
        world.set_fingers(0.0)
        _run(world, CLOSE_TIME, lambda t: hand.torque(world, grasp, track.q[-1]))
        if world.opening() < EMPTY:
            return _finish(world, task, arrived, True, "the fingers closed on nothing")
    lo, hi = inst.joint_limits()[task.joint]
    goal = lo + FOLLOW_TO * (hi - lo) if task.sign > 0 else lo - PRESS_PAST * (hi - lo)
    partial = False
    if plan.to is not None:
        if task.sign > 0:
            goal = min(goal, float(plan.to))
        elif float(plan.to) > lo + CLOSE_ENOUGH * (hi - lo):  # a stage of a close
            goal, partial = float(plan.to), True
    goal = goal if aimed is None else aimed
    follower = PathFollower.from_grasp(inst, task.joint, grasp, goal, task.sign)
    # the budget is the interaction's, as the flying hand's (its approach takes half a second;
    # the arm's planned approach several)
    slipped = _follow(world, task, follower, phases, hand, lo, hi, budget)
    if world.unstable():
        return _finish(world, task, arrived, slipped, "the simulation became unstable", True)
    hold = follower.pose_at(goal) if task.sign < 0 and not slipped and not partial else None
    release = _release(inst, plan) if phases.pinch else None
    return _finish(world, task, arrived, slipped, "", hand=hand, hold=hold, release=release)


def _release(inst: Instance, plan: ActionPlan) -> float | None:
    """How far a pinch opens to let go, as the planner backed it out (``act.RELEASE`` wider
    than the part; None: fully)."""
    from grace_dsl.robot.act import RELEASE

    width = inst.grasp_width(plan.choice.option.grasp)
    return None if width is None else float(width) + RELEASE


def _pinch_in(
    world: ArmWorld, inst: Instance, plan: ActionPlan, grasp: np.ndarray, hand: HandImpedance
) -> np.ndarray:
    """The planner stops a pinch short of its grasp by the pads' standoff (their ends must not
    press into the part), but pads closing with their ends squeeze a round bar out, as the
    flying hand found: the hand goes on, compliantly, as deep as the flying hand's pinch
    (``deeper``: the open hand stays out of the part); returns the pose it closes at."""
    back = grasp.copy()
    back[:3, 3] += grasp[:3, 2] * plan.standoff
    gripper = panda().gripper
    start, posture = world.hand_pose(), world.arm_q()
    widths = _narrow(world, inst, plan, hand, start, posture)
    deep = deeper(inst, gripper, back, widths)
    t0 = world.time

    def move(t: float) -> np.ndarray:
        return hand.torque(world, blend(start, deep, (t - t0) / PINCH_IN_TIME), posture)

    _run(world, PINCH_IN_TIME + SETTLE / 2, move, absolute=True)
    return deep


def _narrow(
    world: ArmWorld,
    inst: Instance,
    plan: ActionPlan,
    hand: HandImpedance,
    pose: np.ndarray,
    posture: np.ndarray,
) -> tuple[float, float]:
    """Close the open hand to the part's width plus the flying hand's clearance where it stands
    (the planner's pose, clear of the object), as the flying hand comes in: a finger open to
    its full 80 mm under a laptop's lid lies under the base and would close on base and lid.
    Returns the openings (before, after closing) the pinch goes in with."""
    width = inst.grasp_width(plan.choice.option.grasp)
    full = panda().gripper.max_width
    if width is None:
        return full, full
    open_to = min(float(width) + 2 * CLEARANCE, full)
    world.set_fingers(open_to)
    _run(
        world,
        (full - open_to) / 2 / FINGER_SPEED + SETTLE / 3,
        lambda t: hand.torque(world, pose, posture),
    )
    return open_to, float(width)


def _posture(phases: _Phases, value: float) -> np.ndarray:
    """The plan's arm posture at the object's joint value ``value`` (clamped to the plan)."""
    values = phases.interact_values
    order = np.argsort(values)
    xs = values[order]
    return np.array([np.interp(value, xs, phases.interact_q[order, i]) for i in range(7)])


def _follow(
    world: ArmWorld,
    task: TaskAction,
    follower: PathFollower,
    phases: _Phases,
    hand: HandImpedance,
    lo: float,
    hi: float,
    seconds: float,
) -> bool:
    """Drive the hand along the path until the joint reaches its goal; True if it slipped."""
    span = hi - lo
    done_at = lo + (FOLLOW_TO - 0.05) * span if task.sign > 0 else lo + CLOSE_GOAL / 5 * span
    if task.sign > 0:  # the goal is where the target stops: done a little short of it
        done_at = min(done_at, follower.goal - DONE_SHORT * span)
    else:  # a close's stage may stop short of the closed end
        done_at = max(done_at, follower.goal + DONE_SHORT * span)
    end = world.time + max(seconds, 0.0)
    off_since: float | None = None
    q_ref = world.q(task.joint)
    target = follower.pose_at(q_ref)
    posture = _posture(phases, q_ref)
    tick = CONTROL_EVERY * world.model.opt.timestep
    steps = 0
    while world.time < end:
        q = world.q(task.joint)
        if (q - done_at) * task.sign >= 0:
            return False
        if steps % CONTROL_EVERY == 0:
            q_ref = follower.advance(q, q_ref, tick)
            target = follower.pose_at(q_ref)
            posture = _posture(phases, q)
            drift = float(np.linalg.norm(world.hand_pose()[:3, 3] - follower.pose_at(q)[:3, 3]))
            if drift > SLIP:
                off_since = world.time if off_since is None else off_since
                if world.time - off_since > SLIP_TIME:
                    return True
            else:
                off_since = None
            if world.unstable():
                return False
        world.step(hand.torque(world, target, posture))
        steps += 1
    return False


def _finish(
    world: ArmWorld,
    task: TaskAction,
    arrived: bool,
    slipped: bool,
    detail: str,
    unstable: bool = False,
    hand: HandImpedance | None = None,
    hold: np.ndarray | None = None,
    release: float | None = None,
) -> Outcome:
    """Let go (at ``hold``, else where the hand is; opening to ``release``, else fully, and
    fully once backed off), back off along the approach axis and settle; the joint value after
    that is the episode's result."""
    if not unstable:
        hand = hand or HandImpedance()
        posture = world.arm_q()
        hold = world.hand_pose() if hold is None else hold
        _run(world, SETTLE, lambda t: hand.torque(world, hold, posture))
        full = world.hand.finger_travel * 2
        world.set_fingers(full if release is None else min(release, full))
        _run(world, SETTLE, lambda t: hand.torque(world, hold, posture))
        back = hold.copy()
        back[:3, 3] -= hold[:3, 2] * RETREAT
        t0 = world.time

        def retreat(t: float) -> np.ndarray:
            return hand.torque(world, blend(hold, back, (t - t0) / SETTLE), world.arm_q())

        _run(world, 2 * SETTLE, retreat, absolute=True)
        world.set_fingers(full)
    q = world.q(task.joint)
    return Outcome(
        q if np.isfinite(q) else float("nan"),
        world.time,
        arrived,
        slipped,
        unstable or world.unstable(),
        detail,
    )


def _run(
    world: ArmWorld,
    seconds: float,
    torque: Callable[[float], np.ndarray],
    absolute: bool = False,
) -> None:
    """Step ``seconds`` with ``torque(t)`` (``t`` from this call's start, or the world's time
    when ``absolute``), recomputed every step."""
    t0 = 0.0 if absolute else world.time
    end = world.time + seconds
    steps = 0
    while world.time < end:
        if steps % CONTROL_EVERY == 0 and world.unstable():
            return
        world.step(torque(world.time - t0))
        steps += 1


def demo_arm_episode(
    concept: str = "CabinetDrawer", task: str = "open", seed: int = 0
) -> EpisodeRecord:
    """One arm episode for the demo: a drawer opened by the full Panda by default."""
    return run_arm_episode(EpisodeConfig(concept, task, agent="arm"), seed)  # type: ignore[arg-type]
