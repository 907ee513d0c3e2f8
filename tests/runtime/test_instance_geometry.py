"""Instance geometry: the mesh, signed distance and surface samples of a posed, opened instance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

import grace_dsl as eac
from grace_dsl.runtime.shapes import ShapeTree

CABINET = Path(__file__).resolve().parent.parent / "export" / "cabinet.eac"


@pytest.fixture(scope="module")
def door(lib: eac.Library) -> eac.Instance:
    pose = trimesh.transformations.rotation_matrix(0.7, [0.2, 1.0, 0.1], [0.3, -0.2, 0.5])
    return lib["SunkenDoor"].instantiate(pose=pose, joints={"hinge": 0.6})


@pytest.fixture(scope="module")
def cabinet() -> eac.Instance:
    return eac.compile_paths([CABINET])["Cabinet"].instantiate()


def piece_meshes(inst: eac.Instance) -> list[trimesh.Trimesh]:
    """Every outermost piece as its own world mesh (an independent route to containment)."""
    tree = ShapeTree(inst)
    out = []
    for name in tree.outermost():
        for piece in tree.pieces(name, tree.placement(name), []):
            link = piece.link
            motion = inst.link_pose(link) @ np.linalg.inv(tree.link_pose(link))
            out.append(piece.mesh.copy().apply_transform(motion @ piece.pose))
    return out


@pytest.mark.parametrize("which", ["door", "cabinet"])
def test_sdf_sign_agrees_with_mesh_containment(which: str, request: pytest.FixtureRequest) -> None:
    inst = request.getfixturevalue(which)
    meshes = piece_meshes(inst)
    lo, hi = inst.mesh().bounds
    points = np.random.default_rng(5).uniform(lo - 0.03, hi + 0.03, (20_000, 3))
    d = inst.sdf(points)
    far = np.abs(d) > 1e-3
    inside = np.any([m.contains(points[far]) for m in meshes], axis=0)
    assert np.mean((d[far] < 0) == inside) >= 0.999


@pytest.mark.parametrize("which", ["door", "cabinet"])
def test_samples_lie_on_the_outer_surface(which: str, request: pytest.FixtureRequest) -> None:
    inst = request.getfixturevalue(which)
    pts, normals = inst.sample_surface_with_normals(3000, seed=2)
    assert pts.shape == normals.shape == (3000, 3)
    distances = np.abs(inst.sdf(pts))
    if which == "door":  # primitives only: samples are exactly on the surface
        assert distances.max() < 1e-6
    assert np.percentile(distances, 99) < 1e-4  # a difference's boolean mesh is made of chords
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)
    step = inst.sdf(pts + 1e-4 * normals) - inst.sdf(pts)
    assert np.mean(step > 0) > 0.97  # normals point out
    np.testing.assert_array_equal(inst.sample_surface(3000, seed=2), pts)


def test_the_mesh_moves_with_the_joints(door: eac.Instance, lib: eac.Library) -> None:
    closed = lib["SunkenDoor"].instantiate(pose=door.pose)
    motion = door.link_pose("leaf") @ np.linalg.inv(closed.link_pose("leaf"))
    moved = closed.link_mesh("leaf").apply_transform(motion)
    # a union (manifold3d, float32 vertices): the same solid to ~1e-7 m, in its own triangles
    opened = door.link_mesh("leaf")
    assert opened.volume == pytest.approx(moved.volume, rel=1e-5)
    assert np.abs(trimesh.proximity.signed_distance(moved, opened.vertices)).max() < 1e-6
    assert door.mesh().is_watertight or len(door.mesh().faces) > 0


def test_difference_removes_material(cabinet: eac.Instance) -> None:
    tree = ShapeTree(cabinet)
    centre = tree.placement("holed")[:3, 3]  # the hole's axis runs through the cube's centre
    wall = centre + [0.025, 0.0, 0.0]  # inside the cube, outside the 10 mm hole
    d = cabinet.sdf(np.array([centre, wall]))
    assert d[0] > 0.005 and d[1] < 0


def test_bad_points_give_a_typed_error(door: eac.Instance) -> None:
    with pytest.raises(eac.ParameterError, match=r"\(N, 3\)"):
        door.sdf(np.zeros((4, 2)))
    with pytest.raises(eac.ParameterError, match="finite"):
        door.sdf(np.array([[np.nan, 0, 0]]))


def test_a_union_inside_a_part_placed_off_its_link_is_placed_once(tmp_path: Path) -> None:
    """The part's placement applies once to a composite's operands (it was applied twice)."""
    src = tmp_path / "u.eac"
    src.write_text(
        "use primitives.{Cuboid, Sphere}\n"
        "concept Knob {\n"
        "    shape a = Cuboid(size: (20mm, 20mm, 20mm)) at trans(0, 0, 10mm)\n"
        "    shape b = Sphere(radius: 12mm) at trans(0, 0, 30mm)\n"
        "    shape both = union(a, b) at rotx(90deg)\n"
        "}\n"
        "concept Host {\n"
        "    shape plate = Cuboid(size: (400mm, 400mm, 10mm))\n"
        "    part knob = Knob() at trans(150mm, -100mm, 5mm) * rotz(30deg)\n"
        "}\n"
    )
    inst = eac.compile_paths([src])["Host"].instantiate()
    place = trimesh.transformations.translation_matrix([0.15, -0.1, 0.005])
    place = place @ trimesh.transformations.rotation_matrix(np.radians(30), [0, 0, 1])
    place = place @ trimesh.transformations.rotation_matrix(np.radians(90), [1, 0, 0])
    centre_a = (place @ [0, 0, 0.01, 1])[:3]
    centre_b = (place @ [0, 0, 0.03, 1])[:3]
    np.testing.assert_allclose(inst.sdf(np.array([centre_a, centre_b])), [-0.01, -0.012], atol=1e-9)
