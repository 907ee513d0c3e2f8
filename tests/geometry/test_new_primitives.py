"""TaperedCuboid, SphericalCap, Torus and Prism against independent computations: the primitives
they reduce to, Monte-Carlo volumes, mesh areas, closed-form sample statistics, and the
parameter derivatives the model fitting uses (CasADi vs finite differences of numpy)."""

from __future__ import annotations

import math
from functools import cache
from typing import Any

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.geometry import (
    PRIMITIVES,
    GeometryError,
    affordances,
    bounds,
    primitive_mesh,
    primitive_sdf,
    primitive_sdf_casadi,
    sample_surface,
    surface_area,
    volume,
)
from tests.geometry.strategies import params_for

NEW = ["TaperedCuboid", "SphericalCap", "Torus", "Prism"]
FAST = settings(derandomize=True, max_examples=8, deadline=None)


def _cloud(name: str, params: dict[str, Any], n: int, seed: int) -> np.ndarray:
    lo, hi = bounds(name, params)
    pad = 0.3 * (hi - lo) + 1e-3
    return np.random.default_rng(seed).uniform(lo - pad, hi + pad, (n, 3))


@FAST
@given(size=st.tuples(*[st.floats(0.005, 0.3)] * 3))
def test_untapered_box_is_the_cuboid(size: tuple[float, float, float]) -> None:
    params = {"size": size, "top": (size[0], size[2]), "offset": (0.0, 0.0)}
    pts = _cloud("Cuboid", {"size": size}, 2000, 0)
    np.testing.assert_allclose(
        primitive_sdf("TaperedCuboid", params, pts),
        primitive_sdf("Cuboid", {"size": size}, pts),
        atol=1e-12,
    )


def test_pyramid_and_wedge_have_their_apex_and_edge_on_the_surface() -> None:
    pyramid = {"size": (0.2, 0.1, 0.2), "top": (0.0, 0.0), "offset": (0.03, -0.02)}
    apex = np.array([[0.03, 0.05, -0.02]])
    assert abs(primitive_sdf("TaperedCuboid", pyramid, apex)[0]) < 1e-15
    # straight above the apex the nearest point is the apex itself
    np.testing.assert_allclose(
        primitive_sdf("TaperedCuboid", pyramid, apex + [0, 0.07, 0]), [0.07], atol=1e-15
    )
    wedge = {"size": (0.2, 0.1, 0.3), "top": (0.0, 0.3), "offset": (-0.1, 0.0)}  # a ramp
    assert math.isclose(volume("TaperedCuboid", wedge), 0.2 * 0.1 / 2 * 0.3)
    along_edge = np.array([[-0.1, 0.05, z] for z in (-0.15, 0.0, 0.15)])
    np.testing.assert_allclose(primitive_sdf("TaperedCuboid", wedge, along_edge), 0, atol=1e-15)


@FAST
@given(radius=st.floats(0.005, 0.3))
def test_whole_cap_is_the_sphere_and_half_cap_the_hemisphere(radius: float) -> None:
    pts = _cloud("Sphere", {"radius": radius}, 2000, 1)
    whole = {"radius": radius, "height": 2 * radius}
    np.testing.assert_allclose(
        primitive_sdf("SphericalCap", whole, pts),
        primitive_sdf("Sphere", {"radius": radius}, pts),
        atol=1e-12,
    )
    # a hemisphere is a cylinder sector's cousin: its frame puts the ball's centre at z = -r/2
    half = {"radius": radius, "height": radius}
    centre = np.array([0.0, 0.0, -radius / 2])
    rho = np.linalg.norm(pts[:, :2] - centre[:2], axis=1)
    z = pts[:, 2] - centre[2]
    # independent: above the plane the ball, below it the flat disk or its rim
    expect = np.where(
        z >= 0,
        np.linalg.norm(pts - centre, axis=1) - radius,
        np.where(rho <= radius, -z, np.hypot(rho - radius, z)),
    )
    inside = (np.linalg.norm(pts - centre, axis=1) < radius) & (z > 0)
    expect[inside] = np.maximum(np.linalg.norm(pts - centre, axis=1) - radius, -z)[inside]
    np.testing.assert_allclose(primitive_sdf("SphericalCap", half, pts), expect, atol=1e-12)


