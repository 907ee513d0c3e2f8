"""An instance of a primitive concept (``lib["Torus"].instantiate()``) is the primitive itself:
its mesh has the analytic volume, its surface samples lie on its signed-distance zero set, and
it is written (mesh files, URDF, MJCF) like any concept's shape."""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.geometry import volume
from grace_dsl.geometry.pieces import convex_pieces
from tests.render.conftest import random_pose

# a non-default parameter set per primitive (SI), to see the instance's values are the ones used
OTHER: dict[str, dict[str, Any]] = {
    "Cuboid": {"size": (0.2, 0.3, 0.05)},
    "Cylinder": {"radius": 0.05, "height": 0.2, "radian": math.pi},
    "Tube": {"r_in": 0.03, "r_out": 0.05, "height": 0.1},
    "Ring": {"r_in": 0.05, "r_out": 0.06, "height": 0.02, "radian": 1.5 * math.pi},
    "RectRing": {"outer": (0.3, 0.2), "inner": (0.2, 0.1), "depth": 0.03},
    "Sphere": {"radius": 0.07},
    "Capsule": {"radius": 0.02, "length": 0.3},
    "Frustum": {"r_bottom": 0.05, "r_top": 0.03, "height": 0.12},
    "TaperedCuboid": {"size": (0.2, 0.1, 0.15), "top": (0.1, 0.05), "offset": (0.02, -0.01)},
    "SphericalCap": {"radius": 0.05, "height": 0.03},
    "Torus": {"r_major": 0.1, "r_minor": 0.02, "radian": math.pi},
    "Prism": {"sides": 5, "radius": 0.04, "height": 0.03},
    "BoardBox": {"size": (0.4, 0.5, 0.3), "board": 0.018, "top": False, "front": True},
}
NONE: dict[str, Any] = {}
CASES = [(n, NONE) for n in OTHER] + [(n, dict(p)) for n, p in OTHER.items()]
IDS = [f"{n}-{'other' if p else 'defaults'}" for n, p in CASES]


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def test_the_cases_are_every_primitive_concept(lib) -> None:
    assert set(OTHER) == {n for n in lib if lib[n].entry["kind"] == "primitive"}


def _instance(lib: eac.Library, name: str, params: dict[str, Any], seed: int) -> eac.Instance:
    return lib[name].instantiate(pose=random_pose(np.random.default_rng(seed)), **params)


@pytest.mark.parametrize(("name", "params"), CASES, ids=IDS)
def test_mesh_has_the_analytic_volume(lib, name, params) -> None:
    inst = _instance(lib, name, params, seed=1)
    mesh = inst.mesh(resolution=128)
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(volume(name, inst.params), rel=2e-3)


@pytest.mark.parametrize(("name", "params"), CASES, ids=IDS)
def test_surface_samples_and_mesh_vertices_lie_on_the_zero_set(lib, name, params) -> None:
    inst = _instance(lib, name, params, seed=2)
    pts, normals = inst.sample_surface_with_normals(400, seed=3)
    assert pts.shape == (400, 3)
    np.testing.assert_allclose(inst.sdf(pts), 0, atol=1e-9)
    # 1 mm out along the normal is 1 mm away (every primitive's features are wider than 2 mm)
    np.testing.assert_allclose(inst.sdf(pts + 1e-3 * normals), 1e-3, atol=1e-9)
    np.testing.assert_allclose(inst.sdf(np.asarray(inst.mesh().vertices)), 0, atol=1e-9)


@pytest.mark.parametrize("name", sorted(OTHER))
def test_cli_writes_urdf_mjcf_and_mesh(lib, name, tmp_path, capsys) -> None:
    for fmt, ext in (("--urdf", "urdf"), ("--mjcf", "xml"), ("--stl", "stl")):
        assert main(["export", name, fmt, str(tmp_path / f"p.{ext}")]) == 0
    assert "wrote" in capsys.readouterr().out
    mj = mujoco.MjModel.from_xml_path(str(tmp_path / "p.xml"))
    inst = lib[name].instantiate()
    # visual: a BoardBox as its boards, the others whole; collision: the convex pieces
    split = len(convex_pieces(name, inst.params) or ())
    visual = split if name == "BoardBox" else 1
    colliding = mj.geom_contype != 0
    assert split > 1 or name not in ("BoardBox", "RectRing", "Tube", "Ring", "Torus")
    assert int(colliding.sum()) == max(split, 1) and int((~colliding).sum()) == visual
    assert set(mj.geom_group[colliding]) == {3} and set(mj.geom_group[~colliding]) == {2}
    assert mj.nbody == 2  # the world and the primitive
    solid = 600 * volume(name, inst.params)
    assert 0 < mj.body_mass[1] <= solid * 1.02  # at most the solid body (a shell if lighter)
