"""A parallel gripper's abilities and finger geometry, for ranking and verifying grasps.

The gripper frame is the project's (DESIGN.md §6): origin between the fingertips, +z the approach
(into the object), +y the direction in which the fingers close, +x = y × z. The fingertips end at
the origin: each finger pad is a box reaching back from z = 0 to z = -finger_length, its inner
face at y = ±width/2 for an opening ``width``. A pinch grasp therefore puts the material it holds
between the pads at its origin, and a push or press grasp puts the origin on the touched surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.inputs import as_array, as_number
from grace_dsl.tolerances import DEGENERATE, RANGE_SLACK


@dataclass(frozen=True)
class FingerBox:
    """One finger pad: a box at ``pose`` (gripper frame <- box frame) with ``half_extents``."""

    pose: np.ndarray
    half_extents: tuple[float, float, float]


@dataclass(frozen=True)
class Gripper:
    """What a hand can do (open how wide, close at all, from which direction) and its pads."""

    name: str
    max_width: float  # widest opening between the pads' inner faces, metres
    finger_width: float  # pad size along x
    finger_thickness: float  # pad size along y (the closing direction)
    finger_length: float  # pad size along z (the approach)
    can_close: bool = True
    approach: tuple[float, float, float] | None = None  # required world approach; None: any
    approach_tolerance: float = math.pi  # radians the approach may deviate from ``approach``

    def __post_init__(self) -> None:
        sizes = {
            "max_width": self.max_width,
            "finger_width": self.finger_width,
            "finger_thickness": self.finger_thickness,
            "finger_length": self.finger_length,
        }
        for field_name, value in sizes.items():
            value = as_number(f"gripper {self.name}: {field_name}", value)
            if not math.isfinite(value) or value < 0 or (value == 0 and field_name != "max_width"):
                raise ParameterError(
                    f"gripper {self.name}: {field_name} must be a finite positive length in "
                    f"metres, got {value!r}"
                )
        if self.approach is not None:
            a = as_array(f"gripper {self.name}: approach", self.approach)
            if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < DEGENERATE:
                raise ParameterError(
                    f"gripper {self.name}: approach must be a non-zero world direction (x, y, z) "
                    f"or None, got {self.approach!r}"
                )
        tolerance = as_number(f"gripper {self.name}: approach_tolerance", self.approach_tolerance)
        if not 0.0 <= tolerance <= math.pi:
            raise ParameterError(
                f"gripper {self.name}: approach_tolerance must lie in [0, pi] radians, got "
                f"{self.approach_tolerance!r}"
            )

    @staticmethod
    def panda() -> Gripper:
        """The Franka Emika Panda hand.

        Source: example-robot-data 6.0.0, robots/panda_description/urdf/panda.urdf. Each finger
        joint travels 0-40 mm (``panda_finger_joint1/2``, limit upper="0.04"), so the pads open
        0-80 mm; the "rubber tip with which to grasp" collision box of ``panda_leftfinger`` is
        17.5 x 15.2 x 18.5 mm (x, y, z) with its inner face on the finger joint's origin, which
        matches Franka's datasheet (80 mm stroke).
        """
        return Gripper(
            name="panda",
            max_width=0.080,
            finger_width=0.0175,
            finger_thickness=0.0152,
            finger_length=0.0185,
        )

    def finger_boxes(self, width: float) -> tuple[FingerBox, FingerBox]:
        """The two pads in the gripper frame at opening ``width`` (inner faces ``width`` apart):
        the one on -y first. Width 0 is the closed hand, pads touching."""
        width = as_number("width", width)
        if not math.isfinite(width) or not 0.0 <= width <= self.max_width + RANGE_SLACK:
            raise ParameterError(
                f"{self.name} opens 0-{self.max_width * 1e3:g} mm; cannot open to "
                f"{width * 1e3:g} mm"
            )
        half = (self.finger_width / 2, self.finger_thickness / 2, self.finger_length / 2)
        y = width / 2 + self.finger_thickness / 2
        boxes = []
        for side in (-1.0, 1.0):
            pose = np.eye(4)
            pose[:3, 3] = (0.0, side * y, -self.finger_length / 2)
            boxes.append(FingerBox(pose, half))
        return boxes[0], boxes[1]


def box_surface_grid(box: FingerBox, spacing: float) -> np.ndarray:
    """(N, 3) points on a box's surface, a grid at most ``spacing`` apart on each face, in the
    frame ``box.pose`` maps to (corners and edges included once per face that holds them)."""
    if not as_number("spacing", spacing) > 0:
        raise ParameterError(f"spacing must be a positive length, got {spacing!r}")
    h = np.asarray(box.half_extents, dtype=float)
    ticks = [np.linspace(-e, e, max(2, math.ceil(2 * e / spacing) + 1)) for e in h]
    faces = []
    for axis in range(3):
        a, b = (i for i in range(3) if i != axis)
        u, v = np.meshgrid(ticks[a], ticks[b], indexing="ij")
        for sign in (-1.0, 1.0):
            pts = np.empty((u.size, 3))
            pts[:, axis] = sign * h[axis]
            pts[:, a], pts[:, b] = u.ravel(), v.ravel()
            faces.append(pts)
    local = np.concatenate(faces)
    return local @ box.pose[:3, :3].T + box.pose[:3, 3]


def finger_points(gripper: Gripper, width: float, spacing: float = 0.002) -> np.ndarray:
    """(N, 3) sample points on the surfaces of both pads at opening ``width``, gripper frame:
    where a penetration check evaluates the part's signed distance. The -y pad's points come
    first, as many as the +y pad's."""
    return np.concatenate([box_surface_grid(b, spacing) for b in gripper.finger_boxes(width)])