def test_square_prism_is_a_cuboid_and_many_sides_approach_the_cylinder() -> None:
    r, h = 0.05, 0.03
    pts = _cloud("Cylinder", {"radius": r, "height": h}, 3000, 2)
    square = {"size": (r * math.sqrt(2), r * math.sqrt(2), h)}
    np.testing.assert_allclose(
        primitive_sdf("Prism", {"sides": 4, "radius": r, "height": h}, pts),
        primitive_sdf("Cuboid", square, pts),
        atol=1e-12,
    )
    n = 256
    # the polygon is inscribed: the prism's distance is larger by at most the sag
    gap = primitive_sdf("Prism", {"sides": n, "radius": r, "height": h}, pts) - primitive_sdf(
        "Cylinder", {"radius": r, "height": h}, pts
    )
    assert np.all(gap >= -1e-12) and np.all(gap <= r * (1 - math.cos(math.pi / n)) + 1e-12)


def test_full_torus_agrees_with_its_segments_inside_their_wedge() -> None:
    full = {"r_major": 0.05, "r_minor": 0.01, "radian": 2 * math.pi}
    arc = {**full, "radian": math.pi}  # the half with y <= 0
    pts = _cloud("Torus", full, 3000, 3)
    lower = pts[:, 1] < -0.012  # farther from the cut planes than from the tube
    np.testing.assert_allclose(
        primitive_sdf("Torus", arc, pts[lower]), primitive_sdf("Torus", full, pts[lower])
    )
    # beyond a cut, the nearest point is on the end disk: a circle of radius r in the x=+-0 plane
    p = np.array([[0.08, 0.03, 0.0]])
    np.testing.assert_allclose(primitive_sdf("Torus", arc, p), [math.hypot(0.03, 0.08 - 0.06)])


@pytest.mark.parametrize("name", NEW)
@settings(derandomize=True, max_examples=3, deadline=None)
@given(data=st.data())
def test_monte_carlo_volume_of_the_sdf_matches_the_analytic_volume(name: str, data: Any) -> None:
    params = data.draw(params_for(name))
    lo, hi = bounds(name, params)
    n = 200_000
    pts = np.random.default_rng(4).uniform(lo, hi, (n, 3))
    fraction = np.mean(primitive_sdf(name, params, pts) < 0)
    box = float(np.prod(hi - lo))
    sigma = math.sqrt(fraction * (1 - fraction) / n) * box
    assert abs(fraction * box - volume(name, params)) < 5 * sigma + 1e-12


@pytest.mark.parametrize("name", NEW)
@FAST
@given(data=st.data())
def test_analytic_area_matches_the_fine_mesh(name: str, data: Any) -> None:
    params = data.draw(params_for(name))
    area = primitive_mesh(name, params, resolution=128).area
    assert abs(surface_area(name, params) / area - 1) < 2e-3


def test_torus_samples_follow_the_area_element() -> None:
    """Outer half of the tube (cos v > 0) holds (pi R + 2 r) / (2 pi R) of the area."""
    big, small = 0.05, 0.03
    pts, nrm = sample_surface("Torus", {"r_major": big, "r_minor": small}, 40_000, seed=5)
    rho = np.linalg.norm(pts[:, :2], axis=1)
    share = np.mean(rho > big)
    expect = (math.pi * big + 2 * small) / (2 * math.pi * big)
    assert abs(share - expect) < 4 * math.sqrt(expect * (1 - expect) / len(pts))


