"""The convex collision pieces: each lies inside its solid and together they fill it (up to the
chords of curved faces), so a simulator that collides convex hulls sees the real shape."""

from __future__ import annotations

import math

import numpy as np
import pytest

from grace_dsl.geometry import convex_pieces, primitive_mesh, primitive_sdf, volume
from grace_dsl.geometry.pieces import carve_boxes

CASES = [
    ("Tube", {}),
    ("Tube", {"r_in": 0.049, "r_out": 0.05}),  # a thin wall needs more segments
    ("Ring", {}),
    ("Ring", {"radian": 2 * math.pi}),
    ("Cylinder", {"radian": math.radians(270)}),
    ("Torus", {"radian": 2 * math.pi}),
    ("RectRing", {}),
    ("BoardBox", {"front": True}),
]


@pytest.mark.parametrize(("name", "params"), CASES)
def test_pieces_are_convex_inside_the_solid_and_fill_it(name, params) -> None:
    pieces = convex_pieces(name, params)
    assert pieces is not None and len(pieces) >= 2
    total = 0.0
    for c in pieces:
        mesh = primitive_mesh(c.primitive, c.params, 64).apply_transform(c.pose)
        assert mesh.is_convex, c.name
        # a torus's capsules bulge past the chord by at most a fifth of the tube's radius
        slack = 0.2 * params.get("r_minor", 0.005) if name == "Torus" else 1e-9
        assert primitive_sdf(name, params, np.asarray(mesh.vertices)).max() <= slack
        total += mesh.volume
    assert total >= 0.85 * volume(name, params)  # thin walls: WALL of their thickness


def test_convex_primitives_need_no_split() -> None:
    for name in ("Cuboid", "Sphere", "Capsule", "Frustum", "TaperedCuboid", "Prism"):
        assert convex_pieces(name, {}) is None
    assert convex_pieces("Cylinder", {"radian": math.pi}) is None


def test_a_box_minus_a_recess_is_carved_into_disjoint_boxes() -> None:
    recess = np.eye(4)
    recess[:3, 3] = (0.1, 0.0, 0.24)  # 30 mm deep into the front face at z = 0.25 (clipped)
    blocks = carve_boxes((0.6, 0.4, 0.5), [(recess, (0.1, 0.2, 0.04))])
    assert blocks is not None
    vol = sum(float(np.prod(b.params["size"])) for b in blocks)
    assert vol == pytest.approx(0.6 * 0.4 * 0.5 - 0.1 * 0.2 * 0.03, rel=1e-12)
    centres = np.array([b.pose[:3, 3] for b in blocks])
    assert np.all(np.abs(centres - recess[:3, 3]).max(axis=1) > 0)  # none inside the recess
    turned = recess.copy()
    turned[:3, :3] = [
        [math.cos(0.3), -math.sin(0.3), 0],
        [math.sin(0.3), math.cos(0.3), 0],
        [0, 0, 1],
    ]
    assert carve_boxes((0.6, 0.4, 0.5), [(turned, (0.1, 0.2, 0.04))]) is None
