"""A picture of a fitted instance over the points it was fitted to (PNG, no GUI needed).

The fitted instance is sphere-traced (``perception.render``) from the camera that saw the points
(the origin of their frame, or ``camera``), shaded by its surface's slope, and the points are
drawn over it in red, each pixel's nearest point in front: what a person checks a fit by.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from grace_dsl.perception.camera import look_at, project
from grace_dsl.perception.render import render
from grace_dsl.perception.types import Intrinsics
from grace_dsl.runtime.instance import Instance

POINT = np.array([220, 40, 40], dtype=np.uint8)


def _framing(points: np.ndarray, size: int) -> Intrinsics:
    """Intrinsics that fit the points' projection in a square image with a margin."""
    uv = points[:, :2] / points[:, 2:3]
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    f = 0.7 * size / max(float((hi - lo).max()), 1e-6)
    c = (lo + hi) / 2
    return Intrinsics(f, f, size / 2 - f * c[0], size / 2 - f * c[1], size, size)


def fit_picture(inst: Instance, points: np.ndarray, path: str | Path, size: int = 480) -> Path:
    """Write ``path`` (PNG): ``inst`` (posed in the points' frame, the camera at its origin)
    in grey, the points in red."""
    from PIL import Image

    pts = np.asarray(points, float)
    pts = pts[pts[:, 2] > 1e-6]
    intr = _framing(pts, size)
    camera = look_at(np.zeros(3), np.array([0.0, 0.0, 1.0]), up=np.array([0.0, -1.0, 0.0]))
    shot = render(inst, camera, intr)
    depth = shot.depth
    gy, gx = np.gradient(np.where(depth > 0, depth, np.nan))
    slope = np.nan_to_num(np.sqrt(gx**2 + gy**2) / np.maximum(depth, 1e-6) * intr.fx, nan=0.0)
    shade = np.clip(200 - 60 * np.tanh(slope), 60, 230)
    image = np.full((size, size, 3), 255, dtype=np.uint8)
    seen = depth > 0
    image[seen] = shade[seen, None].astype(np.uint8)
    uv = np.round(project(intr, pts)).astype(int)
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < size) & (uv[:, 1] >= 0) & (uv[:, 1] < size)
    for du in (0, 1):
        for dv in (0, 1):
            u = np.clip(uv[ok, 0] + du, 0, size - 1)
            v = np.clip(uv[ok, 1] + dv, 0, size - 1)
            image[v, u] = POINT
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(image, "RGB").save(target, format="PNG", optimize=True)
    return target
