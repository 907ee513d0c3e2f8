"""The persistent multi-object world: joint states survive between actions on several objects."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.sim.multi import MultiWorld, MultiWorldError, place


@pytest.fixture(scope="module")
def world(lib: eac.Library) -> MultiWorld:
    chest = place(lib["ChestOfDrawers"].instantiate(joints={"slide1": 0.2}), (0.0, 0.0, 0.0))
    microwave = place(lib["Microwave"].instantiate(), (0.0, 1.2, 0.0))
    return MultiWorld([("chest", chest), ("microwave", microwave)])


def test_objects_start_at_their_joint_values_and_face_x(world: MultiWorld) -> None:
    assert world.joints("chest") == pytest.approx({"slide1": 0.2, "slide2": 0.0, "slide3": 0.0})
    assert world.q("microwave", "hinge") == 0.0
    front = world.instance("chest").pose[:3, 2]  # the concept's +z, out of its front
    assert np.allclose(front, [1.0, 0.0, 0.0], atol=1e-9)
    with pytest.raises(MultiWorldError, match="no object 'oven'"):
        world.q("oven", "hinge")
    with pytest.raises(MultiWorldError, match="no movable joint 'slide9'"):
        world.q("chest", "slide9")


@pytest.mark.slow
def test_states_persist_between_actions_on_different_objects(world: MultiWorld) -> None:
    """Open the microwave to a goal, then close the chest's top drawer: the microwave stays
    where the first action left it, and the chest's other drawers never move."""
    options = [o for o in world.instance("microwave").rank("open", gripper=world.gripper)]
    done = world.act("microwave", "open", "hinge", 1.0, options[0], goal=0.8)
    assert done.q_before == 0.0
    assert done.q_after == pytest.approx(0.8, abs=0.05)
    options = [o for o in world.instance("chest").rank("close1", gripper=world.gripper)]
    shut = world.act("chest", "close1", "slide1", -1.0, options[0])
    assert shut.q_before == pytest.approx(0.2, abs=0.005)
    assert shut.q_after < 0.01
    assert world.q("microwave", "hinge") == pytest.approx(done.q_after, abs=0.01)
    assert world.joints("chest")["slide2"] == pytest.approx(0.0, abs=1e-3)
    assert world.instance("chest").joints["slide1"] == pytest.approx(shut.q_after)
