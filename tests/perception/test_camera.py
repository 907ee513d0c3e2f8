"""The camera: poses, rays and back-projection against independent computations, noise."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.perception.camera import (
    DEFAULT_INTRINSICS,
    DepthNoise,
    back_project,
    look_at,
    project,
    to_world,
)
from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.render import render
from grace_dsl.perception.types import Intrinsics

K = DEFAULT_INTRINSICS


def test_look_at_points_the_optical_axis_at_the_target_with_the_image_up_world_up() -> None:
    eye, target = np.array([0.3, 0.8, 1.2]), np.array([0.0, 0.1, 0.0])
    pose = look_at(eye, target)
    r = pose[:3, :3]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    forward = (target - eye) / np.linalg.norm(target - eye)
    np.testing.assert_allclose(r[:, 2], forward, atol=1e-12)
    assert r[:, 1] @ np.array([0.0, 1.0, 0.0]) < 0  # image +y (down) points away from up
    assert abs(r[:, 0] @ np.array([0.0, 1.0, 0.0])) < 1e-12  # no roll
    with pytest.raises(PerceptionError):
        look_at(eye, eye)


def test_back_project_matches_the_inverse_intrinsic_matrix() -> None:
    rng = np.random.default_rng(0)
    depth = rng.uniform(0.3, 2.0, (K.height, K.width))
    depth[rng.random(depth.shape) < 0.3] = 0.0
    pts = back_project(depth, K)
    kinv = np.linalg.inv(np.array([[K.fx, 0, K.cx], [0, K.fy, K.cy], [0, 0, 1.0]]))
    expected = [
        depth[v, u] * (kinv @ np.array([u, v, 1.0]))
        for v in range(K.height)
        for u in range(K.width)
        if depth[v, u] > 0
    ]
    np.testing.assert_allclose(pts, np.array(expected), rtol=1e-12, atol=1e-12)
    uv = project(K, pts)
    v, u = np.nonzero(depth > 0)
    np.testing.assert_allclose(uv, np.stack([u, v], 1), atol=1e-9)
    with pytest.raises(PerceptionError, match="intrinsics"):
        back_project(depth[:-1], K)


def test_rendered_cuboid_face_back_projects_onto_the_plane_and_into_its_outline(lib) -> None:
    """A cube seen head-on from 1 m: every pixel's depth is the distance to its front face
    (a plane at z = +s/2), and the pixels are those whose rays meet the face's square."""
    s = 0.2
    inst = lib["Cuboid"].instantiate(size=(s, s, s))
    small = Intrinsics(fx=200.0, fy=200.0, cx=39.5, cy=29.5, width=80, height=60)
    camera = look_at(np.array([0.0, 0.0, 1.0]), np.zeros(3))
    shot = render(inst, camera, small)
    seen = shot.depth > 0
    np.testing.assert_allclose(shot.depth[seen], 1.0 - s / 2, atol=2e-4)
    world = to_world(back_project(shot.depth, small), camera)
    np.testing.assert_allclose(world[:, 2], s / 2, atol=2e-4)
    assert np.all(np.abs(world[:, :2]) <= s / 2 + 1e-3)
    # independent: a pixel sees the face iff its ray's hit on the plane lies in the square
    u, v = np.meshgrid(np.arange(80.0), np.arange(60.0))
    x = (u - small.cx) / small.fx * (1 - s / 2)
    y = (v - small.cy) / small.fy * (1 - s / 2)
    inside = (np.abs(x) < s / 2 - 1e-3) & (np.abs(y) < s / 2 - 1e-3)
    outside = (np.abs(x) > s / 2 + 1e-3) | (np.abs(y) > s / 2 + 1e-3)
    assert seen[inside].all() and not seen[outside].any()
    assert set(np.unique(shot.labels[seen])) == {0}


def test_noise_has_its_sigma_dropout_and_flies_only_at_edges() -> None:
    rng = np.random.default_rng(1)
    depth = np.zeros((100, 100))
    depth[20:80, 20:80] = 1.0
    noisy = DepthNoise(sigma=0.002).apply(depth, rng)
    assert np.std(noisy[20:80, 20:80] - 1.0) == pytest.approx(0.002, rel=0.05)
    assert not noisy[depth == 0].any()
    dropped = DepthNoise(sigma=0.0, dropout=0.25).apply(depth, rng)
    assert (dropped[20:80, 20:80] == 0).mean() == pytest.approx(0.25, abs=0.03)
    flying = DepthNoise(sigma=0.0, flying=1.0).apply(depth, rng)
    moved = flying != depth
    assert moved.any() and not moved[22:78, 22:78].any()  # only the square's rim moves
    assert np.all(flying[moved] > 1.0)
