"""Collision-free joint paths with OMPL, shortcut, re-checked densely and timed.

``plan_path`` asks OMPL's RRTConnect for a path in joint space whose states the collision scene
accepts, lets OMPL shortcut it, and then checks every segment itself at a fixed joint-space
resolution (OMPL's own motion check samples too, but a plan is only returned once this module has
seen it free). ``time_path`` gives each segment the duration of a trapezoidal velocity profile
under the robot's velocity limits and an acceleration limit, stopping at each waypoint: slow
but exactly within limits, which is what an executed plan must be.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.robot.collision import CollisionScene
from grace_dsl.runtime.errors import GraceError

FloatArray = np.ndarray
CHECK_RESOLUTION = 0.01  # radians between collision checks along a segment
DEFAULT_ACCELERATION = 5.0  # rad/s², a gentle fraction of the Panda's 7.5-20 rad/s²


class PlanningError(GraceError):
    """No collision-free path was found (or the start or goal itself collides)."""


@dataclass(frozen=True)
class JointPath:
    """Waypoints ``q`` (K, nq) and their times ``t`` (K,), starting at t = 0."""

    q: FloatArray
    t: FloatArray

    @property
    def duration(self) -> float:
        return float(self.t[-1])


def plan_path(
    scene: CollisionScene,
    start: Any,
    goal: Any,
    *,
    time_limit: float = 2.0,
    seed: int = 0,
    resolution: float = CHECK_RESOLUTION,
) -> FloatArray:
    """A collision-free joint path (K, nq) from ``start`` to ``goal``, shortcut and re-checked."""
    robot = scene.robot
    q0, q1 = robot.check_q(start), robot.check_q(goal)
    for name, q in (("start", q0), ("goal", q1)):
        if scene.collides(q):
            hit = scene.contacts(q)[:1]
            what = f" ({hit[0].first} touches {hit[0].second})" if hit else ""
            raise PlanningError(f"the {name} configuration is in collision{what}")
    if segment_free(scene, q0, q1, resolution):
        return np.stack([q0, q1])
    waypoints = _ompl_path(scene, q0, q1, time_limit, seed, resolution)
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        if not segment_free(scene, a, b, resolution):
            raise PlanningError("OMPL returned a path that collides between its waypoints")
    return waypoints


def segment_free(scene: CollisionScene, a: FloatArray, b: FloatArray, resolution: float) -> bool:
    """True when every configuration on the straight joint segment a-b is free (checked every
    ``resolution`` radians on the joint that moves most, both ends included)."""
    steps = max(1, math.ceil(float(np.max(np.abs(b - a))) / resolution))
    return not any(scene.collides(a + (b - a) * s) for s in np.linspace(0.0, 1.0, steps + 1))


def _ompl_path(
    scene: CollisionScene,
    q0: FloatArray,
    q1: FloatArray,
    time_limit: float,
    seed: int,
    resolution: float,
) -> FloatArray:
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_ERROR)
    _seed_once(ou, seed)
    robot = scene.robot
    space = ob.RealVectorStateSpace(robot.nq)
    bounds = ob.RealVectorBounds(robot.nq)
    for i in range(robot.nq):
        bounds.setLow(i, float(robot.lower[i]))
        bounds.setHigh(i, float(robot.upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    n = robot.nq
    setup.setStateValidityChecker(lambda s: not scene.collides([s[i] for i in range(n)]))
    extent = float(np.linalg.norm(robot.upper - robot.lower))
    setup.getSpaceInformation().setStateValidityCheckingResolution(resolution / extent)
    start, goal = space.allocState(), space.allocState()
    for i in range(n):
        start[i], goal[i] = float(q0[i]), float(q1[i])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(setup.getSpaceInformation()))
    began = time.perf_counter()
    solved = setup.solve(time_limit)
    if not solved or not setup.haveExactSolutionPath():
        raise PlanningError(
            f"no collision-free path found in {time.perf_counter() - began:.2f} s "
            f"(time limit {time_limit:g} s)"
        )
    setup.simplifySolution(min(0.5, time_limit / 4))
    path = setup.getSolutionPath()
    return np.array([[path.getState(k)[i] for i in range(n)] for k in range(path.getStateCount())])


_SEEDED: list[int] = []


def _seed_once(ou: Any, seed: int) -> None:
    """OMPL seeds every sampler from one process-wide generator that can be seeded only before
    its first use: the first plan's seed fixes the sequence of the whole process, so a process
    that plans the same problems in the same order gets the same paths."""
    if not _SEEDED:
        ou.RNG.setSeed(seed)
        _SEEDED.append(seed)


def time_path(
    waypoints: FloatArray,
    velocity: FloatArray,
    acceleration: float = DEFAULT_ACCELERATION,
) -> JointPath:
    """Times for ``waypoints``: each segment a trapezoidal profile, rest to rest, synchronized on
    its slowest joint, within ``velocity`` (per joint) and ``acceleration`` (every joint)."""
    q = np.asarray(waypoints, dtype=float)
    times = [0.0]
    for a, b in zip(q[:-1], q[1:]):
        times.append(
            times[-1] + max(_trapezoid(abs(d), v, acceleration) for d, v in zip(b - a, velocity))
        )
    t = np.asarray(times)
    q.setflags(write=False)
    t.setflags(write=False)
    return JointPath(q, t)


def _trapezoid(distance: float, vmax: float, amax: float) -> float:
    """The shortest rest-to-rest time over ``distance`` with speed and acceleration bounds."""
    if distance <= vmax * vmax / amax:  # triangular: never reaches vmax
        return 2.0 * math.sqrt(distance / amax)
    return distance / vmax + vmax / amax
