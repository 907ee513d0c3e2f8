"""Pose IK: solutions re-checked by forward kinematics, typed failures, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.ik import IKOptions, solve_ik
from grace_dsl.robot.model import Robot
from tests.robot.test_model import urdf_chain_fk


def _errors(pose: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    cos = (np.trace(target[:3, :3].T @ pose[:3, :3]) - 1) / 2
    return float(np.linalg.norm(pose[:3, 3] - target[:3, 3])), math.acos(min(1.0, max(-1.0, cos)))


def test_reachable_targets_are_reached(panda: Robot) -> None:
    rng = np.random.default_rng(11)
    for i in range(25):
        target = panda.fk(panda.random_q(rng))
        result = solve_ik(panda, target, seed=i)
        assert result.success, result
        assert np.all(result.q >= panda.lower) and np.all(result.q <= panda.upper)
        pos, rot = _errors(urdf_chain_fk(result.q), target)  # independent forward kinematics
        assert pos <= 1e-3 and rot <= math.radians(1)
        assert pos == pytest.approx(result.error_pos, abs=1e-9)
        assert rot == pytest.approx(result.error_rot, abs=1e-6)  # acos is coarse near 0


def test_a_target_out_of_reach_fails_with_a_reason(panda: Robot) -> None:
    target = np.eye(4)
    target[:3, 3] = (2.0, 0.0, 0.5)  # the Panda reaches about 0.85 m
    result = solve_ik(panda, target, options=IKOptions(max_restarts=10))
    assert not result.success
    assert result.reason == "unreachable" and result.restarts == 10
    assert result.error_pos > 0.5
    pos, _ = _errors(panda.fk(result.q), target)
    assert pos == pytest.approx(result.error_pos)


def test_starting_at_the_answer_takes_no_step(panda: Robot) -> None:
    q0 = panda.random_q(np.random.default_rng(2))
    result = solve_ik(panda, panda.fk(q0), q0=q0)
    assert result.success and result.iterations == 0 and result.restarts == 0
    np.testing.assert_array_equal(result.q, q0)


def test_same_seed_same_answer(panda: Robot) -> None:
    target = panda.fk(panda.random_q(np.random.default_rng(4)))
    a, b = solve_ik(panda, target, seed=7), solve_ik(panda, target, seed=7)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.iterations == b.iterations


@pytest.mark.parametrize(
    "target, words",
    [
        (np.full((4, 4), np.nan), "finite"),
        (np.diag([1.0, 1.0, -1.0, 1.0]), "rigid"),
        ("home", "4x4"),
        (np.eye(3), "4x4"),
    ],
)
def test_bad_targets_are_typed_errors(panda: Robot, target: object, words: str) -> None:
    with pytest.raises(eac.ParameterError, match=words):
        solve_ik(panda, target)


def test_result_arrays_are_read_only(panda: Robot) -> None:
    result = solve_ik(panda, panda.fk(panda.home))
    with pytest.raises(ValueError):
        result.q[0] = 1.0


def test_the_ur5_reaches_its_targets_too() -> None:
    ur5 = Robot.ur5()
    rng = np.random.default_rng(12)
    for i in range(15):
        target = ur5.fk(ur5.random_q(rng))
        result = solve_ik(ur5, target, seed=i)
        assert result.success, result
        pos, rot = _errors(ur5.fk(result.q), target)
        assert pos <= 1e-3 and rot <= math.radians(1)
