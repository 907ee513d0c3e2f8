"""The MuJoCo Panda of the IK benchmark's mink baseline has the same kinematics as Robot.panda()."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from grace_dsl.robot.model import Robot

pytest.importorskip("mujoco")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import bench_ik  # noqa: E402


def test_the_tcp_site_matches_pinocchio_at_random_configurations() -> None:
    import mujoco

    robot = Robot.panda()
    model = bench_ik.panda_mjcf(robot)
    assert model.nq == robot.nq
    np.testing.assert_allclose(model.jnt_range, np.column_stack([robot.lower, robot.upper]))
    data = mujoco.MjData(model)
    site = model.site("tcp").id
    rng = np.random.default_rng(8)
    for _ in range(50):
        q = robot.random_q(rng)
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        pose = np.eye(4)
        pose[:3, :3] = data.site_xmat[site].reshape(3, 3)
        pose[:3, 3] = data.site_xpos[site]
        np.testing.assert_allclose(pose, robot.fk(q), atol=1e-9)
