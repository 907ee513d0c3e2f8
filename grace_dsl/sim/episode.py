"""One physical episode with a flying hand: a pure function of (config, seed).

The protocol (``grace_dsl.sim.protocol``) draws the object, its initial joint value and the
camera; ``inst.rank`` picks the manipulation function (the best feasible option for this hand);
the hand then comes in along its approach axis to the grasp, closes or not according to the
option's mode (pinch closes on the part; hook, push and press keep the fingers shut), follows the
action's path with the compliant controller (``grace_dsl.sim.control``: the target re-anchored on
the measured joint value), lets go and backs off. A physical failure is a record with a reason
from ``FAILURE_REASONS``, never an exception; a bad configuration raises.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from grace_dsl.runtime.errors import GraceError, ParameterError, RequirementError
from grace_dsl.runtime.gripper import Gripper, box_surface_grid
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Library
from grace_dsl.runtime.manipulation import CLEARANCE, Option
from grace_dsl.sim.control import PathFollower, blend, rotation_angle
from grace_dsl.sim.engines import ENGINES, HandWorld, build_world
from grace_dsl.sim.hand_motion import follower_for
from grace_dsl.sim.model import zup_pose
from grace_dsl.sim.protocol import (
    CLOSE_GOAL,
    MOVED,
    Draw,
    TaskAction,
    draw_episode,
    lenient_success,
    strict_success,
    task_action,
)
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord
from grace_dsl.sim.world import World

# The object's +y (up in a concept) is world +z; its front (+z) faces world +x.
Z_UP = zup_pose(yaw=math.pi / 2)
BACK_OFF = 0.06  # m the hand starts behind the grasp, beyond the hand's approach distance
APPROACH_SPEED = 0.25  # m/s along the approach line
SETTLE = 0.3  # s held at the grasp before closing, and after letting go
CLOSE_TIME = 0.5  # s for the fingers to close on the part
ARRIVED = 0.015  # m: the hand reached the grasp if this close after the approach
ARRIVED_ROT = math.radians(8.0)
EMPTY = 0.002  # m: pads closer than this after closing held nothing
FOLLOW_TO = 0.9  # fraction of the range an open follows to (strict needs 0.5)
SLIP = 0.05  # m the hand may drift off the path at the measured joint value before it slipped
SLIP_TIME = 0.3  # s the drift must last
CONTROL_EVERY = 5  # physics steps per re-anchoring of the target (100 Hz at 2 ms)
PRESS_PAST = 0.03  # fraction of the range a close aims past its stop (pressing it home)
PRESS_MIN = 0.01  # m of hand travel a close aims past its stop at least (15 N at 1500 N/m)
RETREAT = 0.1  # m backed off along -z after letting go
PINCH_DEPTHS = (0.012, 0.009, 0.006, 0.003)  # m a pinch goes in past its grasp origin, tried
PENETRATION = 0.002  # m the hand may touch the object at the deeper pinch
CLOSING_CHECKS = 4  # openings checked between the open hand and the closed pinch
PATH_CHECKS = 6  # joint values checked along the path with the closed pinch
STILL_TIME = 2.0  # s a part sent to an explicit goal may take to come to rest in the hand
STILL_SPEED = 0.005  # m/s or rad/s: at rest
GOAL_TOLERANCE = 0.01  # fraction of the range short of an explicit goal that counts as there
STALL_TIME = 0.5  # s: past the model's goal, a joint that moves less than STALL_MOVE in this
STALL_MOVE = 0.002  # m or rad: ... has stopped (its real stop, or the hand's force limit)


def run_episode(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """Run one episode of ``config`` with ``seed``; the same pair gives the same record."""
    return episode_and_world(config, seed)[0]


def episode_and_world(
    config: EpisodeConfig, seed: int, trace_every: int = 0
) -> tuple[EpisodeRecord, World | None]:
    """``run_episode``'s record and the world as the episode left it (None if the hand never
    moved); ``trace_every`` > 0 records every body's pose that often (physics steps) on the
    world, for a replay. Recording changes nothing in the physics."""
    _check_config(config)
    if config.agent == "arm":  # the full Panda: planned by the robot layer (sim.arm_episode)
        from grace_dsl.sim.arm_episode import run_arm_episode

        return run_arm_episode(config, seed), None
    started = time.perf_counter()
    start = start_episode(config, seed, started)
    if isinstance(start, EpisodeRecord):
        return start, None
    task, draw, inst = start.task, start.draw, start.inst
    gripper = Gripper.load(config.hand)
    try:
        options = inst.rank(task.action, gripper=gripper)
    except GraceError as exc:
        early = _early(config, seed, task, "no_feasible_grasp", str(exc), started, draw, inst)
        return early, None
    usable = [o for o in options if o.feasible]
    if not usable:
        why = "; ".join(f"{o.grasp}: {o.reasons[0]}" for o in options if o.reasons) or "no option"
        return _early(config, seed, task, "no_feasible_grasp", why, started, draw, inst), None
    if config.engine != "mujoco" and trace_every:
        raise ParameterError("a replay traces a MuJoCo world: run it with engine='mujoco'")
    outcome = execute(
        inst, task, usable[0], gripper, config.max_seconds, trace_every, engine=config.engine
    )
    record = outcome_record(config, seed, task, draw, inst, outcome, usable[0], started)
    return record, outcome.world if isinstance(outcome.world, World) else None


@dataclass(frozen=True)
class Start:
    """An episode's seeded draw made into the object it acts on."""

    task: TaskAction
    draw: Draw
    ranges: str  # "typical", or "valid" for a scaled draw or a config that asks for it
    inst: Instance  # the true object, z-up at the origin, at the draw's initial joint value


