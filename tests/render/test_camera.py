"""The framing camera: from the concept's front-right-above, every point inside the picture, and
no farther than needed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.render.camera import (
    AZIMUTH,
    ELEVATION,
    MARGIN,
    MIN_DISTANCE,
    NEAR,
    View,
    frame_points,
)
from tests.render.conftest import random_pose


def _ndc(view: View, pts: np.ndarray, aspect: float) -> np.ndarray:
    """Normalised image coordinates (-1..1 inside) of world points, by a pinhole projection."""
    right, up, back = view.basis()
    rel = pts - np.array(view.eye)
    depth = -(rel @ back)
    assert np.all(depth > 0), "a point behind the camera"
    ty = math.tan(math.radians(view.fovy) / 2)
    return np.stack([(rel @ right) / depth / (ty * aspect), (rel @ up) / depth / ty], axis=1)


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    n=st.integers(1, 50),
    spread=st.floats(1e-3, 10.0),
    aspect=st.floats(0.5, 2.5),
)
def test_every_point_fits_tightly(seed: int, n: int, spread: float, aspect: float) -> None:
    rng = np.random.default_rng(seed)
    pose = random_pose(rng)
    pts = pose[:3, 3] + spread * rng.normal(size=(n, 3)) * rng.uniform(0.1, 1, 3)
    view = frame_points(pts, pose[:3, :3], aspect)
    ndc = _ndc(view, pts, aspect)
    assert np.abs(ndc).max() <= 1 / MARGIN + 1e-9  # inside, with the margin
    nearest = float(((np.array(view.eye) - pts) @ view.basis()[2]).min())
    clearance = max(NEAR * float(np.linalg.norm(np.ptp(pts, axis=0))), MIN_DISTANCE)
    assert nearest >= clearance - 1e-9  # the camera stands outside the scene
    if n > 1 and nearest > clearance + 1e-9:  # not pushed back by the clearance: a tight fit
        k = int(np.argmax(np.abs(ndc).max(axis=0)))  # the axis that limits the framing...
        assert ndc[:, k].max() == pytest.approx(1 / MARGIN)  # ...is filled edge to edge
        assert ndc[:, k].min() == pytest.approx(-1 / MARGIN)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_view_from_front_right_above_in_the_concept_frame(seed: int) -> None:
    rng = np.random.default_rng(seed)
    pose = random_pose(rng)
    pts = pose[:3, 3] + rng.normal(size=(20, 3)) * 0.2
    view = frame_points(pts, pose[:3, :3], 4 / 3)
    back = np.subtract(view.eye, view.target) / view.distance
    local = pose[:3, :3].T @ back  # concept frame: +x right, +y up, +z front
    assert local[0] > 0 and local[1] > 0 and local[2] > 0
    assert abs(math.degrees(math.asin(local[1])) - ELEVATION) < 1e-6
    assert abs(math.degrees(math.atan2(local[0], local[2])) - AZIMUTH) < 1e-6
    up = np.array(view.up)
    assert abs(up @ back) < 1e-9 and (pose[:3, :3].T @ up)[1] > 0  # the concept's up is up
