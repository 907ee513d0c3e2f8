"""The other hands in simulation: a translate-only hand keeps its rotation along a turning path,
a hand that cannot close has no fingers to drive, and both run real episodes."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.sim.control import PathFollower, rotation_angle
from grace_dsl.sim.episode import Z_UP, run_episode
from grace_dsl.sim.hand_motion import TranslatingFollower, follower_for
from grace_dsl.sim.records import EpisodeConfig
from grace_dsl.sim.runner import episode_seed
from grace_dsl.sim.world import World


def test_a_hand_that_cannot_turn_follows_a_hinge_by_translating(lib: eac.Library) -> None:
    inst = lib["HingedCabinet"].instantiate(pose=Z_UP)
    grasp = inst.grasp("handle.pull")
    joint = "hinge"
    lo, hi = inst.joint_limits()[joint]
    turning = follower_for(Gripper.panda(), inst, joint, grasp, hi, 1.0)
    fixed = follower_for(Gripper.load("topdown"), inst, joint, grasp, hi, 1.0)
    assert type(turning) is PathFollower and isinstance(fixed, TranslatingFollower)
    q = lo + 0.5 * (hi - lo)
    assert rotation_angle(turning.pose_at(q), grasp) > 0.3  # the path turns the hand
    assert rotation_angle(fixed.pose_at(q), grasp) < 1e-9  # this hand keeps its rotation
    assert np.allclose(fixed.pose_at(q)[:3, 3], turning.pose_at(q)[:3, 3])


@pytest.mark.slow
def test_the_pusher_is_built_without_finger_joints(lib: eac.Library) -> None:
    inst = lib["Drawer"].instantiate(pose=Z_UP)
    start = np.eye(4)
    start[:3, 3] = (0.5, 0.0, 0.5)
    world = World.build(inst, Gripper.load("pusher"), start)
    assert world.hand.fingers == () and world.hand.actuators == ()
    assert world.model.nu == 0
    names = {world.model.geom(i).name for i in range(world.model.ngeom)}
    assert {"hand_palm0", "hand_pad_left", "hand_finger_left0"} <= names


@pytest.mark.slow
def test_the_pusher_closes_a_drawer_and_the_topdown_hand_opens_a_dish_drawer() -> None:
    pushed = run_episode(EpisodeConfig("Drawer", "close", hand="pusher"), 3)
    assert pushed.strict, pushed.detail
    assert pushed.option.endswith("(push)")
    seed = episode_seed(0, "DishDrawer", "open", 0)
    lifted = run_episode(EpisodeConfig("DishDrawer", "open", hand="topdown"), seed)
    assert lifted.strict, lifted.detail
