"""The silhouette as a render-and-compare term: rays just outside the cloud's outline saw
nothing, so the fitted surface must not reach them at any depth.

Free-space samples at fixed depths rarely land in the sliver a view barely shows (a cabinet's
bottom edge seen from above is a few pixels wide), so a fit too tall by those pixels paid
nothing. Here each outline ray is searched along its length, at the current estimate, for the
depth where the surface comes nearest; that one point per ray joins the free-space points (the
distance there must not be negative). Its depth is held while a step is solved (the envelope
theorem: the minimum's gradient is the gradient at the minimizer) and searched again after
every accepted step, so the term follows the fit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import binary_dilation
from scipy.spatial import cKDTree

INNER = 2  # spacings off the outline where the seen-through band starts (a dropped pixel: 1)
OUTER = 8  # spacings: where it ends
RAYS = 256
DEPTHS = 24  # coarse samples along a ray, then as many again within one step of the nearest
SPACING_SAMPLE = 1000  # points whose neighbour distance gives the rays' typical spacing


@dataclass(frozen=True)
class Outline:
    """Rays from ``origin`` along ``dirs`` (R, 3, unit) that met nothing, to be searched
    between ``near`` and ``far`` (m along the ray)."""

    origin: np.ndarray
    dirs: np.ndarray
    near: float
    far: float


def outline_rays(
    points: np.ndarray, camera: np.ndarray, seed: int = 0, n_rays: int = RAYS
) -> Outline | None:
    """The rays in a band ``INNER``-``OUTER`` spacings outside the cloud's outline (and in its
    holes that wide), read off the rays' gnomonic projection rasterized at their spacing (no
    intrinsics needed). None when the cloud is too small or spans too wide a view."""
    if len(points) < 16:
        return None
    rays = points - camera
    dist = np.linalg.norm(rays, axis=1)
    unit = rays / np.maximum(dist, 1e-9)[:, None]
    c = unit.mean(axis=0)
    c /= np.linalg.norm(c)
    cos = unit @ c
    if np.any(cos < 0.2):
        return None
    e1 = np.cross(c, [0.0, 1.0, 0.0] if abs(c[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    a = np.stack([unit @ e1 / cos, unit @ e2 / cos], axis=1)
    rng = np.random.default_rng(seed)
    some = a[rng.choice(len(a), min(SPACING_SAMPLE, len(a)), replace=False)]
    spacing = float(np.median(cKDTree(a).query(some, k=2)[0][:, 1]))
    if spacing <= 0:
        return None
    pad = OUTER + 2
    lo = a.min(axis=0) - pad * spacing
    cells = np.floor((a - lo) / spacing).astype(int)
    shape = tuple(cells.max(axis=0) + pad + 1)
    if shape[0] * shape[1] > 4_000_000:  # a sparse cloud: no outline at its spacing
        return None
    occ = np.zeros(shape, bool)
    occ[cells[:, 0], cells[:, 1]] = True
    band = binary_dilation(occ, iterations=OUTER) & ~binary_dilation(occ, iterations=INNER)
    free = np.argwhere(band)
    if len(free) == 0:
        return None
    if len(free) > n_rays:
        free = free[rng.choice(len(free), n_rays, replace=False)]
    uv = lo + (free + 0.5) * spacing
    dirs = c + uv[:, :1] * e1 + uv[:, 1:] * e2
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    extent = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    near = max(float(dist.min()) - 0.3 * extent, 0.0)
    return Outline(np.asarray(camera, float), dirs, near, float(dist.max()) + 0.3 * extent)


def nearest_points(
    outline: Outline, distance: Callable[[np.ndarray], np.ndarray], depths: int = DEPTHS
) -> np.ndarray:
    """Per ray, the point (world frame) where ``distance`` (world points -> signed distance of
    the current estimate) is least: a coarse search along the ray, then a finer one within a
    step of the coarse minimum."""
    r = len(outline.dirs)
    ts = np.linspace(outline.near, outline.far, depths)
    step = ts[1] - ts[0]
    best = _argmin_along(outline, distance, np.broadcast_to(ts, (r, depths)))
    fine = best[:, None] + np.linspace(-step, step, depths)[None, :]
    t = _argmin_along(outline, distance, fine)
    return outline.origin + t[:, None] * outline.dirs


def _argmin_along(
    outline: Outline, distance: Callable[[np.ndarray], np.ndarray], ts: np.ndarray
) -> np.ndarray:
    pts = outline.origin + ts[:, :, None] * outline.dirs[:, None, :]
    d = distance(pts.reshape(-1, 3)).reshape(ts.shape)
    return ts[np.arange(len(ts)), d.argmin(axis=1)]
