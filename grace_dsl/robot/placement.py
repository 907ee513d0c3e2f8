"""A default scene for planning: an instance in front of the robot, facing it.

The concept's front (+z) faces the robot's base (world −x), its up (+y) is the world's up, and the
instance is moved so that the middle of the action's grasps (at the middle of their free
parameters) sits ``REACH`` ahead of the base at ``HEIGHT``: where a Panda has the most room to
move. Where the robot's home configuration would touch the object there, the object steps back
until it does not. ``jitter`` moves the robot base (x, y, yaw) for seeded variations of a scene.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.runtime.errors import ParameterError

FloatArray = np.ndarray
FACING_ROBOT = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
REACH = 0.60  # metres ahead of the base where the action's grasps are centred
HEIGHT = 0.50  # metres above the base
STEP_BACK = 0.05  # metres the object moves away while the home configuration touches it
MAX_STEPS_BACK = 8


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


def _grasp_centre(inst: Any, action: str) -> FloatArray:
    """The mean position of the action's grasps at the middle of their free parameters (the
    instance's origin for an action without grasps)."""
    spec = inst.concept.actions[action]
    points = []
    for name in spec.using:
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
