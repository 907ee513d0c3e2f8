"""The winding-number containment the geometry tests use as their independent check."""

from __future__ import annotations

import numpy as np
import trimesh

from tests.meshes import inside, winding_numbers


def test_winding_number_is_one_inside_and_zero_outside_a_box() -> None:
    box = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    pts = np.random.default_rng(0).uniform(-1.5, 1.5, (500, 3))
    truth = np.all(np.abs(pts) < [1.0, 0.5, 0.25], axis=1)
    w = winding_numbers(box, pts)
    assert np.allclose(w[truth], 1.0) and np.allclose(w[~truth], 0.0, atol=1e-9)
    assert np.array_equal(inside(box, pts), truth)


def test_an_inverted_mesh_winds_minus_one_and_two_shells_add() -> None:
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    flipped = box.copy()
    flipped.invert()
    centre = np.zeros((1, 3))
    assert np.allclose(winding_numbers(flipped, centre), -1.0)
    both = trimesh.util.concatenate([box, box.copy()])
    assert np.allclose(winding_numbers(both, centre), 2.0)


def test_a_sphere_in_chunks_agrees_with_the_radius() -> None:
    ball = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    pts = np.random.default_rng(1).uniform(-1.2, 1.2, (600, 3))
    r = np.linalg.norm(pts, axis=1)
    clear = np.abs(r - 1.0) > 0.02  # the icosphere's chords lie within ~1 % of the radius
    assert np.array_equal(inside(ball, pts[clear]), r[clear] < 1.0)
