"""Time-optimal parameterization: limits met by the samples themselves, optimal where the
optimum is known in closed form."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.robot.model import Robot
from grace_dsl.robot.timing import TimingError, time_optimal

PANDA_ACCELERATION = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])  # Franka's datasheet


@functools.cache
def _panda() -> Robot:
    return Robot.panda()


@pytest.fixture(scope="module")
def panda() -> Robot:
    return _panda()


def differenced(q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity per interval and acceleration between interval midpoints, as an executor that
    interpolates the samples linearly would see them."""
    vel = np.diff(q, axis=0) / np.diff(t)[:, None]
    acc = np.diff(vel, axis=0) / np.diff((t[1:] + t[:-1]) / 2)[:, None]
    return vel, acc


def bang_bang(d: np.ndarray, v: np.ndarray, a: np.ndarray) -> float:
    """The minimum rest-to-rest time of the straight move by ``d``: the path parameter's own
    speed and acceleration bounds are the tightest joint's, and its best profile is
    accelerate-coast-brake (or accelerate-brake when the coast never starts)."""
    d = np.abs(d)
    vs, as_ = float(np.min(v / d)), float(np.min(a / d))
    return 2 * math.sqrt(1 / as_) if vs * vs / as_ >= 1 else 1 / vs + vs / as_


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_a_straight_move_takes_the_bang_bang_time(seed: int) -> None:
    robot = _panda()
    rng = np.random.default_rng(seed)
    a, b = robot.random_q(rng), robot.random_q(rng)
    traj = time_optimal(np.stack([a, b]), robot.velocity_limit, PANDA_ACCELERATION)
    best = bang_bang(b - a, robot.velocity_limit, PANDA_ACCELERATION)
    assert best * (1 - 1e-6) <= traj.duration <= best * 1.002
    np.testing.assert_allclose(traj.q[[0, -1]], [a, b], atol=1e-12)


@pytest.mark.parametrize("smooth", [True, False])
def test_every_sample_is_within_the_limits(panda: Robot, smooth: bool) -> None:
    rng = np.random.default_rng(4)
    waypoints = np.stack([panda.random_q(rng) for _ in range(5)])
    traj = time_optimal(waypoints, panda.velocity_limit, PANDA_ACCELERATION, smooth=smooth)
    vel, acc = differenced(traj.q, traj.t)
    assert np.all(np.abs(vel) <= panda.velocity_limit * (1 + 1e-9))
    assert np.all(np.abs(acc) <= PANDA_ACCELERATION * (1 + 1e-9))
    assert np.all(np.diff(traj.t) > 0)
    # Not needlessly slow: some joint is at its velocity or acceleration limit most of the time.
    busy = np.maximum(
        np.max(np.abs(vel[1:]) / panda.velocity_limit, axis=1),
        np.max(np.abs(acc) / PANDA_ACCELERATION, axis=1),
    )
    assert np.median(busy) > 0.95
    # Both paths pass through every waypoint; the polyline stops at each of its corners.
    for w in waypoints:
        assert np.min(np.linalg.norm(traj.q - w, axis=1)) <= 1e-9
    if not smooth:
        corners = [int(np.argmin(np.linalg.norm(traj.q - w, axis=1))) for w in waypoints[1:-1]]
        speeds = np.linalg.norm(vel, axis=1)
        assert all(min(speeds[k - 1], speeds[k]) < 0.2 * speeds.max() for k in corners)


def test_a_smooth_path_is_faster_than_stopping_at_corners(panda: Robot) -> None:
    angle = np.linspace(0.0, math.pi, 12)[:, None]  # a half circle in joints 1 and 2
    waypoints = np.tile(panda.home, (12, 1))
    waypoints[:, :2] += 0.6 * np.hstack([np.sin(angle), 1 - np.cos(angle)])
    smooth = time_optimal(waypoints, panda.velocity_limit, PANDA_ACCELERATION)
    stops = time_optimal(waypoints, panda.velocity_limit, PANDA_ACCELERATION, smooth=False)
    assert smooth.duration < 0.8 * stops.duration


def test_carried_coordinates_follow_the_path(panda: Robot) -> None:
    a, b = panda.home, panda.home + 0.4
    traj = time_optimal(np.stack([a, b]), panda.velocity_limit, 5.0, extra=np.array([0.0, 1.2]))
    progress = (traj.q[:, 0] - a[0]) / 0.4
    np.testing.assert_allclose(traj.extra[:, 0], 1.2 * progress, atol=1e-12)


def test_bad_limits_are_typed_errors(panda: Robot) -> None:
    with pytest.raises(TimingError, match="acceleration"):
        time_optimal(np.stack([panda.home, panda.home + 0.1]), panda.velocity_limit, 0.0)
    with pytest.raises(TimingError, match="not finite"):
        time_optimal(np.array([[np.nan] * 7, [0.0] * 7]), panda.velocity_limit, 1.0)
