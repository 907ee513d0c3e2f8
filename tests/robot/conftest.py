"""Fixtures of the robot tests: the Panda, built once per session (the standard library is the
session's ``lib`` of tests/conftest.py)."""

from __future__ import annotations

import pytest

from grace_dsl.robot.model import Robot


@pytest.fixture(scope="session")
def panda() -> Robot:
    return Robot.panda()
