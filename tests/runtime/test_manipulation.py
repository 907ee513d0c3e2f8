"""Ranking the manipulation functions of an action for a gripper's abilities."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.manipulation import Option
from grace_dsl.runtime.manipulation import _judge as judge
from tests.conftest import write

DOOR = """use primitives.{Cuboid, Capsule}

/// A hinged door with a vertical bar handle near its free edge.
concept BarDoor {
    param size : vec3 length in [(300mm, 400mm, 15mm), (900mm, 2100mm, 50mm)] = (400mm, 600mm, 20mm)
    param radius : length in [5mm, 60mm] = 8mm "radius of the bar"
    let bar_x = size.x / 2 - 50mm
    let bar_z = size.z / 2 + 30mm
    link leaf {
        shape panel = Cuboid(size: size)
        shape bar = Capsule(radius: radius, length: 120mm) at trans(bar_x, 0, bar_z) * rotx(90deg)
        /// Pinch the bar from the front at height s.
        grasp pinch(s in [-50mm, 50mm] = 0) =
            trans(bar_x, s, bar_z) * roty(180deg) * rotz(90deg)
            width 2 * radius
        /// Hook the closed fingers behind the bar at height s, coming in from the free edge; the
        /// wall they rest on (the bar's back) is on their +x side.
        grasp hook(s in [-50mm, 50mm] = 0) =
            trans(bar_x, s, bar_z - radius - 10mm) * roty(-90deg)
            by hook
        /// The same fingers laid on the bar's front (+x of the grasp points back at the door).
        grasp hook_front(s in [-50mm, 50mm] = 0) =
            trans(bar_x, s, bar_z + radius + 10mm) * roty(90deg)
            by hook
        /// Push the front face near the free edge.
        grasp push_edge = trans(size.x / 2 - 10mm, 0, size.z / 2) * roty(180deg) by push
    }
    joint hinge : revolute(base -> leaf) axis (0, 1, 0) at (-size.x / 2, 0, 0)
        range [0, 110deg] opens -
    /// Pull the door open toward the robot.
    action open = pull along hinge using pinch, hook, push_edge, hook_front
    /// Push it shut.
    action close = push along hinge using push_edge, pinch
}
"""


@pytest.fixture(scope="module")
def door(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    return eac.compile_paths([write(tmp_path_factory.mktemp("door"), "door.eac", DOOR)])["BarDoor"]


def facing_robot() -> np.ndarray:
    """The door stands 1 m in front of the robot, its front (+z) facing back at it (-x world)."""
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])  # x = y cross z
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


def test_a_free_hand_prefers_pinch_then_hook_and_cannot_pull_by_pushing(door: eac.Concept) -> None:
    options = door.instantiate(pose=facing_robot(), joints={"hinge": 0.2}).rank(
        "open", Gripper.panda()
    )
    assert [o.grasp for o in options] == ["pinch", "hook", "hook_front", "push_edge"]
    assert [o.feasible for o in options] == [True, True, False, False]
    assert "push contact cannot apply the force of open" in options[3].reasons[0]
    assert "deg from the fingers' approach" in options[3].reasons[0]
    assert options[0].tilt == 0.0 and options[0].pose is not None


def test_pushing_shut_is_feasible_by_push_and_pinch(door: eac.Concept) -> None:
    options = door.instantiate(pose=facing_robot(), joints={"hinge": 0.5}).rank("close")
    assert {o.grasp: o.feasible for o in options} == {"pinch": True, "push_edge": True}
    assert options[0].grasp == "pinch"


def test_a_hand_that_cannot_close_hooks(door: eac.Concept) -> None:
    hook_only = dataclasses.replace(Gripper.panda(), can_close=False)
    options = door.instantiate(pose=facing_robot()).rank("open", hook_only)
    assert options[0].grasp == "hook" and options[0].feasible
    pinch = next(o for o in options if o.grasp == "pinch")
    assert not pinch.feasible and "needs fingers that close" in pinch.reasons[0]


def test_a_thick_bar_does_not_fit_the_panda(door: eac.Concept) -> None:
    options = door.instantiate(pose=facing_robot(), radius=0.045).rank("open")
    pinch = next(o for o in options if o.grasp == "pinch")
    assert not pinch.feasible and "needs a 90 mm opening" in pinch.reasons[0]
    # a 45 mm bar 30 mm off the door sinks into it: no room behind it for the fingers either
    hook = next(o for o in options if o.grasp == "hook")
    assert not hook.feasible and "enters the part" in hook.reasons[0]


def test_a_top_down_hand_cannot_reach_a_front_face(door: eac.Concept) -> None:
    top_down = dataclasses.replace(
        Gripper.panda(), approach=(0.0, 0.0, -1.0), approach_tolerance=math.radians(20)
    )
    facing = door.instantiate(pose=facing_robot()).rank("open", top_down)
    assert not any(o.feasible for o in facing)
    assert "tilt 90 deg" in facing[0].reasons[-1]
    lying = door.instantiate(pose=np.eye(4)).rank("open", top_down)  # front facing up: from above
    assert lying[0].grasp == "pinch" and lying[0].tilt == 0.0
    np.testing.assert_allclose(lying[0].pose[:3, 2], (0, 0, -1), atol=1e-12)
    # it reaches the bar from above, but a pinch carries the hand round with the door (110 deg)
    assert not lying[0].feasible and "along the path the hand would tilt" in lying[0].reasons[0]


def test_options_carry_the_free_parameters_of_their_pose(door: eac.Concept) -> None:
    inst = door.instantiate(pose=facing_robot())
    best = inst.rank("open")[0]
    np.testing.assert_allclose(best.pose, inst.grasp(best.grasp, **best.free), atol=1e-12)


def test_unknown_actions_and_bad_samples_are_errors(door: eac.Concept) -> None:
    inst = door.instantiate()
    with pytest.raises(eac.UnknownNameError, match="open"):
        inst.rank("opn")
    with pytest.raises(eac.ParameterError, match="samples"):
        inst.rank("open", samples=0)


def test_a_hook_pulls_only_towards_the_wall_on_its_plus_x_side(door: eac.Concept) -> None:
    """The force must press the fingers onto the wall they rest on: the bar's back (+x of
    ``hook``) when pulling open; ``hook_front`` lies on the bar's front and would slip off."""
    inst = door.instantiate(pose=facing_robot(), joints={"hinge": 0.3})
    options = {o.grasp: o for o in inst.rank("open")}
    assert options["hook"].feasible
    front = options["hook_front"]
    assert not front.feasible and "pulls the fingers off the wall" in front.reasons[0]
    for o in (options["hook"], front):  # the check is on +x of the pose, in the world
        f = inst.force("open", grasp=o.pose)
        assert (float(f @ o.pose[:3, 0]) > 0) == o.feasible


