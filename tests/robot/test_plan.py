"""Planning: paths around an object, re-checked densely and independently; timing within limits."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.robot.plan import PlanningError, plan_path, time_path


@pytest.mark.slow
def test_a_path_goes_around_the_object(panda: Robot, blocked) -> None:  # type: ignore[no-untyped-def]
    scene, start, goal = blocked
    path = plan_path(scene, start, goal, seed=3)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], goal, atol=1e-9)
    assert np.all(path >= panda.lower - 1e-12) and np.all(path <= panda.upper + 1e-12)
    for a, b in zip(path[:-1], path[1:]):  # five times finer than the planner's own check
        for s in np.linspace(0, 1, max(2, int(np.max(np.abs(b - a)) / 0.002) + 1)):
            assert not scene.collides(a + (b - a) * s)


def test_a_free_straight_segment_needs_no_planner(panda: Robot) -> None:
    scene = collision_scene(panda)
    goal = panda.home.copy()
    goal[0] += 0.5
    path = plan_path(scene, panda.home, goal)
    assert path.shape == (2, 7)


def test_a_start_in_collision_is_refused(panda: Robot, blocked, lib) -> None:  # type: ignore[no-untyped-def]
    scene, _, goal = blocked
    tcp = panda.fk(panda.home)[:3, 3]
    pose = np.eye(4)
    pose[:3, 3] = tcp
    inside = collision_scene(panda, lib["CabinetDrawer"].instantiate(pose=pose))
    with pytest.raises(PlanningError, match="start configuration is in collision"):
        plan_path(inside, panda.home, goal)
    assert issubclass(PlanningError, eac.GraceError)


def test_timing_respects_velocity_and_acceleration(panda: Robot) -> None:
    rng = np.random.default_rng(0)
    waypoints = np.stack([panda.random_q(rng) for _ in range(4)])
    timed = time_path(waypoints, panda.velocity_limit, acceleration=4.0)
    assert timed.t[0] == 0 and np.all(np.diff(timed.t) > 0)
    for k, (a, b) in enumerate(zip(waypoints[:-1], waypoints[1:])):
        span = timed.t[k + 1] - timed.t[k]
        # A rest-to-rest move of d in time T needs peak speed >= d/T and acceleration >= 4d/T^2.
        d = np.abs(b - a)
        assert np.all(d / span <= panda.velocity_limit + 1e-9)
        assert np.all(4 * d / span**2 <= 4.0 + 1e-9)
        slowest = np.argmax(d / panda.velocity_limit)
        assert d[slowest] / span > 0.3 * panda.velocity_limit[slowest]  # not needlessly slow
