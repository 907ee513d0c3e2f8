"""The board furniture of ``concepts/furniture.eac``: parts without a carcass, placed by hosts.

Checked against numbers computed here from the parameters: where the door's hinge is and which
way it opens, where a drawer's front goes when it slides, that the carcass is hollow (a point
inside it is outside the instance), that the plinth's front is set back, and that the MuJoCo
export collides with the boards rather than a solid block.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from grace_dsl import Gripper
from grace_dsl.export import export_mjcf
from grace_dsl.runtime.errors import RequirementError
from grace_dsl.runtime.kinematics import Kinematics


@pytest.mark.parametrize("side", ["left", "right"])
def test_door_leaf_hinges_on_its_side_and_opens_towards_the_viewer(lib, side: str) -> None:  # type: ignore[no-untyped-def]
    leaf = lib["DoorLeaf"].instantiate(size=(0.5, 0.7, 0.02), hinge_side=side)
    axes = Kinematics.of(leaf).joint_axes()
    edge = -0.25 if side == "left" else 0.25
    np.testing.assert_allclose(axes.origins[0][[0, 2]], [edge, 0.0], atol=1e-12)
    opened = leaf.with_joints({"hinge": np.pi / 2})
    # the free edge's back corner swings out in front of the hinge, by the leaf's width
    free = np.array([[-edge + 0.0, 0.0, 0.0]])
    moved = opened.link_pose("leaf") @ np.array([*free[0], 1.0])
    np.testing.assert_allclose(moved[:3], [edge, 0.0, 0.5], atol=1e-9)
    # the handle sits `handle_inset` from the free edge
    g = leaf.grasp("handle.pull")
    assert abs(g[0, 3] - (-edge - (0.05 if side == "left" else -0.05))) < 1e-9


def test_drawer_slides_its_front_tray_and_handle_but_not_its_rails(lib) -> None:  # type: ignore[no-untyped-def]
    drawer = lib["Drawer"].instantiate(front=(0.6, 0.2, 0.018), depth=0.45, travel=0.4)
    out = drawer.with_joints({"slide": 0.3})
    np.testing.assert_allclose(out.link_pose("drawer")[:3, 3], [0, 0, 0.3], atol=1e-12)
    np.testing.assert_allclose(
        out.grasp("handle.pull")[:3, 3] - drawer.grasp("handle.pull")[:3, 3], [0, 0, 0.3]
    )
    # the tray is open at the top: the middle of the tray's opening is outside the drawer
    tray_top = np.array([[0.0, 0.1 - 0.02 - 0.001, -0.2]])
    inside_tray = np.array([[0.0, 0.0, -0.2]])
    assert drawer.sdf(tray_top)[0] > 0 and drawer.sdf(inside_tray)[0] > 0.05
    with pytest.raises(RequirementError, match="runners"):
        lib["Drawer"].instantiate(depth=0.3, travel=0.4)


def test_cabinet_is_hollow_and_stands_on_a_recessed_plinth(lib) -> None:  # type: ignore[no-untyped-def]
    cab = lib["BoardCabinet"].instantiate(size=(0.6, 0.72, 0.56), board=0.018)
    sdf = cab.sdf(np.array([[0.0, 0.0, 0.0], [-0.29, 0.0, 0.0]]))
    assert sdf[0] > 0.2  # the middle of the carcass is empty
    assert sdf[1] < 0  # inside the left board
    # the plinth: under the carcass, its front board 50 mm behind the carcass's front
    below = -0.36 - 0.05
    front = cab.sdf(np.array([[0.0, below, 0.28 - 0.05 - 0.009], [0.0, below, 0.28 - 0.02]]))
    assert front[0] < 0 < front[1]


def test_chest_drawers_are_stacked_and_slide_apart(lib) -> None:  # type: ignore[no-untyped-def]
    chest = lib["BoardChest3"].instantiate(size=(0.8, 0.78, 0.48))
    assert set(chest.concept.moving_joints) == {"drawer1.slide", "drawer2.slide", "drawer3.slide"}
    ys = [chest.link_pose(f"drawer{k}.drawer")[1, 3] for k in (1, 2, 3)]
    h = (0.78 - 4 * 0.003) / 3
    np.testing.assert_allclose(ys, [0.003 + h, 0.0, -0.003 - h], atol=1e-12)
    opened = chest.with_joints({"drawer2.slide": 0.2})
    assert opened.link_pose("drawer2.drawer")[2, 3] == pytest.approx(0.24 + 0.2)
    assert opened.link_pose("drawer1.drawer")[2, 3] == pytest.approx(0.24)


def test_mujoco_collides_with_the_boards(lib) -> None:  # type: ignore[no-untyped-def]
    cab = lib["BoardCabinet"].instantiate()
    model = mujoco.MjModel.from_xml_string(export_mjcf(cab))
    boxes = sum(model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX for g in range(model.ngeom))
    assert boxes >= 5 + 1  # the carcass's five boards and the door's panel, at least
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    # the carcass's cavity is in no geom's bounding box (one mesh of the carcass, collided as
    # its convex hull, would hold it)
    centre = np.zeros(3)
    for g in range(model.ngeom):
        rot = data.geom_xmat[g].reshape(3, 3)
        local = rot.T @ (centre - data.geom_xpos[g]) - model.geom_aabb[g, :3]
        assert not np.all(np.abs(local) < model.geom_aabb[g, 3:]), model.geom(g).name


def _facing_robot() -> np.ndarray:
    """The part 1 m in front of the robot, its front (+z) facing back at it, +y up."""
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.0, 0.8)
    return m


@pytest.mark.parametrize(
    "name, edge, extra",
    [
        ("DoorLeaf", "pinch_edge[0]", {"hinge_side": "left"}),
        ("DoorLeaf", "pinch_edge[0]", {"hinge_side": "right"}),
        ("Drawer", "pinch_top[0]", {}),
    ],
)
def test_a_recessed_pull_is_opened_by_the_free_edge_pinched(
    lib, name: str, edge: str, extra
) -> None:  # type: ignore[no-untyped-def]
    """A recessed pull's cup walls face sideways, so no hook in it pulls a leaf or a drawer out
    of its face; alone, the part is opened by its free edge pinched, and in a host (free_edge
    0) that grasp is not offered at all."""
    panda = Gripper.panda()
    inst = lib[name].instantiate(pose=_facing_robot(), handle_kind="recessed", **extra)
    options = inst.rank("open", panda)
    best = options[0]
    assert best.feasible and best.grasp == edge and best.mode == "pinch"
    hook = next(o for o in options if o.grasp == "handle@recessed.pull")
    if name == "Drawer" or extra["hinge_side"] == "left":
        assert not hook.feasible and "pulls the fingers off the wall" in hook.reasons[0]
    framed = lib[name].instantiate(
        pose=_facing_robot(), handle_kind="recessed", free_edge=0, **extra
    )
    assert edge not in framed.grasp_names
    assert all(o.grasp != edge for o in framed.rank("open", panda))


@pytest.mark.parametrize(
    "name, edge, handle",
    [
        ("Drawer", "pinch_top[0]", "handle@bar.pull"),
        ("DoorLeaf", "pinch_edge[0]", "handle@bar.pull"),
    ],
)
def test_the_handle_listed_first_beats_a_free_edge_that_turns_the_hand_less(
    lib, name: str, edge: str, handle: str
) -> None:  # type: ignore[no-untyped-def]
    """Alone, a part with a bar handle offers both the handle and its free edge, both pinches
    the Panda can make; where the edge needs less turn of the hand than the handle (a drawer's
    top edge from above), the action's ``using`` order (the handle first) still decides."""
    panda = Gripper.panda()
    inst = lib[name].instantiate(pose=_facing_robot(), handle_kind="bar")
    options = inst.rank("open", panda)
    by_name = {o.grasp: o for o in options}
    assert by_name[handle].feasible and by_name[edge].feasible
    assert by_name[handle].mode == by_name[edge].mode == "pinch"
    assert by_name[handle].listed < by_name[edge].listed
    assert options[0].grasp == handle
    if name == "Drawer":  # the case that made the rule: rotation alone would pick the edge
        assert by_name[edge].rotation < by_name[handle].rotation


def test_rank_orders_feasible_then_mode_then_listed_then_rotation() -> None:
    """The sort key, on options made by hand: a listed-earlier grasp beats a smaller rotation,
    but not a better mode, and never feasibility."""
    from grace_dsl.runtime.manipulation import Option

    edge = Option("edge", "pinch", True, 0.0, rotation=0.1, listed=3)
    handle = Option("handle", "pinch", True, 0.0, rotation=1.5, listed=0)
    hook = Option("hook", "hook", True, 0.0, rotation=0.0, listed=1)
    blocked = Option("blocked", "pinch", False, 0.0, rotation=0.0, listed=0)
    got = sorted([blocked, hook, edge, handle], key=Option.sort_key)
    assert [o.grasp for o in got] == ["handle", "edge", "hook", "blocked"]
    tied = Option("other", "pinch", True, 0.0, rotation=0.2, listed=3)
    assert sorted([tied, edge], key=Option.sort_key)[0] is edge  # same place: rotation decides
