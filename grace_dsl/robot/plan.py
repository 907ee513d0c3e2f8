"""Collision-free joint paths with OMPL, shortcut, re-checked densely and timed.

``plan_path`` asks OMPL's RRTConnect for a path in joint space whose states the collision scene
accepts, lets OMPL shortcut it, and then checks every segment itself at a fixed joint-space
resolution (OMPL's own motion check samples too, but a plan is only returned once this module has
seen it free). ``time_path`` gives each segment the duration of a trapezoidal velocity profile
under the robot's velocity limits and an acceleration limit, stopping at each waypoint: slow
but exactly within limits, which is what an executed plan must be.

A plan is a function of the scene, the two configurations and the seed, never of the machine's
load: the planner and its shortcutting stop after a number of collision checks (``checks``,
``SIMPLIFY_CHECKS``), not after a time, and OMPL's generator is seeded afresh from ``seed``
before each plan (a single thread: RRTConnect and a termination condition without a timer
thread). ``time_limit`` (off by default) is only a safety cap; hitting it raises
:class:`PlanningTimeout`, a failure that depends on the load and says so.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.robot.collision import CollisionScene
from grace_dsl.runtime.errors import GraceError, ParameterError

FloatArray = np.ndarray
CHECK_RESOLUTION = 0.01  # radians between collision checks along a segment
DEFAULT_ACCELERATION = 5.0  # rad/s², a gentle fraction of the Panda's 7.5-20 rad/s²
# The planner's budget in collision checks (about 2 s of RRTConnect on a quiet machine, the
# former time limit) and the shortcutting's (about its former 0.5 s)
PLAN_CHECKS = 20_000
SIMPLIFY_CHECKS = 5_000


class PlanningError(GraceError):
    """No collision-free path was found (or the start or goal itself collides)."""


class PlanningTimeout(PlanningError):
    """The optional wall-clock safety cap ended the search before its budget of checks: unlike
    every other outcome of :func:`plan_path`, this one depends on the machine's load."""


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
    checks: int = PLAN_CHECKS,
    seed: int = 0,
    resolution: float = CHECK_RESOLUTION,
    time_limit: float | None = None,
) -> FloatArray:
    """A collision-free joint path (K, nq) from ``start`` to ``goal``, shortcut and re-checked;
    the planner may spend ``checks`` collision checks (and the optional wall-clock cap
    ``time_limit`` seconds, :class:`PlanningTimeout`)."""
    robot = scene.robot
    q0, q1 = robot.check_q(start), robot.check_q(goal)
    for name, q in (("start", q0), ("goal", q1)):
        if scene.collides(q):
            hit = scene.contacts(q)[:1]
            what = f" ({hit[0].first} touches {hit[0].second})" if hit else ""
            raise PlanningError(f"the {name} configuration is in collision{what}")
    if segment_free(scene, q0, q1, resolution):
        return np.stack([q0, q1])
    if checks < 1:
        raise ParameterError(f"the planner's budget must be at least 1 check, not {checks}")
    waypoints = _ompl_path(scene, q0, q1, _Budget(checks, time_limit), seed, resolution)
    for a, b in zip(waypoints[:-1], waypoints[1:]):
        if not segment_free(scene, a, b, resolution):
            raise PlanningError("OMPL returned a path that collides between its waypoints")
    return waypoints


def segment_free(scene: CollisionScene, a: FloatArray, b: FloatArray, resolution: float) -> bool:
    """True when every configuration on the straight joint segment a-b is free (checked every
    ``resolution`` radians on the joint that moves most, both ends included)."""
    steps = max(1, math.ceil(float(np.max(np.abs(b - a))) / resolution))
    return not any(scene.collides(a + (b - a) * s) for s in np.linspace(0.0, 1.0, steps + 1))


@dataclass
class _Budget:
    """Collision checks counted by the validity checker; the planner stops at ``checks`` (and
    at the optional wall-clock cap ``seconds``, noted in ``timed_out``)."""

    checks: int
    seconds: float | None = None
    used: int = 0
    timed_out: bool = False
    _deadline: float = math.inf

    def start(self, checks: int) -> None:
        self.checks, self.used = checks, 0
        if self.seconds is not None:
            self._deadline = time.perf_counter() + self.seconds

    def spent(self) -> bool:
        if self.used >= self.checks:
            return True
        if self.seconds is not None and time.perf_counter() > self._deadline:
            self.timed_out = True
        return self.timed_out


def _ompl_path(
    scene: CollisionScene,
    q0: FloatArray,
    q1: FloatArray,
    budget: _Budget,
    seed: int,
    resolution: float,
) -> FloatArray:
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    _seed(ou, seed)
    robot = scene.robot
    space = ob.RealVectorStateSpace(robot.nq)
    bounds = ob.RealVectorBounds(robot.nq)
    for i in range(robot.nq):
        bounds.setLow(i, float(robot.lower[i]))
        bounds.setHigh(i, float(robot.upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    n = robot.nq

    def valid(state: Any) -> bool:
        budget.used += 1
        return not scene.collides([state[i] for i in range(n)])

    setup.setStateValidityChecker(valid)
    extent = float(np.linalg.norm(robot.upper - robot.lower))
    setup.getSpaceInformation().setStateValidityCheckingResolution(resolution / extent)
    start, goal = space.allocState(), space.allocState()
    for i in range(n):
        start[i], goal[i] = float(q0[i]), float(q1[i])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(setup.getSpaceInformation()))
    stop = ob.PlannerTerminationCondition(budget.spent)  # evaluated once per iteration
    budget.start(budget.checks)
    solved = setup.solve(stop)
    if budget.timed_out:
        raise PlanningTimeout(
            f"the planner's wall-clock safety cap of {budget.seconds:g} s was hit after "
            f"{budget.used} of its {budget.checks} collision checks (a load-dependent failure)"
        )
    if not solved or not setup.haveExactSolutionPath():
        raise PlanningError(f"no collision-free path found in {budget.checks} collision checks")
    budget.start(SIMPLIFY_CHECKS)
    setup.simplifySolution(ob.PlannerTerminationCondition(budget.spent))
    if budget.timed_out:
        raise PlanningTimeout(
            f"the shortcutting's wall-clock safety cap of {budget.seconds:g} s was hit "
            "(a load-dependent failure)"
        )
    path = setup.getSolutionPath()
    return np.array([[path.getState(k)[i] for i in range(n)] for k in range(path.getStateCount())])


def _seed(ou: Any, seed: int) -> None:
    """Seed OMPL's process-wide seed generator afresh from ``seed`` before a plan: every sampler
    the plan creates then draws the same numbers, whatever the process planned before. OMPL
    logs an error when it is reseeded after its first use (the reseeding works; what it warns
    of is that earlier generators keep their streams), so it is silenced meanwhile; a seed of
    0 is ignored by OMPL, hence the shift."""
    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    ou.RNG.setSeed(1 + seed % (2**31 - 1))
    ou.setLogLevel(ou.LogLevel.LOG_ERROR)


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