def start_episode(config: EpisodeConfig, seed: int, started: float) -> Start | EpisodeRecord:
    """The task, the seeded draw and the true instance of episode ``seed`` of ``config`` (every
    agent's episode begins so); a draw that meets no requirement of the concept is the early
    ``invalid_draw`` record instead."""
    concept = _library()[config.concept]
    task = task_action(concept, config.task)
    try:
        draw = draw_episode(config, concept, seed)
    except RequirementError as exc:
        return _early(config, seed, task, "invalid_draw", str(exc), started)
    ranges = "valid" if draw.scale != 1.0 or config.ranges == "valid" else "typical"
    inst = concept.instantiate(
        pose=Z_UP, joints={task.joint: draw.q_initial}, ranges=ranges, params=draw.params
    )
    return Start(task, draw, ranges, inst)


def outcome_record(
    config: EpisodeConfig,
    seed: int,
    task: TaskAction,
    draw: Draw,
    inst: Instance,
    outcome: Outcome,
    option: Option,
    started: float,
) -> EpisodeRecord:
    """The record of an episode that executed ``option`` (the flying hand's or the arm's):
    both success criteria on the final joint value, and the failure's reason when strict fails."""
    lo, hi = inst.joint_limits()[task.joint]
    strict = strict_success(config.task, outcome.q_final, lo, hi)
    lenient = lenient_success(config.task, draw.q_initial, outcome.q_final)
    reason, detail = ("", outcome.detail) if strict else _failure(config, draw, outcome)
    return EpisodeRecord(
        config=config,
        seed=seed,
        joint=task.joint,
        q_range=(lo, hi),
        q_initial=draw.q_initial,
        q_final=outcome.q_final,
        lenient=lenient,
        strict=strict,
        reason=reason,
        detail=detail,
        params=_jsonable(draw.params),
        camera=_camera(draw, inst),
        option=f"{option.grasp} ({option.mode})",
        sim_seconds=outcome.sim_seconds,
        wall_seconds=time.perf_counter() - started,
    )


