"""Depth and per-link segmentation of an instance by sphere tracing its exact signed distance.

Why sphere tracing rather than MuJoCo or a z-buffer of surface samples: the library's distances
are exact outside a union and a lower bound inside a difference, which is all sphere tracing
needs, so every pixel lands on the concept's true surface (no tessellation, no holes between
splats), the segmentation is the link of the nearest shape at the hit, and nothing beyond numpy
is needed in a data-generation worker. Rays are only traced where they meet the instance's
bounding sphere, so the cost follows the object's size in the image (``docs/benchmarks.md``,
"Perception", gives the measured time per view).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from grace_dsl.perception.camera import pixel_grid, rays
from grace_dsl.perception.types import Intrinsics
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.shapes import ShapeTree

HIT = 1e-4  # m: a ray whose distance falls below this has reached the surface
MAX_STEPS = 160  # grazing rays converge slowly; past this a ray within NEAR counts as a hit
NEAR = 1e-3


@dataclass(frozen=True)
class DepthRender:
    """A rendered view: depth (H, W) in metres (0: nothing), ``labels`` (H, W) the index in
    ``links`` of the link seen at each pixel (-1: nothing)."""

    depth: np.ndarray
    labels: np.ndarray
    links: tuple[str, ...]
    camera_pose: np.ndarray
    intrinsics: Intrinsics
    shape_labels: np.ndarray | None = None  # (H, W) index in ``shapes`` (-1: nothing)
    shapes: tuple[str, ...] = ()  # the outermost shapes (``handle.bar``: part handle)

    def mask(self, links: Iterable[str] | None = None) -> np.ndarray:
        """Pixels that see any of ``links`` (every link of the instance when None)."""
        if links is None:
            return self.labels >= 0
        wanted = [i for i, n in enumerate(self.links) if n in set(links)]
        return np.isin(self.labels, wanted)


class InstanceSDF:
    """The instance's signed distance in the world, shape by shape, with each shape's link: the
    shapes and link motions are evaluated once, then every call only moves points."""

    def __init__(self, inst: Instance):
        self.tree = ShapeTree(inst)
        kin = Kinematics.of(inst)
        self.links = tuple(inst.links)
        index = {n: i for i, n in enumerate(self.links)}
        self.shapes: list[tuple[str, np.ndarray, int]] = []
        for name in self.tree.outermost():
            link = self.tree.shapes[name]["link"]
            motion = kin.link_pose(link) @ np.linalg.inv(self.tree.link_pose(link))
            self.shapes.append((name, motion @ self.tree.placement(name), index[link]))

    def per_shape(self, points: np.ndarray) -> np.ndarray:
        """(S, N) distances of world points to each outermost shape."""
        return np.stack([self.tree.sdf(n, place, points) for n, place, _ in self.shapes])

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.per_shape(points).min(axis=0)

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index of the nearest shape at each point, and of its link in ``links``."""
        owners = np.array([k for _, _, k in self.shapes])
        shape = self.per_shape(points).argmin(axis=0)
        return shape, owners[shape]

    @property
    def shape_names(self) -> tuple[str, ...]:
        return tuple(n for n, _, _ in self.shapes)


def bounding_sphere(inst: Instance, margin: float = 0.01) -> tuple[np.ndarray, float]:
    """Centre and radius of a sphere holding the instance (from its surface samples)."""
    pts = inst.sample_surface(2000, seed=0)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2
    return centre, float(np.linalg.norm(pts - centre, axis=1).max()) + margin


def render(
    inst: Instance,
    camera_pose: np.ndarray,
    intr: Intrinsics,
    sdf: InstanceSDF | None = None,
    sphere: tuple[np.ndarray, float] | None = None,
) -> DepthRender:
    """Depth and link labels of ``inst`` seen from ``camera_pose`` (world <- camera)."""
    sdf = InstanceSDF(inst) if sdf is None else sdf
    centre, radius = bounding_sphere(inst) if sphere is None else sphere
    u, v = pixel_grid(intr)
    dirs_cam = rays(intr, u, v).reshape(-1, 3)
    rot, eye = camera_pose[:3, :3], camera_pose[:3, 3]
    dirs = dirs_cam @ rot.T
    # ray-sphere: |eye + t d - c|^2 = r^2
    oc = eye - centre
    b = dirs @ oc
    disc = b * b - (oc @ oc - radius * radius)
    idx = np.nonzero(disc > 0)[0]
    root = np.sqrt(disc[idx])
    t = np.maximum(-b[idx] - root, 0.0)
    t_exit = -b[idx] + root
    depth = np.zeros(len(dirs))
    labels = np.full(len(dirs), -1, dtype=np.int16)
    shapes = np.full(len(dirs), -1, dtype=np.int16)
    hit_idx, hit_t = _march(sdf, eye, dirs, idx, t, t_exit)
    if len(hit_idx):
        depth[hit_idx] = hit_t * dirs_cam[hit_idx, 2]
        points = eye + hit_t[:, None] * dirs[hit_idx]
        shapes[hit_idx], labels[hit_idx] = sdf.nearest(points)
    hw = (intr.height, intr.width)
    return DepthRender(
        depth.reshape(hw),
        labels.reshape(hw),
        sdf.links,
        camera_pose,
        intr,
        shapes.reshape(hw),
        sdf.shape_names,
    )


def _march(
    sdf: InstanceSDF,
    eye: np.ndarray,
    dirs: np.ndarray,
    idx: np.ndarray,
    t: np.ndarray,
    t_exit: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Sphere-trace the rays ``idx`` from ``t`` until they hit or leave at ``t_exit``."""
    hits_i: list[np.ndarray] = []
    hits_t: list[np.ndarray] = []
    d = np.full(len(idx), np.inf)
    for _ in range(MAX_STEPS):
        if not len(idx):
            break
        d = sdf(eye + t[:, None] * dirs[idx])
        hit = d < HIT
        hits_i.append(idx[hit])
        hits_t.append(t[hit])
        t = t + np.maximum(d, 0.0)
        keep = ~hit & (t < t_exit)
        idx, t, t_exit, d = idx[keep], t[keep], t_exit[keep], d[keep]
    near = d < NEAR
    hits_i.append(idx[near])
    hits_t.append(t[near])
    return np.concatenate(hits_i), np.concatenate(hits_t)
