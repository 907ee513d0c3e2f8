"""Fixtures of the robot tests: the Panda, built once per session (the standard library is the
session's ``lib`` of tests/conftest.py)."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.robot.plan import segment_free


@pytest.fixture(scope="session")
def panda() -> Robot:
    return Robot.panda()


@pytest.fixture(scope="module")
def blocked(panda: Robot, lib):  # type: ignore[no-untyped-def]
    """A drawer in front of the robot, between two swings of the first joint (the straight
    swing between them hits it)."""
    pose = np.eye(4)
    pose[:3, 3] = (0.4, 0.0, 0.45)
    scene = collision_scene(panda, lib["CabinetDrawer"].instantiate(pose=pose))
    start, goal = panda.home.copy(), panda.home.copy()
    start[0], goal[0] = -1.2, 1.2
    assert not segment_free(scene, start, goal, 0.01)
    return scene, start, goal
