"""Grasp selection with the robot in the loop."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.choose import NoGraspError, choose_grasp
from grace_dsl.robot.model import Robot
from tests.robot.test_grasp_ik import facing


def test_the_choice_is_reachable_feasible_and_explained(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(0.7, 0.0, 0.45))
    choice = choose_grasp(panda, door, "close")
    feasible = {o.grasp for o in door.rank("close", gripper=panda.gripper) if o.feasible}
    assert choice.option.grasp in feasible and choice.ik.success
    assert np.linalg.norm(panda.fk(choice.ik.q)[:3, 3] - choice.ik.grasp_pose[:3, 3]) <= 1e-3
    assert {g for g, _ in choice.rejected} | {choice.option.grasp} == {
        o.grasp for o in door.rank("close", gripper=panda.gripper)
    }
    assert all(reason for _, reason in choice.rejected)
    assert choice.margin > 0


def test_a_base_pose_moves_the_problem_with_it(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    """The same scene shifted and turned as a whole has the same answer in base coordinates."""
    door = lib["SunkenDoor"].instantiate(pose=facing(0.7, 0.0, 0.45))
    shift = np.eye(4)
    shift[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    shift[:3, 3] = (2.0, -1.0, 0.0)
    moved = lib["SunkenDoor"].instantiate(pose=shift @ facing(0.7, 0.0, 0.45))
    a = choose_grasp(panda, door, "open")
    b = choose_grasp(panda, moved, "open", base=shift)
    assert a.option.grasp == b.option.grasp
    np.testing.assert_allclose(a.ik.q, b.ik.q, atol=1e-3)  # both within the IK tolerance
    np.testing.assert_allclose(shift @ a.ik.grasp_pose, b.ik.grasp_pose, atol=1e-3)


def test_out_of_reach_is_a_typed_error_with_reasons(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(3.0, 0.0, 0.45))
    with pytest.raises(NoGraspError, match="handle.pull: IK"):
        choose_grasp(panda, door, "open", options=eac.IKOptions(max_restarts=5))
