"""The built-in appliance fronts of grace_dsl/concepts/appliances.eac made of carcass-free parts:
``DropDoor`` (a bottom-hinged door), ``BuiltInDishwasher`` (a hollow tub, a drop door, a kick
plate) and ``OvenWithDrawer`` (a housing with a drop door over a storage drawer).

Directions and positions are written here from the physical object (the door's top falls
towards the viewer, the drawer slides straight out, the tub is empty), not read back from the
concepts' formulas; the SDF agrees with the mesh; the MJCF export loads in MuJoCo and its bodies
move as the instance's links do.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import trimesh

import grace_dsl as eac
from grace_dsl.export import export_mjcf
from grace_dsl.export.model import build_model
from grace_dsl.runtime.errors import RequirementError
from grace_dsl.runtime.shapes import ShapeTree


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def _start(inst: eac.Instance, action: str, grasp: str) -> np.ndarray:
    """The unit direction in which ``grasp``'s point starts to move along ``action``: from the
    closed state for an opening action, from half open for a closing one."""
    joint = inst.concept.actions[action]["joint"]
    lo, hi = inst.joint_limits()[joint]
    opening = action.startswith("open")
    start = inst if opening else inst.with_joints({joint: (lo + hi) / 2})
    q0 = start.joints[joint]
    target = q0 + (1e-4 if opening else -1e-4) * (hi - lo)
    path = start.follow(action, grasp=start.grasp(grasp), to=target, steps=2)
    step = path[-1, :3, 3] - path[0, :3, 3]
    return step / np.linalg.norm(step)


def _falls_forward(direction: np.ndarray) -> bool:
    """Mostly towards the viewer (+z), a little down (a point in front of a bottom hinge line
    starts along the circle about it), never sideways."""
    return bool(direction[2] > 0.95 and -0.3 < direction[1] <= 1e-9 and abs(direction[0]) < 1e-9)


def test_drop_door_falls_towards_the_viewer_and_lies_level_above_its_hinge(lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["DropDoor"].instantiate(size=(0.6, 0.5, 0.04), opening=np.pi / 2)
    assert _falls_forward(_start(door, "open", "handle.pull"))
    opened = door.with_joints({"hinge": np.pi / 2})
    # the back face's top edge ends one thickness above the hinge line (the front of the
    # bottom edge), a door height in front of it: the door lies level, above the hinge
    top_back = opened.link_pose("leaf") @ np.array([0.0, 0.25, 0.0, 1.0])
    np.testing.assert_allclose(top_back[:3], [0.0, -0.25 + 0.04, 0.04 + 0.5], atol=1e-12)
    # the bar is `handle_drop` below the top edge, in front of the door
    g = door.grasp("handle.pull")
    assert g[1, 3] == pytest.approx(0.25 - 0.06) and g[2, 3] > 0.04
    with pytest.raises(RequirementError, match="handle fits"):
        lib["DropDoor"].instantiate(size=(0.45, 0.5, 0.04), **{"handle.length": 0.45})


def test_dishwasher_is_a_hollow_tub_on_a_recessed_kick_plate(lib) -> None:  # type: ignore[no-untyped-def]
    dw = lib["BuiltInDishwasher"].instantiate(size=(0.596, 0.71, 0.56), wall=0.02)
    assert list(dw.joints) == ["door.hinge"]
    sdf = dw.sdf(np.array([[0.0, 0.0, 0.0], [-0.29, 0.0, 0.0]]))
    assert sdf[0] > 0.2 and sdf[1] < 0  # an empty tub, a solid side wall
    below = -0.355 - 0.05  # in the kick plate's height
    kick = dw.sdf(np.array([[0.0, below, 0.28 - 0.05 - 0.009], [0.0, below, 0.28 - 0.02]]))
    assert kick[0] < 0 < kick[1]  # its front board sits 50 mm back
    # the door covers the front and its top falls towards the viewer
    assert dw.sdf(np.array([[0.0, 0.0, 0.28 + 0.02]]))[0] < 0
    assert _falls_forward(_start(dw, "open", "door.handle.pull"))
    back = _start(dw, "close", "door.handle.pull")  # from half open: up and back
    assert back[1] > 0.5 and back[2] < -0.5


def test_oven_door_and_drawer_move_their_own_links(lib) -> None:  # type: ignore[no-untyped-def]
    oven = lib["OvenWithDrawer"].instantiate(size=(0.596, 0.74, 0.56), drawer_height=0.15)
    assert set(oven.joints) == {"door.hinge", "drawer.slide", "dial.spin"}
    opened = oven.with_joints({"drawer.slide": 0.3})
    np.testing.assert_allclose(
        opened.link_pose("drawer.drawer")[:3, 3] - oven.link_pose("drawer.drawer")[:3, 3],
        [0, 0, 0.3],
        atol=1e-12,
    )
    np.testing.assert_array_equal(opened.link_pose("door.leaf"), oven.link_pose("door.leaf"))
    np.testing.assert_allclose(_start(oven, "open_drawer", "drawer.handle.pull"), [0, 0, 1])
    assert _falls_forward(_start(oven, "open", "door.handle.pull"))
    # the drawer's handle is in the bottom 150 mm, the door's above it, under the strip
    low, high = oven.grasp("drawer.handle.pull")[1, 3], oven.grasp("door.handle.pull")[1, 3]
    assert -0.37 < low < -0.37 + 0.15 < high < 0.37 - 0.1
    # the door falls clear of the drawer: its back face stays above the drawer's front
    down = oven.with_joints({"door.hinge": oven.joint_limits()["door.hinge"][1]})
    corner = down.link_pose("door.leaf") @ np.array([0.0, 0.0, 0.0, 1.0])
    assert corner[1] > -0.37 + 0.15
    with pytest.raises(RequirementError, match="oven's cavity"):
        lib["OvenWithDrawer"].instantiate(size=(0.596, 0.64, 0.56), drawer_height=0.2)


def _piece_meshes(inst: eac.Instance) -> list[trimesh.Trimesh]:
    tree = ShapeTree(inst)
    out = []
    for name in tree.outermost():
        for piece in tree.pieces(name, tree.placement(name), []):
            motion = inst.link_pose(piece.link) @ np.linalg.inv(tree.link_pose(piece.link))
            out.append(piece.mesh.copy().apply_transform(motion @ piece.pose))
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", ["BuiltInDishwasher", "OvenWithDrawer"])
def test_sdf_sign_agrees_with_the_mesh(lib, name: str) -> None:  # type: ignore[no-untyped-def]
    closed = lib[name].instantiate()
    half = {n: 0.5 * hi for n, (_, hi) in closed.joint_limits().items() if np.isfinite(hi)}
    inst = closed.with_joints(half)
    meshes = _piece_meshes(inst)
    lo, hi = inst.mesh().bounds
    points = np.random.default_rng(3).uniform(lo - 0.02, hi + 0.02, (6000, 3))
    d = inst.sdf(points)
    far = np.abs(d) > 1e-3
    inside = np.any([m.contains(points[far]) for m in meshes], axis=0)
    assert np.mean((d[far] < 0) == inside) >= 0.998


@pytest.mark.parametrize("name", ["BuiltInDishwasher", "OvenWithDrawer"])
def test_mjcf_loads_in_mujoco_and_moves_as_the_instance(lib, name: str) -> None:  # type: ignore[no-untyped-def]
    inst = lib[name].instantiate()
    exported = build_model(inst)
    model = mujoco.MjModel.from_xml_string(export_mjcf(inst))
    data = mujoco.MjData(model)
    moving = [j for j in exported.joints if j.kind != "fixed"]
    assert model.njnt == len(moving) == len(inst.joints)
    values = {}
    for j in moving:
        lo, hi = inst.joint_limits()[j.source]
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j.name)
        if np.isfinite(hi - lo):
            values[j.source] = lo + 0.6 * (hi - lo)
            assert model.jnt_limited[jid]
            np.testing.assert_allclose(model.jnt_range[jid], [lo, hi], atol=1e-9)
        else:  # the dial turns without a stop
            values[j.source] = 0.7
            assert not model.jnt_limited[jid]
        data.qpos[model.jnt_qposadr[jid]] = values[j.source]
    mujoco.mj_forward(model, data)
    moved = inst.with_joints(values)
    for link in exported.links:
        bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, link.name)
        if bid < 0:
            continue
        want = moved.link_pose(link.source) @ link.offset
        np.testing.assert_allclose(data.xpos[bid], want[:3, 3], atol=1e-6)
        np.testing.assert_allclose(data.xmat[bid].reshape(3, 3), want[:3, :3], atol=1e-6)