@dataclass(frozen=True)
class Outcome:
    """What the hand's execution left behind."""

    q_final: float
    sim_seconds: float
    arrived: bool  # the hand reached the grasp pose
    slipped: bool  # the hand lost the part while following
    unstable: bool = False
    detail: str = ""
    world: HandWorld | None = field(default=None, compare=False, repr=False)
    #: a pinch's fingers had closed on nothing when the follow ended: the part slipped out of
    #: them (the hand itself stays on the path, so the drift check does not see it)
    emptied: bool = False


def execute(
    inst: Instance,
    task: TaskAction,
    option: Option,
    gripper: Gripper,
    budget: float,
    trace_every: int = 0,
    *,
    goal: float | None = None,
    world: HandWorld | None = None,
    engine: str = "mujoco",
    relative: bool = False,
    beyond: float = 0.0,
) -> Outcome:
    """Approach, close (pinch), follow, let go and back off; ``budget`` simulated seconds.

    ``goal``: a joint value to stop at instead of the task's default (``FOLLOW_TO`` of the range
    for an open, pressed past the stop for a close). ``world``: act in this world (several
    objects, joint states kept between calls: ``grace_dsl.sim.multi``) with the hand placed at
    the pre-grasp, instead of a new world of ``inst`` alone; ``budget`` counts from the call.
    ``engine``: the physics of a new world (``grace_dsl.sim.engines``).

    For a model that is an estimate (the agent's, not the simulator's): ``relative`` reads
    the measured joint as its motion since the follow began, added to the model's joint value
    (the model's zero is the estimate's, the encoder's the world's: only the motion is shared;
    otherwise a joint estimated 45 mm off starts the path 45 mm off the grasp), and ``beyond``
    (joint units, > 0) lets the path go on that far past the model's goal while the measured
    joint still moves (a closed drawer's travel is not in any view: the path must not end where
    the estimated travel does); it ends when the joint stops (``STALL_TIME``). Both default
    off: the oracle's execution is unchanged."""
    grasp = option.hand_pose if option.hand_pose is not None else option.pose
    assert grasp is not None
    pinch = option.mode == "pinch"
    width = inst.grasp_width(option.grasp) if pinch else None
    open_to = gripper.max_width if width is None else min(width + 2 * CLEARANCE, gripper.max_width)
    lo, hi = inst.joint_limits()[task.joint]
    aimed = goal is not None
    if goal is None:
        goal = lo + FOLLOW_TO * (hi - lo) if task.sign > 0 else lo - PRESS_PAST * (hi - lo)
    if pinch:
        closed = open_to if width is None else width
        grasp = deeper(inst, gripper, grasp, (open_to, closed), _path_of(inst, task, goal))
    start = grasp.copy()
    start[:3, 3] -= grasp[:3, 2] * (gripper.approach_distance + BACK_OFF)
    if world is None:
        world = build_world(engine, inst, gripper, start, driven=task.joint)
    else:
        world.place_hand(start)
    world.trace_every = trace_every
    began = world.time
    if pinch:
        world.set_fingers(open_to, at_once=True)
    travel = float(np.linalg.norm(grasp[:3, 3] - start[:3, 3]))
    duration = travel / APPROACH_SPEED
    t0 = world.time
    _run(world, duration + SETTLE, lambda: blend(start, grasp, (world.time - t0) / duration))
    now = world.hand_pose()
    arrived = bool(
        np.linalg.norm(now[:3, 3] - grasp[:3, 3]) < ARRIVED
        and rotation_angle(now, grasp) < ARRIVED_ROT
    )
    if pinch:
        world.set_fingers(0.0)
        _run(world, CLOSE_TIME, lambda: grasp)
        if world.opening() < EMPTY:
            return _finish(world, task, arrived, True, "the fingers closed on nothing")
    follower = follower_for(gripper, inst, task.joint, grasp, goal, task.sign)
    if task.sign < 0 and not aimed:  # a short lever's 3 % is a fraction of a mm: friction wins
        past = follower.lookahead(lo) * PRESS_MIN / follower.lead
        follower = replace(follower, goal=min(goal, lo - past))
    done_at = goal - task.sign * GOAL_TOLERANCE * (hi - lo) if aimed else None
    offset = float(inst.joints[task.joint]) - world.q(task.joint) if relative else 0.0
    stalled_from = None
    if beyond > 0.0:  # on past the model's goal while the joint moves
        stalled_from = done_at if done_at is not None else _done_at(task, lo, hi)
        follower = replace(follower, goal=follower.goal + task.sign * beyond)
        done_at = follower.goal
    slipped = _follow(world, task, follower, lo, hi, budget - (world.time - began), done_at,
                      offset, stalled_from)  # fmt: skip
    emptied = pinch and world.opening() < EMPTY
    if world.unstable():
        return _finish(world, task, arrived, slipped, "the simulation became unstable", True)
    # a part sent to an explicit goal is held there until it stops (let go where the hand is, it
    # springs back and coasts away); a closed part is held pressed against its stop while the
    # hand lets go: the hand as at the stop, pushed on to where the path goes past it (not turned
    # past it too: a short lever pinched and twisted beyond its stop sprang back up 0.03 rad)
    reached = done_at is not None and (world.q(task.joint) + offset - done_at) * task.sign >= 0
    hold = None
    if stalled_from is not None and not slipped:  # held where the joint stopped, a lead on
        hold = follower.target(world.q(task.joint) + offset)
    elif reached and not slipped:
        hold = follower.pose_at(goal)
        _still(world, task.joint, hold)
    elif task.sign < 0 and not slipped:
        hold = follower.pose_at(lo)
        hold[:3, 3] = follower.pose_at(follower.goal)[:3, 3]
    return _finish(world, task, arrived, slipped, "", hold=hold, emptied=emptied)


