"""A default scene for planning: an instance in front of the robot, facing it.

The concept's front (+z) faces the robot's base (world −x), its up (+y) is the world's up, and the
instance is moved so that the middle of the action's grasps (at the middle of their free
parameters) sits ``REACH`` ahead of the base at ``HEIGHT``: where a Panda has the most room to
move. Where the robot's home configuration would touch the object there, the object steps back
until it does not. ``jitter`` moves the robot base (x, y, yaw) for seeded variations of a scene.

A fixed base cannot do every action from the default spot: a drop-down door's handle comes down
and toward the robot, a side-hinged door swings across it. ``plan_placed`` tries a few base
poses, the given one first, then the one moved along with the middle of the action's hand path,
then seeded shifts back and to the sides facing the grasps, and keeps the first from which the
whole action plans (``Placed.tried`` says how many it took).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.ik import IKOptions, solve_ik
from grace_dsl.robot.model import Robot
from grace_dsl.runtime.errors import GraceError, ParameterError

FloatArray = np.ndarray
FACING_ROBOT = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
REACH = 0.60  # metres ahead of the base where the action's grasps are centred
HEIGHT = 0.50  # metres above the base
STEP_BACK = 0.05  # metres the object moves away while the home configuration touches it
MAX_STEPS_BACK = 8
# Base shifts (metres, in the first base's frame) tried after it: back from the object (an
# opening door or drawer comes toward the robot), to either side (a door swings sideways), back
# and to the side (a drop-down door), closer (a lid or a roller door goes up and away).
SHIFTS = (
    (-0.1, 0.0),
    (-0.1, 0.1),
    (-0.1, -0.1),
    (-0.2, 0.0),
    (0.0, 0.15),
    (0.0, -0.15),
    (-0.15, 0.2),
    (-0.15, -0.2),
    (0.1, 0.0),
    (0.2, 0.0),
)
PLACEMENTS = 2 + len(SHIFTS)  # tried by plan_placed: the given base, the centred one, the shifts
JITTER = 0.02  # metres of seeded jitter on each shift


def default_instance(
    robot: Robot,
    concept: Any,
    action: str,
    params: Mapping[str, Any] | None = None,
) -> Any:
    """``concept`` instantiated with ``params`` in front of ``robot`` for ``action``."""
    if action not in concept.actions:
        known = ", ".join(concept.actions) or "none"
        raise ParameterError(f"{concept.name} has no action {action!r}; it has {known}")
    pose = np.eye(4)
    pose[:3, :3] = FACING_ROBOT
    inst = concept.instantiate(pose=pose, params=params or {})
    centre = _grasp_centre(inst, action)
    pose[:3, 3] += np.array([REACH, 0.0, HEIGHT]) - centre
    inst = concept.instantiate(pose=pose, params=params or {})
    for _ in range(MAX_STEPS_BACK):
        if not collision_scene(robot, inst).collides(robot.home):
            break
        pose[0, 3] += STEP_BACK
        inst = concept.instantiate(pose=pose, params=params or {})
    return inst


def _present(inst: Any, using: Any) -> list[str]:
    """The action's grasps this instance has (a variant's exist only where its option is
    chosen; a repeated part's only where its copy is) and that apply at its joint values (a
    grasp's ``when``)."""
    have = set(inst.grasp_names)
    return [g for g in using if g in have and inst.grasp_applies(g)]


def _grasp_centre(inst: Any, action: str) -> FloatArray:
    """The mean position of the action's grasps at the middle of their free parameters (the
    instance's origin for an action without grasps)."""
    spec = inst.concept.actions[action]
    points = []
    for name in _present(inst, spec.using):
        middle = {f: (lo + hi) / 2 for f, (lo, hi) in inst.grasp_range(name).items()}
        points.append(inst.grasp(name, free=middle)[:3, 3])
    return np.mean(points, axis=0) if points else inst.pose[:3, 3].copy()