def test_cap_samples_split_between_dome_and_disk_by_area() -> None:
    r, h = 0.02, 0.008
    pts, nrm = sample_surface("SphericalCap", {"radius": r, "height": h}, 40_000, seed=6)
    disk = math.pi * h * (2 * r - h)
    share, expect = np.mean(nrm[:, 2] == -1.0), disk / (disk + 2 * math.pi * r * h)
    assert abs(share - expect) < 4 * math.sqrt(expect * (1 - expect) / len(pts))
    # Archimedes: the dome's samples are uniform in z
    z = pts[nrm[:, 2] != -1.0, 2]
    counts, _ = np.histogram(z, bins=8, range=(-h / 2, h / 2))
    assert counts.max() / counts.min() < 1.1


@pytest.mark.parametrize(
    ("sides", "width"),
    [(3, 1.5), (4, math.sqrt(2)), (5, 1 + math.cos(math.pi / 5)), (6, math.sqrt(3)), (8, None)],
)
def test_prism_is_grasped_across_flats_or_face_to_corner(sides: int, width: float | None) -> None:
    aff = affordances("Prism", {"sides": sides, "radius": 1.0, "height": 0.5})
    expect = 2 * math.cos(math.pi / sides) if width is None else width
    assert math.isclose(aff["graspable_width"], expect)
    np.testing.assert_array_equal(aff["principal_axis"], [0, 0, 1])


def test_prism_stands_on_a_face_and_shares_the_polygon_with_its_mesh() -> None:
    for sides in (3, 5, 6, 7):
        lo, _ = bounds("Prism", {"sides": sides, "radius": 1.0, "height": 1.0})
        assert math.isclose(lo[1], -math.cos(math.pi / sides))  # an edge's middle on -y
        mesh = primitive_mesh("Prism", {"sides": sides, "radius": 1.0, "height": 1.0})
        assert math.isclose(
            mesh.volume, volume("Prism", {"sides": sides, "radius": 1.0, "height": 1.0})
        )


def test_torus_affordances_are_the_tube_and_its_middle_tangent() -> None:
    aff = affordances("Torus", {"r_major": 0.05, "r_minor": 0.006, "radian": 2.0})
    assert aff["graspable_width"] == 0.012
    np.testing.assert_array_equal(aff["principal_axis"], [1, 0, 0])


@cache
def _jacobian(name: str) -> tuple[ca.Function, list[str]]:
    spec = PRIMITIVES[name]
    syms = {ps.name: ca.SX.sym(ps.name, ps.size) for ps in spec.params}
    p = ca.SX.sym("p", 3)
    expr = primitive_sdf_casadi(name, syms, p)
    jac = ca.jacobian(expr, ca.vertcat(*syms.values()))
    return ca.Function("dsdf", [p, *syms.values()], [jac]), list(syms)


@pytest.mark.parametrize("name", NEW)
@settings(derandomize=True, max_examples=4, deadline=None)
@given(data=st.data())
def test_parameter_derivatives_match_finite_differences(name: str, data: Any) -> None:
    """d sdf / d params from CasADi against central differences of the numpy sdf (lengths and
    angles; ``sides`` is a whole number, so it is skipped)."""
    params = data.draw(params_for(name))
    fn, order = _jacobian(name)
    pts = _cloud(name, params, 40, 7)
    flat = [(k, i) for k in order for i in range(np.size(params[k]))]
    args = [np.atleast_1d(np.asarray(params[k], float)) for k in order]
    got = np.vstack([np.asarray(fn(x, *args)).ravel() for x in pts])
    for col, (k, i) in enumerate(flat):
        if PRIMITIVES[name].params[order.index(k)].kind == "int":
            continue
        step = 1e-7
        cols = []
        for sign in (1, -1):
            value = np.array(params[k], dtype=float).reshape(-1)
            value[i] += sign * step
            moved = {**params, k: tuple(value) if value.size > 1 else float(value[0])}
            try:
                cols.append(primitive_sdf(name, moved, pts))
            except GeometryError:  # on the edge of validity (a pyramid's top, a whole ball)
                break
        if len(cols) < 2:
            continue
        fd = (cols[0] - cols[1]) / (2 * step)
        close = np.abs(fd - got[:, col]) < 1e-5 * (1 + np.abs(fd))
        assert np.mean(close) >= 0.95, (k, i, fd[~close], got[~close, col])
