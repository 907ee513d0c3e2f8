"""A pinhole RGB-D camera: where it looks, pixel rays, back-projection and depth noise.

Frames follow ``perception.types``: the camera frame is OpenCV's (+z forward, +x right, +y
down), the world's +y is up (a concept's +y is up, §6), and ``camera_pose`` is the camera in the
world (``p_world = camera_pose @ p_camera``). A depth image holds the z coordinate of the
surface in the camera frame (metres) and 0 where the camera saw nothing, as real RGB-D sensors
report it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from grace_dsl.perception.errors import PerceptionError
from grace_dsl.perception.types import Intrinsics

#: A RealSense-like depth camera at a quarter of its 1280x960 resolution: 58 deg across.
DEFAULT_INTRINSICS = Intrinsics(fx=290.0, fy=290.0, cx=159.5, cy=119.5, width=320, height=240)
WORLD_UP = np.array([0.0, 1.0, 0.0])


def fov_half(intr: Intrinsics) -> float:
    """Half the smaller field of view (rad): what an object must fit in to be seen whole."""
    return min(math.atan(intr.width / (2 * intr.fx)), math.atan(intr.height / (2 * intr.fy)))


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = WORLD_UP) -> np.ndarray:
    """The camera pose (world <- camera, OpenCV axes) at ``eye`` looking at ``target``, with the
    image's up (-y) as close to ``up`` as the view direction allows."""
    eye, target = np.asarray(eye, float), np.asarray(target, float)
    z = target - eye
    norm = float(np.linalg.norm(z))
    if not norm > 0:
        raise PerceptionError("the camera's eye and target coincide: no view direction")
    z /= norm
    x = np.cross(z, np.asarray(up, float))  # right = forward x up, so that y (down) = -up
    if np.linalg.norm(x) < 1e-9:  # looking straight along up: any right direction will do
        x = np.cross(z, np.array([0.0, 0.0, 1.0]))
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = x, y, z, eye
    return pose


def pixel_grid(intr: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) pixel coordinates (H, W) of the pixel centres: u along x, v along y."""
    return np.meshgrid(np.arange(intr.width, dtype=float), np.arange(intr.height, dtype=float))


def rays(intr: Intrinsics, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit ray directions (..., 3) in the camera frame through pixels (u, v)."""
    d = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones_like(u)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def project(intr: Intrinsics, points: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) of camera-frame points (N, 3) in front of the camera."""
    p = np.asarray(points, float)
    return np.stack(
        [intr.fx * p[:, 0] / p[:, 2] + intr.cx, intr.fy * p[:, 1] / p[:, 2] + intr.cy], 1
    )


def back_project(depth: np.ndarray, intr: Intrinsics, mask: np.ndarray | None = None) -> np.ndarray:
    """Camera-frame points (N, 3) of the pixels with depth > 0 (inside ``mask`` if given), in
    row-major pixel order: x = (u - cx) z / fx, y = (v - cy) z / fy."""
    depth = np.asarray(depth, float)
    if depth.shape != (intr.height, intr.width):
        raise PerceptionError(
            f"depth is {depth.shape}, the intrinsics say {(intr.height, intr.width)} (H, W)"
        )
    keep = depth > 0
    if mask is not None:
        keep &= np.asarray(mask, bool)
    v, u = np.nonzero(keep)
    z = depth[v, u]
    return np.stack([(u - intr.cx) * z / intr.fx, (v - intr.cy) * z / intr.fy, z], axis=1)


def to_world(points: np.ndarray, camera_pose: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) in the world."""
    pose = np.asarray(camera_pose, float)
    return np.asarray(points, float) @ pose[:3, :3].T + pose[:3, 3]


@dataclass(frozen=True)
class DepthNoise:
    """A depth sensor's errors: Gaussian noise on z (``sigma``, m), pixels that return nothing
    (``dropout``, a fraction) and flying pixels, which mix foreground and background where the
    depth jumps by more than ``edge`` (m) between neighbours (a ``flying`` fraction of those
    edge pixels take a depth between the two). Why these three: they are what a fit on real
    RGB-D clouds must survive, and each one breaks a naive estimator differently."""

    sigma: float = 0.002
    dropout: float = 0.0
    flying: float = 0.0
    edge: float = 0.02

    def apply(self, depth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A noisy copy of ``depth`` (0 = no return stays 0)."""
        out = np.asarray(depth, float).copy()
        seen = out > 0
        if self.flying > 0:
            out = _flying_pixels(out, self.flying, self.edge, rng)
            seen = out > 0
        if self.sigma > 0:
            out[seen] += rng.normal(0.0, self.sigma, int(seen.sum()))
        if self.dropout > 0:
            out[seen & (rng.random(out.shape) < self.dropout)] = 0.0
        return np.where(out > 0, out, 0.0)


def _flying_pixels(
    depth: np.ndarray, share: float, edge: float, rng: np.random.Generator
) -> np.ndarray:
    """Pixels beside a depth jump (or beside empty space) moved to a random depth between their
    own and their farthest neighbour's, as a sensor averaging over the edge reports them."""
    pad = np.pad(depth, 1, mode="edge")
    h, w = depth.shape
    neighbours = np.stack(
        [
            pad[1 + dv : 1 + dv + h, 1 + du : 1 + du + w]
            for dv, du in ((-1, 0), (1, 0), (0, -1), (0, 1))
        ]
    )
    far = np.where(neighbours > 0, neighbours, depth + 4 * edge).max(axis=0)
    jump = (depth > 0) & (far - depth > edge)
    pick = jump & (rng.random(depth.shape) < share)
    out = depth.copy()
    t = rng.random(int(pick.sum()))
    out[pick] = depth[pick] + t * (far[pick] - depth[pick])
    return out