def base_pose(x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> FloatArray:
    """The robot base's world pose: at (x, y) on the floor, turned by ``yaw`` about +z."""
    pose = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[:2, 3] = (x, y)
    return pose


def jitter(seed: int, shift: float = 0.05, turn: float = 0.15) -> FloatArray:
    """A seeded base pose near the origin (seed 0: the origin itself)."""
    if seed == 0:
        return np.eye(4)
    rng = np.random.default_rng(seed)
    x, y = rng.uniform(-shift, shift, 2)
    return base_pose(float(x), float(y), float(rng.uniform(-turn, turn)))


@dataclass(frozen=True)
class Placed:
    """A plan found by :func:`plan_placed`, the base pose it was planned from and how many base
    poses were tried (1: the first one worked)."""

    plan: Any  # grace_dsl.robot.act.ActionPlan
    base: FloatArray
    tried: int


def placements(
    inst: Any,
    action: str,
    base: FloatArray | None = None,
    *,
    seed: int = 0,
    count: int = PLACEMENTS,
) -> list[FloatArray]:
    """``count`` base poses to try for ``action`` on ``inst``: ``base`` (default the origin),
    then ``SHIFTS`` in that base's own frame (back from the object, to either side, closer) with a
    seeded jitter of ``JITTER`` metres, each turned to face the action's grasps. Deterministic
    for a seed."""
    first = np.eye(4) if base is None else np.asarray(base, float)
    target = np.linalg.inv(first) @ np.append(_grasp_centre(inst, action), 1.0)
    rng = np.random.default_rng(seed)
    out = [first]
    for dx, dy in SHIFTS[: max(0, count - 1)]:
        x, y = np.array([dx, dy]) + rng.uniform(-JITTER, JITTER, 2)
        yaw = math.atan2(target[1] - y, target[0] - x)
        out.append(first @ base_pose(float(x), float(y), yaw))
    return out


def _centred(inst: Any, action: str, to: float | None, base: FloatArray) -> FloatArray | None:
    """``base`` moved on the floor by as much as the middle of the action's hand path (from the
    grasps' centre, at the middle of their free parameters) lies off the grasps' centre: the
    robot stands where the motion, not only its start, is in front of it. None for an action
    that moves no joint or whose path cannot be computed."""
    spec = inst.concept.actions[action]
    using = _present(inst, spec.using)
    if spec.joint is None or not using:
        return None
    lo, hi = inst.joint_limits()[spec.joint]
    target = (hi if spec.opening else lo) if to is None else float(to)
    grasp = using[0]
    middle = {f: (a + b) / 2 for f, (a, b) in inst.grasp_range(grasp).items()}
    try:
        path = inst.follow(action, grasp=inst.grasp(grasp, free=middle), to=target, steps=9)
    except GraceError:
        return None
    shift = path[:, :3, 3].mean(axis=0) - path[0, :3, 3]
    moved = np.asarray(base, float).copy()
    moved[:2, 3] += shift[:2]
    return moved


def plan_placed(
    robot: Robot,
    inst: Any,
    action: str,
    to: float | None = None,
    *,
    base: FloatArray | None = None,
    seed: int = 0,
    count: int = PLACEMENTS,
    poses: list[FloatArray] | None = None,
    **options: Any,
) -> Placed:
    """``plan_action`` from the first of :func:`placements` (or of ``poses``, at most ``count``)
    that can do the action: a person opening a door steps to where they can, so does the
    robot's base here. When none can, raises
    the error of the placement whose plan got furthest (``act.progress``; its ``base`` set to
    that placement, so a caller can plan part of the way from there), naming how many were
    tried."""
    from grace_dsl.robot.act import ActionPlanningError, plan_action, progress

    spec = inst.concept.actions[action]
    start = float(inst.joints[spec.joint]) if spec.joint is not None else 0.0
    first: GraceError | None = None
    furthest: ActionPlanningError | None = None
    if poses is None:
        poses = placements(inst, action, base, seed=seed, count=count - 1)
        centred = _centred(inst, action, to, poses[0]) if count > 1 else None
        poses = poses[:1] + ([centred] if centred is not None else []) + poses[1:]
    else:
        poses = list(poses)[:count]
    start_q = robot.home if options.get("q_start") is None else options["q_start"]
    for k, pose in enumerate(poses):
        if collision_scene(robot, inst, base=pose).collides(start_q):
            # the arm could not even start there; planning the action first would waste the
            # time of its tracking and rank this placement above any that tracked less
            first = first or GraceError(
                f"{inst.concept.name}: the arm's start posture touches "
                "the object from this base placement"
            )
            continue
        try:
            plan = plan_action(robot, inst, action, to, base=pose, seed=seed, **options)
        except GraceError as exc:
            first = first or exc
            if isinstance(exc, ActionPlanningError) and (
                furthest is None or progress(exc, start) > progress(furthest, start)
            ):
                exc.base = pose
                furthest = exc
            continue
        return Placed(plan, pose, k + 1)
    assert first is not None
    if furthest is not None:
        raise ActionPlanningError(
            f"{furthest} ({len(poses)} base placements tried)",
            phase=furthest.phase,
            reason=furthest.reason,
            value=furthest.value,
            base=furthest.base,
        ) from None
    raise first


# Bases tried around the action's hand path (``path_bases``): distances from the path's middle
# (metres; the Panda has most room 0.4-0.7 m out) and bearings off the object's front (radians)
# (beside the object too: a lid's edge swings up in a plane a robot at its side faces)
PATH_RADII = (0.5, 0.65, 0.8)
PATH_BEARINGS = tuple(math.radians(a) for a in (-60, -35, -12, 12, 35, 60))
SIDE_BEARINGS = tuple(math.radians(a) for a in (-120, -90, 90, 120))
SIDE_RADII = (0.5, 0.65)
PATH_SAMPLES = 9  # poses along the hand path checked by IK per base
PATH_IK = IKOptions(max_restarts=0)


def hand_paths(
    inst: Any, action: str, to: float | None, steps: int = PATH_SAMPLES
) -> list[FloatArray]:
    """The hand's poses (steps, 4, 4) along ``action`` to ``to`` from each of its grasps at the
    middle of their free parameters (those that can be computed)."""
    spec = inst.concept.actions[action]
    if spec.joint is None:
        return []
    lo, hi = inst.joint_limits()[spec.joint]
    target = (hi if spec.opening else lo) if to is None else float(to)
    out = []
    for grasp in _present(inst, spec.using):
        middle = {f: (a + b) / 2 for f, (a, b) in inst.grasp_range(grasp).items()}
        try:
            pose = inst.grasp(grasp, free=middle)
            out.append(np.asarray(inst.follow(action, grasp=pose, to=target, steps=steps)))
        except GraceError:
            continue
    return out


def reach_score(robot: Robot, path: FloatArray, base: FloatArray) -> float:
    """The fraction of ``path`` the arm on ``base`` tracks from its start by IK (each pose
    warm-started from the last, no restarts: a branch switch counts as the end), a cheap
    forecast of how far the full plan will get."""
    if len(path) == 0:
        return 0.0
    to_base = np.linalg.inv(base)
    first = solve_ik(robot, to_base @ path[0], options=IKOptions())
    if not first.success:
        return 0.0
    q, reached = np.asarray(first.q), 1
    for pose in path[1:]:
        result = solve_ik(robot, to_base @ pose, q0=q, options=PATH_IK)
        if not result.success or float(np.max(np.abs(result.q - q))) > 4 * 0.2:
            break
        q, reached = np.asarray(result.q), reached + 1
    return reached / len(path)


def path_bases(
    robot: Robot, inst: Any, action: str, to: float | None, first: FloatArray
) -> list[FloatArray]:
    """Base poses for the whole of ``action``, not only its grasp: ``first`` and poses around
    the middle of the hand's path (``PATH_RADII`` out, at ``PATH_BEARINGS`` off the direction
    from the path's middle to ``first``, and beside it at ``SIDE_BEARINGS``; facing the path's
    middle, ``HEIGHT`` below it), those
    whose home posture touches the object left out, ordered by :func:`reach_score` (``first``
    ahead on ties; alone when the whole path is in reach from it). Deterministic."""
    paths = hand_paths(inst, action, to)
    if not paths:
        return [first]
    middle = paths[0][:, :3, 3].mean(axis=0)
    out = np.asarray(first, float)
    ahead = math.atan2(out[1, 3] - middle[1], out[0, 3] - middle[0])
    candidates = [out]
    candidates += _ring(middle, ahead, PATH_RADII, PATH_BEARINGS)
    candidates += _ring(middle, ahead, SIDE_RADII, SIDE_BEARINGS)
    if max(reach_score(robot, path, out) for path in paths) >= 1.0:
        return [out]  # the whole path is in reach from where the grasps put the base
    free = [c for c in candidates if not collision_scene(robot, inst, base=c).collides(robot.home)]
    scores = [max(reach_score(robot, path, c) for path in paths) for c in free]
    order = sorted(range(len(free)), key=lambda k: (-scores[k], k))
    return [free[k] for k in order] or [first]


def _ring(
    middle: FloatArray, ahead: float, radii: tuple[float, ...], bearings: tuple[float, ...]
) -> list[FloatArray]:
    """Base poses ``radii`` from ``middle`` at ``bearings`` off the direction ``ahead``, facing
    ``middle``, ``HEIGHT`` below it."""
    out = []
    for radius in radii:
        for bearing in bearings:
            a = ahead + bearing
            x, y = middle[0] + radius * math.cos(a), middle[1] + radius * math.sin(a)
            pose = base_pose(x, y, math.atan2(middle[1] - y, middle[0] - x))
            pose[2, 3] = middle[2] - HEIGHT
            out.append(pose)
    return out
