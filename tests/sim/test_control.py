"""The compliant path follower: targets re-anchored on the measured joint, a capped spring."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.sim.control import (
    LEAD,
    Impedance,
    PathFollower,
    blend,
    rotation_angle,
    rotation_vector,
)
from grace_dsl.sim.episode import Z_UP


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def _follower(lib: eac.Library, concept: str, joint: str, q0: float, goal: float) -> PathFollower:
    inst = lib[concept].instantiate(pose=Z_UP, joints={joint: q0})
    option = inst.rank("open")[0]
    assert option.feasible and option.pose is not None
    return PathFollower.from_grasp(inst, joint, option.pose, goal, 1.0)


def test_drawer_target_runs_a_lead_ahead_of_the_measured_joint(lib: eac.Library) -> None:
    f = _follower(lib, "CabinetDrawer", "slide", 0.05, 0.2)
    # the path at the instance's own joint value is the grasp itself
    assert np.allclose(f.pose_at(0.05), f.inst.rank("open")[0].pose, atol=1e-9)
    for q in (0.0, 0.08, 0.12):
        target = f.target(q)
        ahead = target[:3, 3] - f.pose_at(q)[:3, 3]
        assert np.linalg.norm(ahead) == pytest.approx(LEAD, rel=1e-3)
        assert ahead[0] > 0  # the drawer's front faces world +x: opening pulls along +x
    assert np.allclose(f.target(0.19), f.pose_at(0.2))  # never past the goal


def test_door_target_turns_with_the_leaf(lib: eac.Library) -> None:
    f = _follower(lib, "HingedCabinet", "hinge", 0.3, 1.5)
    a, b = f.pose_at(0.3), f.pose_at(0.8)
    assert rotation_angle(a, b) == pytest.approx(0.5, abs=1e-6)  # a pinch rides the leaf
    assert f.lookahead(0.3) > 0


def test_advance_is_speed_limited_and_falls_back_when_the_joint_lags(lib: eac.Library) -> None:
    f = _follower(lib, "CabinetDrawer", "slide", 0.0, 0.2)
    ref = f.advance(0.0, 0.0, 0.01)
    assert ref == pytest.approx(f.speed * 0.01, rel=1e-3)  # a prismatic joint: 1 m per metre
    ref = 0.1  # the reference ran ahead, the joint stayed at 0: back to a lead ahead of it
    assert f.advance(0.0, ref, 0.01) == pytest.approx(f.ahead(0.0))


def test_impedance_pulls_towards_the_target_and_caps_the_force() -> None:
    imp = Impedance(stiffness=1000.0, rot_stiffness=10.0, max_force=50.0, max_torque=2.0)
    pose, target = np.eye(4), np.eye(4)
    target[:3, 3] = (0.01, 0.0, 0.0)
    w = imp.wrench(pose, target)
    assert np.allclose(w[:3], (10.0, 0.0, 0.0)) and np.allclose(w[3:], 0.0)
    target[:3, 3] = (1.0, 0.0, 0.0)
    assert np.linalg.norm(imp.wrench(pose, target)[:3]) == pytest.approx(50.0)
    turned = np.eye(4)
    turned[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # a quarter turn about z
    torque = imp.wrench(pose, turned)[3:]
    assert torque[2] == pytest.approx(2.0) and np.allclose(torque[:2], 0.0)


def test_rotation_vector_and_blend() -> None:
    r = np.array([[1.0, 0, 0], [0, -1, 0], [0, 0, -1]])  # half a turn about x
    assert np.allclose(np.abs(rotation_vector(r)), (math.pi, 0, 0))
    a, b = np.eye(4), np.eye(4)
    b[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    b[:3, 3] = (0.2, 0, 0)
    mid = blend(a, b, 0.5)
    assert np.allclose(mid[:3, 3], (0.1, 0, 0))
    assert rotation_angle(a, mid) == pytest.approx(math.pi / 4)
    assert np.allclose(blend(a, b, 2.0), b)
