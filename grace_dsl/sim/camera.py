"""A seeded RGB-D camera on the upper hemisphere around a target, and depth back-projection.

The protocol of the paper's appendix B: azimuth uniform in [0, 360) degrees, elevation uniform
in [30, 60] degrees, at a given distance from the object. Azimuth is measured in the world's
xy plane from +x towards +y, elevation up from that plane (z-up world, ``sim.model``).

Frames: the camera frame is MuJoCo's (x right, y up, looking along -z); a depth image holds the
distance along the viewing axis in metres (0 where nothing was hit). ``back_project`` turns it
into points in the camera frame and, with the camera's pose, in the world frame.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from grace_dsl.runtime.errors import GraceError

AZIMUTH = (0.0, 360.0)  # degrees, [lo, hi)
ELEVATION = (30.0, 60.0)  # degrees


class CameraError(GraceError):
    """Camera settings no image can be taken with (a non-positive size, distance or field of
    view, an elevation outside [-90, 90] degrees)."""


@dataclass(frozen=True)
class Camera:
    """Where the camera looks from: spherical coordinates (degrees, metres) about ``target``
    (world; None: the scene's object centre), the vertical field of view (degrees) and the
    image size (pixels). ``distance`` None: the scene picks one that frames the objects."""

    azimuth: float = 45.0
    elevation: float = 45.0
    distance: float | None = None
    target: tuple[float, float, float] | None = None
    fovy: float = 45.0
    width: int = 320
    height: int = 240

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise CameraError(f"image size must be positive, got {self.width}x{self.height}")
        if self.distance is not None and not self.distance > 0:
            raise CameraError(f"camera distance must be > 0 m, got {self.distance}")
        if not 0 < self.fovy < 180:
            raise CameraError(f"fovy must be in (0, 180) degrees, got {self.fovy}")
        if not -90 <= self.elevation <= 90:
            raise CameraError(f"elevation must be in [-90, 90] degrees, got {self.elevation}")

    @classmethod
    def random(
        cls,
        rng: np.random.Generator,
        distance: float | None = None,
        azimuth: tuple[float, float] = AZIMUTH,
        elevation: tuple[float, float] = ELEVATION,
        **settings: Any,
    ) -> Camera:
        """A camera drawn from ``rng`` as the protocol says (azimuth uniform in ``azimuth``,
        elevation uniform in ``elevation``, degrees); the same generator state gives the same
        camera."""
        az = float(rng.uniform(*azimuth))
        el = float(rng.uniform(*elevation))
        return cls(azimuth=az, elevation=el, distance=distance, **settings)

    def aimed(self, target: np.ndarray, distance: float) -> Camera:
        """This camera with its target and distance filled in where they were left open."""
        x, y, z = (float(v) for v in target)
        t = self.target if self.target is not None else (x, y, z)
        return replace(self, target=t, distance=self.distance or float(distance))

    def pose(self) -> np.ndarray:
        """world <- camera (4x4); needs ``target`` and ``distance`` (``aimed``)."""
        if self.target is None or self.distance is None:
            raise CameraError("the camera has no target or distance yet: use camera.aimed(...)")
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        target = np.asarray(self.target, float)
        eye = target + self.distance * np.array(
            [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]
        )
        forward = (target - eye) / np.linalg.norm(target - eye)
        up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.999 else np.array([0.0, 1.0, 0.0])
        right = np.cross(forward, up)
        right /= np.linalg.norm(right)
        out = np.eye(4)
        out[:3, 0], out[:3, 1], out[:3, 2] = right, np.cross(-forward, right), -forward
        out[:3, 3] = eye
        return out

    def focal(self) -> float:
        """The focal length in pixels (square pixels; MuJoCo's fovy is vertical)."""
        return self.height / 2 / math.tan(math.radians(self.fovy) / 2)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["target"] = list(self.target) if self.target is not None else None
        return out


def back_project(depth: np.ndarray, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (H, W, 3) of a depth image, and the mask of pixels that hit
    something (depth > 0). Pixel (row v, column u) looks through its centre."""
    h, w = depth.shape
    f = camera.focal()
    u = np.arange(w) + 0.5 - w / 2
    v = np.arange(h) + 0.5 - h / 2
    x = u[None, :] / f * depth
    y = -v[:, None] / f * depth
    points = np.stack([x, y, -depth], axis=-1)
    return points, depth > 0


def to_world(points: np.ndarray, camera: Camera) -> np.ndarray:
    """Camera-frame points (..., 3) in the world frame."""
    pose = camera.pose()
    return points @ pose[:3, :3].T + pose[:3, 3]