def _still(world: HandWorld, joint: str, hold: np.ndarray) -> None:
    """Hold at ``hold`` until ``joint`` stops (at most ``STILL_TIME``): the hand and the part
    it grips swing on the hand's spring, and a part let go while moving coasts on."""
    end = world.time + STILL_TIME
    while world.time < end and not world.unstable():
        _run(world, CONTROL_EVERY * world.timestep * 5, lambda: hold)
        if abs(world.qdot(joint)) < STILL_SPEED:
            return


def deeper(
    inst: Instance,
    gripper: Gripper,
    grasp: np.ndarray,
    widths: tuple[float, float],
    path: Callable[[np.ndarray], list[tuple[Instance, np.ndarray]]] | None = None,
) -> np.ndarray:
    """The pinch pose moved in along its approach so that the pads' middle, not their tips'
    edge, closes on the part: the deepest of ``PINCH_DEPTHS`` at which the hand enters the object
    by less than ``PENETRATION`` (a grasp's origin sits at the fingertips, where a round bar
    squeezes out). ``widths`` is (open, closed): the hand is checked open, at openings while it
    closes (a pad that passes under a laptop's base would close on the base with the lid), and,
    given ``path`` (the object and the hand pose along the follow path for a grasp pose), closed
    along the path (a pad deep under a lid's lip lands on the box's wall as the lid shuts)."""
    open_to, closed = widths
    sweep = [_hand_points(gripper, w) for w in np.linspace(open_to, closed, CLOSING_CHECKS)]
    for depth in PINCH_DEPTHS:
        pose = grasp.copy()
        pose[:3, 3] += grasp[:3, 2] * depth
        checks = [(inst, pose, points) for points in sweep]
        if path is not None:
            checks += [(at, hand, sweep[-1]) for at, hand in path(pose)]
        if all(_clear(at, hand, points) for at, hand, points in checks):
            return pose
    return grasp


def _hand_points(gripper: Gripper, width: float) -> np.ndarray:
    """Points on the surface of every box of the hand opened to ``width`` (gripper frame)."""
    boxes = gripper.hand_boxes(min(width, gripper.max_width))
    return np.concatenate([box_surface_grid(b, 0.003) for b in boxes])


