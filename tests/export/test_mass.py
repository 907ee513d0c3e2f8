"""The exported mass model: each solid weighs the lesser of a full body and a thin-walled shell,
with that model's centre of mass and inertia; the shell's are exact over the mesh triangles."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import grace_dsl as eac
from grace_dsl.export import ExportOptions, build_model
from grace_dsl.export.model import DENSITY, WALL, mass_properties, shell_properties
from grace_dsl.geometry import primitive_mesh, surface_area
from tests.render.conftest import random_pose


def _box_shell_second_moment(a: float, b: float, c: float) -> np.ndarray:
    """∫ x x^T dA over the surface of an a x b x c box centred on the origin, face by face:
    a face normal to axis k at ±d_k/2 spans the other two axes."""
    dims = np.array([a, b, c])
    out = np.zeros((3, 3))
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        area = dims[i] * dims[j]
        out[k, k] += 2 * area * dims[k] ** 2 / 4  # both faces at distance d_k / 2
        out[i, i] += 2 * area * dims[i] ** 2 / 12  # spread uniformly along the face
        out[j, j] += 2 * area * dims[j] ** 2 / 12
    return out


@pytest.mark.parametrize("seed", range(4))
def test_shell_of_a_box_matches_the_closed_form(seed: int) -> None:
    rng = np.random.default_rng(seed)
    dims = rng.uniform(0.1, 1.5, 3)
    pose = random_pose(rng)
    mesh = trimesh.creation.box(extents=dims).apply_transform(pose)
    sigma = 7.3  # kg/m^2
    mass, com, inertia = shell_properties(mesh, sigma)
    area = 2 * (dims[0] * dims[1] + dims[1] * dims[2] + dims[0] * dims[2])
    second = sigma * _box_shell_second_moment(*dims)
    body = np.trace(second) * np.eye(3) - second  # about the centre, box axes
    rot = pose[:3, :3]
    assert mass == pytest.approx(sigma * area, rel=1e-12)
    np.testing.assert_allclose(com, pose[:3, 3], atol=1e-12)
    np.testing.assert_allclose(inertia, rot @ body @ rot.T, atol=1e-12 * np.abs(body).max())


def test_shell_of_a_torus_matches_monte_carlo() -> None:
    """A curved, off-centre, rotated surface: the exact triangle integrals against the mean
    over 400 000 points drawn uniformly by area on the same mesh."""
    params = {"r_major": 0.3, "r_minor": 0.08, "radian": 1.5 * math.pi}
    mesh = primitive_mesh("Torus", params, resolution=48)
    mesh.apply_transform(random_pose(np.random.default_rng(5)))
    sigma = 2.0
    mass, com, inertia = shell_properties(mesh, sigma)
    pts, _ = trimesh.sample.sample_surface(mesh, 400_000, seed=6)
    pts = np.asarray(pts)
    d = pts - pts.mean(axis=0)
    mc = mass * ((d * d).sum(axis=1).mean() * np.eye(3) - d.T @ d / len(d))
    assert mass == pytest.approx(sigma * mesh.area, rel=1e-12)
    np.testing.assert_allclose(com, pts.mean(axis=0), atol=2e-3)
    np.testing.assert_allclose(inertia, mc, atol=0.01 * np.abs(mc).max())


@pytest.mark.parametrize("size", [0.03, 0.08, 0.107, 0.109, 0.3, 1.0])
def test_a_cube_weighs_the_lesser_of_solid_and_shell(size: float) -> None:
    """Solid below 6 walls (6 x 18 mm = 108 mm: volume a^3 < wall x area 6 a^2), shell above."""
    mesh = trimesh.creation.box(extents=[size] * 3)
    mass, com, inertia = mass_properties(mesh, DENSITY, WALL)
    solid, shell = DENSITY * size**3, DENSITY * WALL * 6 * size**2
    assert mass == pytest.approx(min(solid, shell), rel=1e-9)
    # about its centre a cube's inertia is isotropic: solid m a^2 / 6, a six-face shell 5 m a^2 / 18
    k = 1 / 6 if solid < shell else 5 / 18
    np.testing.assert_allclose(inertia, k * mass * size**2 * np.eye(3), atol=1e-12)
    np.testing.assert_allclose(com, 0, atol=1e-12)


def test_a_thin_wall_makes_every_solid_a_shell() -> None:
    """SunkenDoor's leaf at a 2 mm wall: density x wall x the analytic areas of its shapes."""
    inst = eac.load_library()["SunkenDoor"].instantiate()
    wall = 0.002
    model = build_model(inst, ExportOptions(density=700.0, wall=wall))
    leaf = next(link for link in model.links if link.source == "leaf")
    area = sum(surface_area(g.primitive, g.params) for g in leaf.geoms)
    assert leaf.inertial.mass == pytest.approx(700.0 * wall * area, rel=5e-3)


@pytest.fixture(scope="module")
def masses() -> dict[str, float]:
    """The total exported mass of every concept of the standard library at its defaults."""
    lib = eac.load_library()
    return {n: sum(k.inertial.mass for k in build_model(lib[n].instantiate()).links) for n in lib}


def test_heavy_concepts_weigh_what_furniture_and_appliances_do(masses) -> None:
    assert 30 < masses["Refrigerator"] < 150
    assert 15 < masses["ChestOfDrawers"] < 90
    for name in ("Dishwasher", "WashingMachine", "Oven", "HingedCabinet"):
        assert 10 < masses[name] < 120, (name, masses[name])


def test_small_concepts_stay_light(masses) -> None:
    small = [n for n in masses if n.endswith(("Handle", "Knob", "Pull", "Button", "Switch"))]
    assert len(small) >= 8
    for name in small:
        assert 0 < masses[name] < 1, (name, masses[name])
    assert max(masses.values()) < 150


def test_every_inertia_is_physical() -> None:
    """Positive principal moments obeying the triangle inequality (MuJoCo rejects others)."""
    lib = eac.load_library()
    for name in lib:
        for link in build_model(lib[name].instantiate()).links:
            moments = np.linalg.eigvalsh(link.inertial.inertia)
            assert moments.min() > 0, (name, link.name)
            assert moments[2] <= moments[0] + moments[1] + 1e-12, (name, link.name)
