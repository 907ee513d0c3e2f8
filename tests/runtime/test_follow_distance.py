"""``inst.follow``: a travel for actions that move no joint, and joints followed past their
declared range when the caller asks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import grace_dsl as eac
from grace_dsl.runtime.verify import random_pose
from tests.runtime.test_runtime import VALVE


def test_a_fixed_direction_action_travels_its_distance(lib) -> None:  # type: ignore[no-untyped-def]
    """StraightHandle.pull_out pulls toward the handle's +z: the hand moves d along the world
    image of +z, its orientation unchanged, in equal steps."""
    pose = random_pose(np.random.default_rng(2))
    inst = lib["StraightHandle"].instantiate(pose=pose)
    g = inst.grasp("pull", s=0.02)
    path = inst.follow("pull_out", grasp=g, distance=0.07, steps=8)
    assert path.shape == (8, 4, 4)
    out = pose[:3, 2]  # the handle's +z in the world
    np.testing.assert_allclose(path[-1][:3, 3], g[:3, 3] + 0.07 * out, atol=1e-12)
    np.testing.assert_allclose(path[:, :3, :3], np.tile(g[:3, :3], (8, 1, 1)), atol=1e-15)
    steps = np.diff(path[:, :3, 3], axis=0)
    np.testing.assert_allclose(np.linalg.norm(steps, axis=1), 0.01, atol=1e-12)
    back = inst.follow("push_in", grasp=inst.grasp("push"), distance=0.03, steps=2)
    np.testing.assert_allclose(back[-1][:3, 3] - back[0][:3, 3], -0.03 * out, atol=1e-12)


def test_distance_zero_stays_put(lib) -> None:  # type: ignore[no-untyped-def]
    inst = lib["RoundKnob"].instantiate()
    g = inst.grasp("pinch")
    path = inst.follow("pull_out", grasp=g, distance=0.0, steps=3)
    np.testing.assert_array_equal(path, np.tile(g, (3, 1, 1)))


def test_a_turn_with_a_direction_turns_its_distance_in_radians(tmp_path) -> None:  # type: ignore[no-untyped-def]
    src = tmp_path / "valve.eac"
    src.write_text(VALVE)
    valve = eac.compile_paths([src])["Valve"]
    pose = random_pose(np.random.default_rng(7))
    inst = valve.instantiate(pose=pose)
    g = inst.grasp("grip")
    path = inst.follow("open", grasp=g, distance=math.pi / 2, steps=5)
    turn = Rotation.from_rotvec(math.pi / 2 * pose[:3, 2]).as_matrix()
    np.testing.assert_allclose(path[-1][:3, :3], turn @ g[:3, :3], atol=1e-12)
    np.testing.assert_allclose(path[:, :3, 3], np.tile(g[:3, 3], (5, 1)), atol=1e-15)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"to": 0.1}, "moves no joint"),
        ({}, "distance=d"),
        ({"distance": -0.01}, ">= 0"),
        ({"distance": float("nan")}, ">= 0"),
        ({"distance": "5cm"}, "distance"),
    ],
)
def test_misused_fixed_direction_follow(lib, kwargs, match) -> None:  # type: ignore[no-untyped-def]
    inst = lib["StraightHandle"].instantiate()
    with pytest.raises(eac.ParameterError, match=match):
        inst.follow("pull_out", grasp=inst.grasp("pull"), **kwargs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"distance": 0.1}, "not a distance"),
        ({"to": 1.0, "distance": 0.1}, "not a distance"),
        ({}, "to=q"),
        ({"to": 2.5}, "beyond_range=True"),
        ({"to": 1.0, "beyond_range": "yes"}, "True or False"),
        ({"to": float("inf"), "beyond_range": True}, "finite"),
        ({"to": -0.5, "beyond_range": True}, "other sense"),
    ],
)
def test_misused_joint_follow(lib, kwargs, match) -> None:  # type: ignore[no-untyped-def]
    inst = lib["HingedCabinet"].instantiate()
    with pytest.raises(eac.ParameterError, match=match):
        inst.follow("open", grasp=inst.grasp("handle.pull"), **kwargs)


def test_beyond_range_continues_the_same_motion(lib) -> None:  # type: ignore[no-untyped-def]
    """Past the 110deg the concept declares, the path keeps turning about the hinge: its pose at
    a value inside the range equals the in-range path's, and the whole turn is the angle asked."""
    pose = random_pose(np.random.default_rng(4))
    inst = lib["HingedCabinet"].instantiate(pose=pose)
    g = inst.grasp("handle.pull")
    far = inst.follow("open", grasp=g, to=2.4, steps=13, beyond_range=True)
    near = inst.follow("open", grasp=g, to=1.2, steps=7)
    np.testing.assert_allclose(far[6], near[-1], atol=1e-12)
    relative = far[-1][:3, :3] @ g[:3, :3].T
    angle = Rotation.from_matrix(relative).magnitude()
    assert angle == pytest.approx(2.4, abs=1e-9)
    # the grasp point stays on a circle about the hinge line the concept declares: vertical
    # through the carcass's front left edge (-size.x / 2, *, size.z / 2), (0.6, 0.72, 0.56) m
    on_axis = pose[:3, :3] @ [-0.3, 0.0, 0.28] + pose[:3, 3]
    up = pose[:3, 1]
    axis = Rotation.from_matrix(relative).as_rotvec() / angle
    np.testing.assert_allclose(abs(axis @ up), 1.0, atol=1e-9)
    radial = [np.linalg.norm(np.cross(up, p[:3, 3] - on_axis)) for p in far]
    np.testing.assert_allclose(radial, radial[0], atol=1e-12)
    assert radial[0] > 0.4  # the handle is near the free edge, 0.56 m from the hinge