def _clear(inst: Instance, pose: np.ndarray, points: np.ndarray) -> bool:
    """The hand's ``points`` at ``pose`` enter ``inst`` by less than ``PENETRATION``."""
    return float(np.min(inst.sdf(points @ pose[:3, :3].T + pose[:3, 3]))) > -PENETRATION


def _path_of(
    inst: Instance, task: TaskAction, goal: float
) -> Callable[[np.ndarray], list[tuple[Instance, np.ndarray]]]:
    """For a grasp pose: the object and the hand (riding the moving link) at ``PATH_CHECKS``
    joint values from the start towards ``goal`` (within the joint's range)."""
    lo, hi = inst.joint_limits()[task.joint]
    q0 = inst.joints[task.joint]
    qs = np.linspace(q0, min(max(goal, lo), hi), PATH_CHECKS + 1)[1:]
    moved = [inst.with_joints({task.joint: float(q)}) for q in qs]

    def along(pose: np.ndarray) -> list[tuple[Instance, np.ndarray]]:
        follower = PathFollower.from_grasp(inst, task.joint, pose, goal, task.sign)
        return [(at, follower.pose_at(float(q))) for at, q in zip(moved, qs, strict=True)]

    return along


def _follow(
    world: HandWorld,
    task: TaskAction,
    follower: PathFollower,
    lo: float,
    hi: float,
    seconds: float,
    done_at: float | None = None,
    offset: float = 0.0,
    stall_past: float | None = None,
) -> bool:
    """Drive along the path until the joint reaches ``done_at`` (default: near the task's
    goal); True if the hand slipped off. The path's joint value is the measured one plus
    ``offset``; past ``stall_past`` (if given) the drive also ends when the joint stops."""
    if done_at is None:
        done_at = _done_at(task, lo, hi)
    end = world.time + max(seconds, 0.0)
    off_since: float | None = None
    q_ref = world.q(task.joint) + offset
    target = follower.pose_at(q_ref)
    tick = CONTROL_EVERY * world.timestep
    steps = 0
    since: tuple[float, float] | None = None  # (time, q) the stall is measured from
    while world.time < end:
        q = world.q(task.joint) + offset
        if (q - done_at) * task.sign >= 0:
            return False
        if stall_past is not None and (q - stall_past) * task.sign >= 0:
            if since is None or abs(q - since[1]) >= STALL_MOVE:
                since = (world.time, q)
            elif world.time - since[0] >= STALL_TIME:
                return False
        if steps % CONTROL_EVERY == 0:
            q_ref = follower.advance(q, q_ref, tick)
            target = follower.pose_at(q_ref)
            drift = float(np.linalg.norm(world.hand_pose()[:3, 3] - follower.pose_at(q)[:3, 3]))
            if drift > SLIP:
                off_since = world.time if off_since is None else off_since
                if world.time - off_since > SLIP_TIME:
                    return True
            else:
                off_since = None
        world.step(target)
        steps += 1
        if steps % CONTROL_EVERY == 0 and world.unstable():
            return False
    return False


def _done_at(task: TaskAction, lo: float, hi: float) -> float:
    """Where a follow to the task's default goal ends: near ``FOLLOW_TO`` of the range for an
    open, a fifth of the strict close's margin above the stop for a close."""
    span = hi - lo
    return lo + (FOLLOW_TO - 0.05) * span if task.sign > 0 else lo + CLOSE_GOAL / 5 * span


def _finish(
    world: HandWorld,
    task: TaskAction,
    arrived: bool,
    slipped: bool,
    detail: str,
    unstable: bool = False,
    hold: np.ndarray | None = None,
    emptied: bool = False,
) -> Outcome:
    """Let go (at ``hold``, else where the hand is), back off and settle; the joint value
    after that is the episode's result."""
    if not unstable:
        hold = world.hand_pose() if hold is None else hold
        _run(world, SETTLE, lambda: hold)  # still holding: the part stops with the hand
        world.set_fingers(world.hand.finger_travel * 2)
        _run(world, SETTLE, lambda: hold)
        back = hold.copy()
        back[:3, 3] -= hold[:3, 2] * RETREAT
        t0 = world.time
        _run(world, 2 * SETTLE, lambda: blend(hold, back, (world.time - t0) / SETTLE))
    q = world.q(task.joint)
    return Outcome(
        q if math.isfinite(q) else float("nan"),
        world.time,
        arrived,
        slipped,
        unstable or world.unstable(),
        detail,
        world,
        emptied,
    )