def _judge(inst: eac.Instance, action: str, grasp: str) -> Option:
    """One grasp judged for an action, whether or not the action lists it."""
    return judge(inst, inst._action(action), grasp, Gripper.panda(), 8, None)


def test_a_sliding_window_opens_and_closes_by_opposite_pocket_walls(lib: eac.Library) -> None:
    window = lib["SlidingWindow"].instantiate(pose=facing_robot(), joints={"track": 0.2})
    assert [o.grasp for o in window.rank("open")] == ["handle.pull"]
    assert [o.grasp for o in window.rank("close")] == ["handle.pull_back"]
    for action, right, wrong in (
        ("open", "handle.pull", "handle.pull_back"),
        ("close", "handle.pull_back", "handle.pull"),
    ):
        assert _judge(window, action, right).feasible
        bad = _judge(window, action, wrong)
        assert not bad.feasible and "pulls the fingers off the wall" in bad.reasons[0]


def test_a_pocket_pull_slides_each_way_by_its_own_wall(lib: eac.Library) -> None:
    pocket = lib["PocketHandle"].instantiate(pose=facing_robot())
    (opening,) = pocket.rank("slide_open")
    (closing,) = pocket.rank("slide_closed")
    assert (opening.grasp, opening.feasible) == ("pull", True)
    assert (closing.grasp, closing.feasible) == ("pull_back", True)
    assert not _judge(pocket, "slide_closed", "pull").feasible
    assert not _judge(pocket, "slide_open", "pull_back").feasible
