"""The IK seed bank: its poses are the robot's forward kinematics, its ranking the pose distance."""

from __future__ import annotations

import numpy as np

from grace_dsl.robot.model import Robot
from grace_dsl.robot.seeds import ROTATION_WEIGHT, build_bank, seed_bank


def test_bank_entries_are_within_limits_and_start_with_home(panda: Robot) -> None:
    bank = build_bank(panda, 200, seed=3)
    assert bank.q.shape == (201, panda.nq)
    np.testing.assert_array_equal(bank.q[0], panda.home)
    assert np.all(bank.q >= panda.lower) and np.all(bank.q <= panda.upper)
    np.testing.assert_array_equal(build_bank(panda, 200, seed=3).q, bank.q)  # reproducible


def test_nearest_ranks_by_the_pose_distance_of_fresh_forward_kinematics(panda: Robot) -> None:
    bank = build_bank(panda, 300, seed=4)
    rng = np.random.default_rng(5)
    for _ in range(5):
        goal = panda.fk(panda.random_q(rng))
        poses = [panda.fk(q) for q in bank.q]
        dist = [
            np.sum((t[:3, 3] - goal[:3, 3]) ** 2)
            + ROTATION_WEIGHT**2 * np.sum((t[:3, :3] - goal[:3, :3]) ** 2)
            for t in poses
        ]
        expected = np.argsort(dist, kind="stable")[:6]
        np.testing.assert_allclose(bank.nearest(goal, 6), bank.q[expected])


def test_the_bank_is_built_once_per_robot(panda: Robot) -> None:
    assert seed_bank(panda) is seed_bank(panda)
    assert seed_bank(panda) is not seed_bank(Robot.panda())
