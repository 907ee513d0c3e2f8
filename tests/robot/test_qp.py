"""The box QP of an IK step: the exact active-set answer against OSQP and the KKT conditions."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.robot.qp import BoxQP, active_set


def _problem(seed: int, n: int) -> tuple[np.ndarray, ...]:
    """An IK-like QP: P = JᵀJ + λI with a 6 x n Jacobian (rank-deficient for n > 6), a box that
    holds 0 (the current point is feasible), some bounds at 0 (a joint at its limit)."""
    rng = np.random.default_rng(seed)
    jac = rng.normal(size=(6, n))
    p = jac.T @ jac + 10.0 ** rng.uniform(-6, -1) * np.eye(n)
    c = jac.T @ rng.normal(size=6) * rng.uniform(0.1, 5.0)
    lo, hi = -rng.uniform(0.0, 0.5, n), rng.uniform(0.0, 0.5, n)
    lo[rng.random(n) < 0.2] = 0.0
    hi[rng.random(n) < 0.2] = 0.0
    return p, c, lo, hi


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(2, 10))
def test_active_set_answers_are_the_qp_optimum(seed: int, n: int) -> None:
    p, c, lo, hi = _problem(seed, n)
    x = active_set(p, c, lo, hi)
    if x is None:  # the sets did not settle: the caller falls back to OSQP
        return
    assert np.all(x >= lo) and np.all(x <= hi)
    grad = p @ x + c  # KKT: zero where free, pushing outward where a bound holds
    scale = 1e-9 * (1.0 + np.abs(grad).max())
    free = (x > lo) & (x < hi)
    assert np.all(np.abs(grad[free]) <= scale)
    pinned = lo == hi  # a joint at its limit with no room either way: any multiplier
    assert np.all(grad[(x <= lo) & ~pinned] >= -scale)
    assert np.all(grad[(x >= hi) & ~pinned] <= scale)
    reference = BoxQP(n, eps=1e-10, max_iter=200_000).solve(p, c, lo, hi)

    def f(z: np.ndarray) -> float:
        return float(0.5 * z @ p @ z + c @ z)

    assert f(x) <= f(reference) + 1e-9 * (1.0 + abs(f(reference)))


def test_active_set_settles_on_most_ik_like_problems() -> None:
    settled = sum(active_set(*_problem(seed, 7)) is not None for seed in range(300))
    assert settled >= 150  # random problems are harder than IK steps (99% settle there)


def test_an_unconstrained_minimum_inside_the_box_is_returned_as_is() -> None:
    p, c = np.diag([2.0, 4.0]), np.array([-2.0, 4.0])  # minimum at (1, -1)
    x = active_set(p, c, np.array([-5.0, -5.0]), np.array([5.0, 5.0]))
    assert x is not None
    np.testing.assert_allclose(x, [1.0, -1.0])
    y = active_set(p, c, np.array([-5.0, -0.5]), np.array([0.5, 5.0]))  # both bounds bind
    assert y is not None
    np.testing.assert_allclose(y, [0.5, -0.5])
