"""Whole actions: the planned trajectory does what the concept says, within limits, continuously."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.act import MAX_JOINT_STEP, ActionPlanningError, plan_action
from grace_dsl.robot.model import Robot
from tests.robot.test_grasp_ik import facing
from tests.robot.test_model import urdf_chain_fk


@pytest.fixture(scope="module")
def panda() -> Robot:
    return eac.Robot.panda()


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


@pytest.mark.slow
def test_opening_a_door_follows_its_arc(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(0.7, 0.0, 0.45))
    plan = plan_action(panda, door, "open", to=0.6)
    assert np.all(plan.q >= panda.lower - 1e-9) and np.all(plan.q <= panda.upper + 1e-9)
    assert np.all(np.diff(plan.t) > 0)
    tracked = plan.q[plan.phases[1][1] :]  # insert, interact, retreat
    assert np.max(np.abs(np.diff(tracked, axis=0))) <= MAX_JOINT_STEP + 1e-9
    # The hand during the interaction is on the door's analytic path (independent FK).
    path = door.follow("open", grasp=plan.choice.ik.grasp_pose, to=0.6, steps=24)
    hand = np.array([urdf_chain_fk(q)[:3, 3] for q in plan.phase("interact")])
    gaps = np.min(np.linalg.norm(hand[:, None] - path[None, :, :3, 3], axis=2), axis=1)
    assert gaps.max() <= 1e-3
    assert np.linalg.norm(hand[-1] - path[-1][:3, 3]) <= 1e-3  # it ends where the door is open
    # A pinch closes on the handle for the interaction and opens before backing out.
    widths = [w for _, w in plan.gripper]
    assert plan.choice.option.mode != "pinch" or widths == [0.08, 0.0, 0.08]


def test_a_door_out_of_reach_fails_with_a_reason(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(2.5, 0.0, 0.45))
    with pytest.raises(eac.GraceError, match="no usable grasp|out of reach"):
        plan_action(panda, door, "open", to=0.6)
    assert issubclass(ActionPlanningError, eac.GraceError)
