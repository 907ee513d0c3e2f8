"""Robot models: the Panda's forward kinematics against an independent chain read from its URDF."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import grace_dsl as eac
from grace_dsl.robot.model import Robot, robot_data_file


def _origin(joint: ET.Element) -> np.ndarray:
    origin = joint.find("origin")
    attrs = origin.attrib if origin is not None else {}
    xyz = [float(v) for v in attrs.get("xyz", "0 0 0").split()]
    rpy = [float(v) for v in attrs.get("rpy", "0 0 0").split()]
    m = np.eye(4)
    m[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF: fixed-axis roll, pitch, yaw
    m[:3, 3] = xyz
    return m


def urdf_chain_fk(
    q: np.ndarray, tip: str = "panda_hand_tcp", urdf: str = "panda_description/urdf/panda.urdf"
) -> np.ndarray:
    """Forward kinematics by walking the URDF's joints from ``tip`` to the root, numpy only."""
    root = ET.parse(robot_data_file(urdf)).getroot()
    by_child = {j.find("child").get("link"): j for j in root.findall("joint")}
    chain = []
    link = tip
    while link in by_child:
        joint = by_child[link]
        chain.append(joint)
        link = joint.find("parent").get("link")
    pose = np.eye(4)
    values = iter(q)
    for joint in reversed(chain):
        pose = pose @ _origin(joint)
        if joint.get("type") == "revolute" and "finger" not in joint.get("name"):
            axis = np.array([float(v) for v in joint.find("axis").get("xyz").split()])
            turn = np.eye(4)
            turn[:3, :3] = Rotation.from_rotvec(axis * next(values)).as_matrix()
            pose = pose @ turn
    return pose


def test_panda_fk_matches_the_urdf_chain(panda: Robot) -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = panda.random_q(rng)
        np.testing.assert_allclose(panda.fk(q), urdf_chain_fk(q), atol=1e-12)


def test_panda_gripper_frame_follows_the_convention(panda: Robot) -> None:
    """At home the hand points down (+z approach = world -z) and sits 103.4 mm past the flange."""
    pose = panda.fk(panda.home)
    np.testing.assert_allclose(pose[:3, 2], [0, 0, -1], atol=1e-9)
    assert panda.nq == 7 and panda.gripper.name == "panda"
    assert 0.3 < pose[0, 3] < 0.32 and 0.48 < pose[2, 3] < 0.5


def test_jacobian_matches_finite_differences(panda: Robot) -> None:
    rng = np.random.default_rng(5)
    q = panda.random_q(rng) * 0.8
    jac = panda.jacobian(q)
    h = 1e-6
    for i in range(panda.nq):
        dq = np.zeros(panda.nq)
        dq[i] = h
        hi, lo = panda.fk(q + dq), panda.fk(q - dq)
        linear = (hi[:3, 3] - lo[:3, 3]) / (2 * h)
        skew = (hi[:3, :3] - lo[:3, :3]) / (2 * h) @ panda.fk(q)[:3, :3].T
        angular = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
        np.testing.assert_allclose(jac[:3, i], linear, atol=1e-6)
        np.testing.assert_allclose(jac[3:, i], angular, atol=1e-6)


def test_random_q_is_seeded_and_within_limits(panda: Robot) -> None:
    a = [panda.random_q(np.random.default_rng(9)) for _ in range(2)]
    np.testing.assert_array_equal(a[0], a[1])
    assert np.all(a[0] >= panda.lower) and np.all(a[0] <= panda.upper)


@pytest.mark.parametrize(
    "q, words",
    [
        ([0.0] * 6, "7 values"),
        ([0.0] * 8, "7 values"),
        ("home", "7 numbers"),
        ([math.nan] * 7, "finite"),
        ([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 9.0], "outside its limits"),
    ],
)
def test_bad_configurations_are_typed_errors(panda: Robot, q: object, words: str) -> None:
    with pytest.raises(eac.ParameterError, match=words):
        panda.fk(q)


def test_limits_are_read_only(panda: Robot) -> None:
    with pytest.raises(ValueError):
        panda.lower[0] = 0.0
    with pytest.raises(ValueError):
        panda.home[0] = 0.0


def test_unknown_tcp_frame_and_missing_urdf(tmp_path) -> None:  # type: ignore[no-untyped-def]
    urdf = robot_data_file("panda_description/urdf/panda.urdf")
    with pytest.raises(eac.ParameterError, match="no frame 'gripper'"):
        Robot.from_urdf(urdf, tcp="gripper", package_dirs=[urdf.parents[4]])
    with pytest.raises(eac.ParameterError, match="no URDF"):
        Robot.from_urdf(tmp_path / "arm.urdf", tcp="tool0")


def test_tcp_offset_moves_the_gripper_frame(panda: Robot) -> None:
    """A TCP given as (frame, offset) equals the frame's pose times the offset."""
    urdf = robot_data_file("panda_description/urdf/panda.urdf")
    offset = np.eye(4)
    offset[:3, 3] = (0.0, 0.0, 0.1034)
    robot = Robot.from_urdf(
        urdf,
        tcp=("panda_hand", offset),
        locked={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04},
        package_dirs=[urdf.parents[4]],
    )
    q = panda.random_q(np.random.default_rng(1))
    np.testing.assert_allclose(robot.fk(q), panda.fk(q), atol=1e-12)


def test_a_second_arm_ur5() -> None:
    """Nothing is Panda-only: the UR5's gripper frame is tool0 moved 150 mm out of the flange."""
    ur5 = Robot.ur5()
    assert ur5.nq == 6
    rng = np.random.default_rng(8)
    for _ in range(10):
        q = ur5.random_q(rng)
        chain = urdf_chain_fk(q, "tool0", "ur_description/urdf/ur5_gripper.urdf")
        out = np.eye(4)
        out[2, 3] = 0.15
        np.testing.assert_allclose(ur5.fk(q), chain @ out, atol=1e-12)
