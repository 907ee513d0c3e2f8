"""Where the camera stands: front-right-above the instance, by the concept convention.

A concept's +z is out of its front and +y is up, so the view direction is fixed in the concept
frame (rotated by the instance pose) and the distance is the smallest at which every point of the
scene fits the field of view, with a margin. Both renderers start from the same :class:`View`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from grace_dsl.render.scene import Scene, Vec3

AZIMUTH = 35.0  # degrees to the right of straight ahead (+x of the concept)
ELEVATION = 25.0  # degrees above (+y)
FOVY = 35.0  # vertical field of view, degrees
MARGIN = 1.08  # the outermost point is 1/MARGIN of the way from the centre to the edge
MIN_DISTANCE = 1e-3  # metres: a single point is still seen from somewhere
NEAR = 0.25  # no point nearer to the camera than this fraction of the scene's diagonal


@dataclass(frozen=True)
class View:
    """A pinhole camera: world eye and target points, the image's up direction, vertical field
    of view in degrees."""

    eye: Vec3
    target: Vec3
    up: Vec3
    fovy: float

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """right, up, back (unit; back points from the target to the eye)."""
        back = np.subtract(self.eye, self.target)
        back = back / np.linalg.norm(back)
        right = np.cross(self.up, back)
        right = right / np.linalg.norm(right)
        return right, np.cross(back, right), back

    @property
    def distance(self) -> float:
        return float(np.linalg.norm(np.subtract(self.eye, self.target)))


def view_direction(rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unit direction from the object to the eye, and the up direction, in the world."""
    az, el = math.radians(AZIMUTH), math.radians(ELEVATION)
    local = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
    return rotation @ local, rotation @ np.array([0.0, 1.0, 0.0])


def frame_scene(scene: Scene, aspect: float, fovy: float = FOVY, margin: float = MARGIN) -> View:
    """The front-right-above view that frames every mesh point and decoration of ``scene``."""
    segs = scene.segments()
    pts = np.concatenate(
        [
            scene.mesh_points(),
            np.array([s.start for s in segs] + [s.end for s in segs]).reshape(-1, 3),
        ]
    )
    if len(pts) == 0:
        pts = np.zeros((1, 3))
    return frame_points(pts, scene.pose[:3, :3], aspect, fovy, margin)


def frame_points(
    pts: np.ndarray, rotation: np.ndarray, aspect: float, fovy: float = FOVY, margin: float = MARGIN
) -> View:
    """The view along :func:`view_direction` in which ``pts`` just fit, within ``1 / margin``
    of the centre-to-edge distance."""
    back, up0 = view_direction(rotation)
    right = np.cross(up0, back)
    right /= np.linalg.norm(right)
    up = np.cross(back, right)
    ty = math.tan(math.radians(fovy) / 2) / margin  # the margin narrows the usable field
    tx = ty * aspect
    origin = (pts.min(axis=0) + pts.max(axis=0)) / 2
    rel = pts - origin
    a = rel @ back  # how far each point stands out towards the camera
    sx, dx = _fit_axis(rel @ right, a, tx)
    sy, dy = _fit_axis(rel @ up, a, ty)
    clearance = max(NEAR * float(np.linalg.norm(np.ptp(pts, axis=0))), MIN_DISTANCE)
    dist = max(dx, dy, float(a.max()) + clearance)  # never inside the scene
    target = origin + sx * right + sy * up
    eye = target + dist * back
    return View(_v(eye), _v(target), _v(up), fovy)


def _fit_axis(x: np.ndarray, a: np.ndarray, t: float) -> tuple[float, float]:
    """The sideways shift s of the camera and the least distance D with every point inside
    ``|x_i - s| <= t (D - a_i)`` (x across the image, a towards the camera; a linear program
    in s and D, solved in closed form): the extremes then touch both edges symmetrically."""
    hi, lo = float(np.max(x + t * a)), float(np.min(x - t * a))
    return (hi + lo) / 2, (hi - lo) / (2 * t)


def _v(a: np.ndarray) -> Vec3:
    return (float(a[0]), float(a[1]), float(a[2]))
