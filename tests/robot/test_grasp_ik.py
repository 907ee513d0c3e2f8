"""Grasp-manifold IK: the gripper lands on the grasp family, free parameters stay in range."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.grasp_ik import solve_grasp_ik
from grace_dsl.robot.ik import IKOptions, solve_ik
from grace_dsl.robot.model import Robot
from tests.robot.test_model import urdf_chain_fk

# The concept's front (+z) toward the robot (world -x), its +y up (world +z).
FACING_ROBOT = np.column_stack([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])


def facing(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = FACING_ROBOT
    m[:3, 3] = (x, y, z)
    return m


def _rotation_error(a: np.ndarray, b: np.ndarray) -> float:
    return math.acos(min(1.0, max(-1.0, (np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2)))


@pytest.mark.parametrize(
    "concept, grasp", [("CabinetDrawer", "handle.pull"), ("SunkenDoor", "handle.pull")]
)
def test_the_gripper_lands_on_the_family(panda: Robot, lib, concept: str, grasp: str) -> None:  # type: ignore[no-untyped-def]
    inst = lib[concept].instantiate(pose=facing(0.65, 0.0, 0.45))
    result = solve_grasp_ik(panda, inst, grasp)
    assert result.success, result.reason
    ranges = inst.grasp_range(grasp)
    assert set(result.free) == set(ranges)
    for name, value in result.free.items():
        lo, hi = ranges[name]
        assert lo - 1e-12 <= value <= hi + 1e-12
    target = inst.grasp(grasp, **result.free)  # the runtime's own grasp pose at those values
    reached = urdf_chain_fk(result.q)  # an independent forward kinematics
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) <= 1e-3
    assert _rotation_error(reached, target) <= math.radians(1)


def test_the_free_parameters_reach_what_a_fixed_grasp_cannot(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    """A drawer far to the side: its handle's default middle is out of reach, a point of the
    handle nearer the arm is not; the free parameter moves the grasp toward the shoulder."""
    inst = lib["CabinetDrawer"].instantiate(pose=facing(0.55, 0.0, 0.45))
    ranges = inst.grasp_range("handle.pull")["s"]
    found = None
    for y in np.linspace(0.70, 0.95, 11):  # slide the drawer sideways until only the family reaches
        moved = lib["CabinetDrawer"].instantiate(pose=facing(0.35, y, 0.45))
        fixed = solve_ik(panda, moved.grasp("handle.pull"))
        family = solve_grasp_ik(panda, moved, "handle.pull")
        if family.success and not fixed.success:
            found = family
            break
    assert found is not None, "no placement where only the grasp family is reachable"
    assert ranges[0] <= found.free["s"] <= ranges[1]
    shoulder = np.array([0.0, 0.0, 0.333])  # the Panda's joint 2 axis, the arm's reach centre
    chosen = np.linalg.norm(found.grasp_pose[:3, 3] - shoulder)
    default = np.linalg.norm(moved.grasp("handle.pull")[:3, 3] - shoulder)
    assert chosen < default


def test_a_symmetric_grasp_frees_its_spin(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["RoundKnob"].instantiate(pose=facing(0.6, 0.1, 0.4))
    result = solve_grasp_ik(panda, inst, "pinch")
    assert result.success
    default = inst.grasp("pinch")  # spun to the hand's home orientation
    reached = panda.fk(result.q)
    # The same origin and the same symmetry axis in the world: only the spin about it is free.
    axis = np.asarray(inst.concept.function("grasp_axis", "pinch")(inst.p, np.zeros(0))).reshape(3)
    assert np.linalg.norm(reached[:3, 3] - default[:3, 3]) <= 1e-3
    assert np.allclose(reached[:3, :3] @ axis, default[:3, :3] @ axis, atol=0.02)
    assert -math.pi <= result.spin <= math.pi
    np.testing.assert_allclose(result.grasp_pose[:3, :3] @ axis, default[:3, :3] @ axis, atol=1e-9)


def test_unreachable_instances_fail_with_a_reason(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["CabinetDrawer"].instantiate(pose=facing(3.0, 0.0, 0.45))
    result = solve_grasp_ik(panda, inst, "handle.pull", options=IKOptions(max_restarts=10))
    assert not result.success and result.reason == "unreachable"


def test_a_solution_in_collision_is_not_a_success(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["CabinetDrawer"].instantiate(pose=facing(0.65, 0.0, 0.45))
    scene = collision_scene(panda, inst, ignore=("panda_leftfinger", "panda_rightfinger"))
    result = solve_grasp_ik(panda, inst, "handle.pull", scene=scene)
    if result.success:
        assert not scene.collides(result.q)
    else:
        assert result.reason in ("collision", "unreachable")


def test_unknown_grasp_is_a_typed_error(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["CabinetDrawer"].instantiate(pose=facing(0.65, 0.0, 0.45))
    with pytest.raises(eac.UnknownNameError):
        solve_grasp_ik(panda, inst, "handle.pul")
