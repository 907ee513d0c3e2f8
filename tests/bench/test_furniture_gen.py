"""The benchmark's furniture generator writes models that Pinocchio and MuJoCo load, with the
joints it sampled (kinds, axes, hinge sides, limits) and link meshes that reassemble the model."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "bench"))
import furniture_gen as gen  # noqa: E402


@pytest.mark.parametrize("layout", gen.LAYOUTS)
def test_urdf_loads_with_the_sampled_joints(layout: str, tmp_path: Path) -> None:
    model = gen.sample_model(layout, seed=7)
    urdf = gen.write_model(model, tmp_path)
    pm = pin.buildModelFromUrdf(str(urdf))
    names = [pm.names[i] for i in range(1, pm.njoints)]
    assert names == [j.name for j in model.joints]
    for k, j in enumerate(model.joints, start=1):
        kind = pm.joints[k].shortname()
        assert ("R" in kind) == (j.kind == "revolute") and ("P" in kind) == (j.kind == "prismatic")
        axis = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}
        letter = kind[-1]
        signed = np.asarray(axis[letter], float) if letter in axis else None
        if signed is None:  # an unaligned axis: pinocchio keeps it in the joint model
            signed = np.asarray(pm.joints[k].extract().axis)
        if j.kind == "revolute":  # pinocchio folds a negative axis into the joint placement
            world = pm.jointPlacements[k].rotation @ signed
            assert np.allclose(world, j.axis) or np.allclose(-world, j.axis)
        np.testing.assert_allclose(pm.jointPlacements[k].translation, j.origin, atol=1e-9)
        assert pm.upperPositionLimit[k - 1] == pytest.approx(j.upper)
    mj = mujoco.MjModel.from_xml_path(str(urdf))
    assert mj.njnt == len(model.joints)
    for k, j in enumerate(model.joints):
        assert mj.jnt_type[k] == (
            mujoco.mjtJoint.mjJNT_HINGE if j.kind == "revolute" else mujoco.mjtJoint.mjJNT_SLIDE
        )
        np.testing.assert_allclose(mj.jnt_axis[k], j.axis, atol=1e-9)
    meta = json.loads((urdf.parent / "meta.json").read_text())
    assert meta["q"] == model.q and meta["layout"] == layout


def test_hinge_side_opens_the_door_towards_the_viewer(tmp_path: Path) -> None:
    for seed in range(6):
        model = gen.sample_model("door", seed)
        (door,) = model.joints
        opened = model.link_mesh("door").apply_transform(model.motion(door, np.pi / 2))
        closed = model.link_mesh("door")
        # a quarter turn puts the leaf in front of the carcass, on its hinge's side
        assert opened.bounds[1, 2] > closed.bounds[1, 2] + 0.2
        side = np.sign(opened.centroid[0] - closed.centroid[0])
        assert side == (-1 if door.hinge == "left" else 1)
        assert (door.axis[1] < 0) == (door.hinge == "left")


def test_link_meshes_reassemble_the_model(tmp_path: Path) -> None:
    model = gen.sample_model("drawers3", seed=3)
    urdf = gen.write_model(model, tmp_path)
    origins = {j.child: np.asarray(j.origin) for j in model.joints}
    for link in model.links:
        mesh = trimesh.load(urdf.parent / "textured_objs" / f"{link}.obj", force="mesh")
        mesh.apply_translation(origins.get(link, np.zeros(3)))
        np.testing.assert_allclose(mesh.bounds, model.link_mesh(link).bounds, atol=1e-8)


def test_models_are_seeded_and_the_mix_is_fixed() -> None:
    a, b = gen.sample_models(9, seed=1), gen.sample_models(9, seed=1)
    assert [m.params for m in a] == [m.params for m in b]
    assert [m.layout for m in a][:2] == ["door", "drawers3"]
    with pytest.raises(ValueError, match="layouts"):
        gen.sample_model("wardrobe", 0)


def test_side_by_side_layouts_put_drawers_in_one_row() -> None:
    for layout, doors in (("drawers_side", 0), ("drawers_over_doors", 2)):
        model = gen.sample_model(layout, seed=11)
        slides = [j for j in model.joints if j.kind == "prismatic"]
        hinges = [j for j in model.joints if j.kind == "revolute"]
        assert len(slides) >= 2 and len(hinges) == doors
        assert len({round(j.origin[1], 6) for j in slides}) == 1  # one row
        xs = sorted(j.origin[0] for j in slides)
        assert all(b - a > 0.2 for a, b in zip(xs, xs[1:]))  # side by side
        if doors:  # the pair under the drawers, hinged at the outer edges
            assert sorted(j.hinge for j in hinges) == ["left", "right"]
            assert max(j.origin[1] for j in hinges) < min(j.origin[1] for j in slides)