def _run(world: HandWorld, seconds: float, target: Callable[[], np.ndarray]) -> None:
    end = world.time + seconds
    goal = target()
    steps = 0
    while world.time < end:
        if steps % CONTROL_EVERY == 0:
            if world.unstable():
                return
            goal = target()
        world.step(goal)
        steps += 1


def _failure(config: EpisodeConfig, draw: Draw, out: Outcome) -> tuple[str, str]:
    """The reason a strict failure happened, from what the execution saw."""
    moved = out.q_final - draw.q_initial
    sign = 1.0 if config.task == "open" else -1.0
    if out.unstable:
        return "timeout", out.detail or "the simulation became unstable"
    if not out.arrived:
        return "collision", "the hand was stopped on its way to the grasp"
    if sign * moved <= -MOVED:
        return "wrong_direction", f"the joint moved {moved:+.3f} against the task"
    if out.slipped:
        return "slip", out.detail or "the hand came off the part while following the path"
    if out.emptied:
        return "slip", f"the part slipped out of the fingers after moving {moved:+.3f}"
    return "timeout", f"the joint moved {moved:+.3f} and stopped short of the goal"


def _early(
    config: EpisodeConfig,
    seed: int,
    task: TaskAction,
    reason: str,
    detail: str,
    started: float,
    draw: Draw | None = None,
    inst: Instance | None = None,
) -> EpisodeRecord:
    """The record of an episode that never touched the object."""
    q0 = draw.q_initial if draw is not None else float("nan")
    q_range = inst.joint_limits()[task.joint] if inst is not None else (float("nan"),) * 2
    return EpisodeRecord(
        config=config,
        seed=seed,
        joint=task.joint,
        q_range=(float(q_range[0]), float(q_range[1])),
        q_initial=q0,
        q_final=q0,
        lenient=False,
        strict=False,
        reason=reason,
        detail=detail,
        params=_jsonable(draw.params) if draw is not None else {},
        camera=_camera(draw, inst) if draw is not None and inst is not None else {},
        wall_seconds=time.perf_counter() - started,
    )


def _camera(draw: Draw, inst: Instance) -> dict[str, float]:
    """The drawn camera with a distance that frames the object (3 times its bounding radius)."""
    lo, hi = inst.mesh(resolution=16).bounds
    radius = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo))) / 2
    return {**draw.camera, "distance": round(3.0 * max(radius, 0.05), 4)}


def _jsonable(params: dict[str, object]) -> dict[str, object]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()}


def _check_config(config: EpisodeConfig) -> None:
    if config.agent not in ("gripper", "arm"):
        raise ParameterError(
            f"agent {config.agent!r} is unknown: run_episode drives a flying hand "
            "(agent='gripper') or the full Panda (agent='arm')"
        )
    if config.mode != "oracle" or config.engine not in ENGINES:
        raise ParameterError(
            f"mode {config.mode!r} on engine {config.engine!r}: only mode='oracle' runs today, "
            f"on an engine of {ENGINES}"
        )
    if config.engine != "mujoco" and config.agent != "gripper":
        raise ParameterError(
            f"engine {config.engine!r} drives the flying hand (agent='gripper'); the full "
            "Panda (agent='arm') runs on engine='mujoco'"
        )
    if config.task not in ("open", "close"):
        raise ParameterError(f"task must be 'open' or 'close', not {config.task!r}")


def _library() -> Library:
    """The standard library, loaded once per process: the runner's copy (its workers warm it),
    so a process that runs episodes and checks a bench's arguments loads it once, not twice."""
    from grace_dsl.sim.runner import shared_library

    library: Library = shared_library()
    return library
