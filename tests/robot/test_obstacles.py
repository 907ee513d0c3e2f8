"""A room's other objects as obstacles: collision scenes and the grasp filter of the planner."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.choose import NoGraspError, grasp_candidates
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.robot.placement import default_instance


def _box(lib: eac.Library, at: np.ndarray) -> eac.Instance:
    pose = np.eye(4)
    pose[:3, 3] = at
    return lib["Cuboid"].instantiate(params={"size": (0.1, 0.1, 0.1)}, pose=pose)


@pytest.mark.slow
def test_an_obstacle_at_the_hand_collides_and_one_far_away_does_not(
    lib: eac.Library, panda: Robot
) -> None:
    drawer = default_instance(panda, lib["CabinetDrawer"], "open")
    assert not collision_scene(panda, drawer).collides(panda.home)
    at_hand = _box(lib, panda.fk(panda.home)[:3, 3])
    far = _box(lib, np.array([0.0, 3.0, 0.5]))
    assert collision_scene(panda, drawer, obstacles=[at_hand]).collides(panda.home)
    scene = collision_scene(panda, drawer, obstacles=[far])
    assert not scene.collides(panda.home)
    scene.place(drawer.with_joints({"slide": 0.1}))  # the object still moves, the obstacle not
    assert not scene.collides(panda.home)


@pytest.mark.slow
def test_the_grasp_filter_keeps_only_the_named_options(lib: eac.Library, panda: Robot) -> None:
    drawer = default_instance(panda, lib["CabinetDrawer"], "close").with_joints({"slide": 0.15})
    everything, _ = grasp_candidates(panda, drawer, "close", starts=0)
    assert {c.option.grasp for c in everything} == {"handle.pull", "push_front", "push_top"}
    only, _ = grasp_candidates(panda, drawer, "close", starts=0, grasps=["push_front"])
    assert {c.option.grasp for c in only} == {"push_front"}
    with pytest.raises(NoGraspError):
        grasp_candidates(panda, drawer, "close", starts=0, grasps=["no_such_grasp"])
