"""What a hand can do and what it is made of, for ranking and verifying grasps.

The gripper frame is the project's (DESIGN.md §6): origin between the fingertips, +z the approach
(into the object), +y the direction in which the fingers close, +x = y × z. The fingertips end at
the origin: each finger pad is a box reaching back from z = 0 to z = -finger_length, its inner
face at y = ±width/2 for an opening ``width``. A pinch grasp therefore puts the material it holds
between the pads at its origin, and a push or press grasp puts the origin on the touched surface.

Beyond the pads a hand has finger blocks (the rest of each finger: they move with the pads and
are given for the +y finger at the closed hand, mirrored for the -y finger) and a palm (boxes
fixed to the hand), so a ranker can check the whole hand against a part. A hand may also be
limited in orientation (a top-down gripper: approach within a cone about a world direction, the
fingers closing within a cone about a world line) and in its wrist (``can_turn``: whether the
hand can turn while it acts, which a twist on a knob's axis needs). Hands are described in small
TOML files (``grace_dsl.runtime.hands``); ``Gripper.load`` reads them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.inputs import as_array, as_number
from grace_dsl.tolerances import DEGENERATE, RANGE_SLACK

# What a hand may push with: fingertips, a finger's side, palm, and the closed fingers' edge or
# corner nearest the part with the hand at its home orientation (for a hand that cannot turn
# to put a face on the part: only when its description lists it).
PUSHES = ("tip", "side", "palm", "edge")
DEFAULT_PUSHES = ("tip", "side", "palm")


@dataclass(frozen=True)
class FingerBox:
    """One box of the hand: at ``pose`` (gripper frame <- box frame) with ``half_extents``;
    ``part`` is ``pad``, ``finger`` (moves with the pads) or ``palm`` (fixed to the hand)."""

    pose: np.ndarray
    half_extents: tuple[float, float, float]
    name: str = ""
    part: str = "pad"


@dataclass(frozen=True)
class HandBox:
    """A box of a hand's description: centre (gripper frame, fingers closed), half extents and
    roll-pitch-yaw (radians, ``R = Rz(yaw) Ry(pitch) Rx(roll)``, as URDF)."""

    name: str
    center: tuple[float, float, float]
    half_extents: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def pose(self, shift_y: float = 0.0) -> np.ndarray:
        """Gripper frame <- box frame, the box moved by ``shift_y`` along the closing axis."""
        pose = np.eye(4)
        pose[:3, :3] = rpy_matrix(self.rpy)
        pose[:3, 3] = self.center
        pose[1, 3] += shift_y
        return pose

    def mirrored(self) -> HandBox:
        """The same box on the -y finger (mirror y -> -y: roll and yaw change sign)."""
        x, y, z = self.center
        r, p, w = self.rpy
        return HandBox(self.name, (x, -y, z), self.half_extents, (-r, p, -w))


def rpy_matrix(rpy: tuple[float, float, float]) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class Gripper:
    """What a hand can do (open how wide, close at all, reach which orientations, turn its wrist)
    and the boxes it is made of (pads, finger blocks, palm)."""

    name: str
    max_width: float  # widest opening between the pads' inner faces, metres
    finger_width: float  # pad size along x
    finger_thickness: float  # pad size along y (the closing direction)
    finger_length: float  # pad size along z (the approach)
    can_close: bool = True
    approach: tuple[float, float, float] | None = None  # required world approach; None: any
    approach_tolerance: float = math.pi  # radians the approach may deviate from ``approach``
    closing: tuple[float, float, float] | None = None  # world line the fingers close along
    closing_tolerance: float = math.pi  # radians the closing axis may deviate from that line
    can_turn: bool = True  # the hand may turn while it acts (a twist on a knob's axis needs it)
    fingers: tuple[HandBox, ...] = ()  # the +y finger's blocks besides its pad (closed hand)
    palm: tuple[HandBox, ...] = ()  # boxes fixed to the hand
    pushes: tuple[str, ...] = DEFAULT_PUSHES  # what it may push with, of those it has
    approach_distance: float = 0.08  # metres the hand starts back from a grasp, along -z
    doc: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        sizes = {
            "max_width": self.max_width,
            "finger_width": self.finger_width,
            "finger_thickness": self.finger_thickness,
            "finger_length": self.finger_length,
            "approach_distance": self.approach_distance,
        }
        for field_name, value in sizes.items():
            value = as_number(f"gripper {self.name}: {field_name}", value)
            zero_ok = field_name in ("max_width", "approach_distance")
            if not math.isfinite(value) or value < 0 or (value == 0 and not zero_ok):
                raise ParameterError(
                    f"gripper {self.name}: {field_name} must be a finite positive length in "
                    f"metres, got {value!r}"
                )
        for axis in ("approach", "closing"):
            self._check_direction(axis)
            tol = getattr(self, f"{axis}_tolerance")
            tolerance = as_number(f"gripper {self.name}: {axis}_tolerance", tol)
            if not 0.0 <= tolerance <= math.pi:
                raise ParameterError(
                    f"gripper {self.name}: {axis}_tolerance must lie in [0, pi] radians, got "
                    f"{tol!r}"
                )
        for push in self.pushes:
            if push not in PUSHES:
                raise ParameterError(
                    f"gripper {self.name}: pushes lists {push!r}; a hand pushes with "
                    f"{', '.join(PUSHES)}"
                )
        for box in (*self.fingers, *self.palm):
            if not isinstance(box, HandBox) or not all(
                math.isfinite(h) and h > 0 for h in box.half_extents
            ):
                raise ParameterError(
                    f"gripper {self.name}: every finger block and palm box must be a HandBox "
                    f"with positive sizes, got {box!r:.80}"
                )

    def _check_direction(self, axis: str) -> None:
        value = getattr(self, axis)
        if value is None:
            return
        a = as_array(f"gripper {self.name}: {axis}", value)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < DEGENERATE:
            raise ParameterError(
                f"gripper {self.name}: {axis} must be a non-zero world direction (x, y, z) "
                f"or None, got {value!r}"
            )

    # -- the shipped hands and description files
    @staticmethod
    def panda() -> Gripper:
        """The Franka Emika Panda hand (``grace_dsl/hands/panda.toml``).

        Source: example-robot-data 6.0.0, robots/panda_description/urdf/panda.urdf. Each finger
        joint travels 0-40 mm (``panda_finger_joint1/2``, limit upper="0.04"), so the pads open
        0-80 mm; the "rubber tip with which to grasp" collision box of ``panda_leftfinger`` is
        17.5 x 15.2 x 18.5 mm (x, y, z) with its inner face on the finger joint's origin, which
        matches Franka's datasheet (80 mm stroke). The finger blocks and the palm come from the
        same file (see the description file for every number).
        """
        from grace_dsl.runtime.hands import load_hand

        return load_hand("panda")

    @staticmethod
    def load(path_or_name: str | Path) -> Gripper:
        """A hand from a description file (a path to a ``.toml`` file) or a shipped hand by name
        (``panda``, ``topdown``, ``pusher``): see ``docs/api.md`` for the format."""
        from grace_dsl.runtime.hands import load_hand

        return load_hand(path_or_name)

    @staticmethod
    def shipped() -> tuple[str, ...]:
        """The names of the hands that ship with the package."""
        from grace_dsl.runtime.hands import shipped_hands

        return shipped_hands()

    # -- geometry
    def finger_boxes(self, width: float) -> tuple[FingerBox, FingerBox]:
        """The two pads in the gripper frame at opening ``width`` (inner faces ``width`` apart):
        the one on -y first. Width 0 is the closed hand, pads touching."""
        width = self._width(width)
        half = (self.finger_width / 2, self.finger_thickness / 2, self.finger_length / 2)
        y = width / 2 + self.finger_thickness / 2
        boxes = []
        for side in (-1.0, 1.0):
            pose = np.eye(4)
            pose[:3, 3] = (0.0, side * y, -self.finger_length / 2)
            boxes.append(FingerBox(pose, half, "pad", "pad"))
        return boxes[0], boxes[1]

    def hand_boxes(self, width: float) -> tuple[FingerBox, ...]:
        """Every box of the hand at opening ``width``, gripper frame: the pads (-y first), the
        finger blocks (each -y then +y), then the palm."""
        width = self._width(width)
        out = list(self.finger_boxes(width))
        for box in self.fingers:
            for side, b in ((-1.0, box.mirrored()), (1.0, box)):
                out.append(FingerBox(b.pose(side * width / 2), b.half_extents, b.name, "finger"))
        out += [FingerBox(b.pose(), b.half_extents, b.name, "palm") for b in self.palm]
        return tuple(out)

    def _width(self, width: float) -> float:
        width = as_number("width", width)
        if not math.isfinite(width) or not 0.0 <= width <= self.max_width + RANGE_SLACK:
            raise ParameterError(
                f"{self.name} opens 0-{self.max_width * 1e3:g} mm; cannot open to "
                f"{width * 1e3:g} mm"
            )
        return width

    @property
    def push_modes(self) -> tuple[str, ...]:
        """What this hand can push with: the fingertips and a finger's side (it has pads), the
        palm (it has one), of those its description allows."""
        have = {"tip", "side", "edge"} | ({"palm"} if self.palm else set())
        return tuple(p for p in PUSHES if p in self.pushes and p in have)

    # -- orientation
    def home(self, fallback: np.ndarray) -> np.ndarray:
        """The hand's preferred world rotation: its required approach and closing line where it
        has them, else ``fallback``'s axes (its approach, then its closing axis made orthogonal)."""
        z = _unit(self.approach) if self.approach is not None else fallback[:, 2]
        y = _unit(self.closing) if self.closing is not None else fallback[:, 1]
        y = y - (y @ z) * z
        if np.linalg.norm(y) < 1e-6:  # closing along the approach: take the fallback's x
            y = np.cross(z, fallback[:, 0])
        y = y / np.linalg.norm(y)
        return np.column_stack([np.cross(y, z), y, z])

    def orientation_error(self, rotations: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(tilt, turn) per world rotation (..., 3, 3): the angle of its approach from the
        required one, and of its closing axis from the required closing line (either sense: a
        parallel hand turned half a turn about its approach is the same hand); 0 where free."""
        shape = rotations.shape[:-2]
        tilt = np.zeros(shape)
        turn = np.zeros(shape)
        if self.approach is not None:
            tilt = np.arccos(np.clip(rotations[..., :, 2] @ _unit(self.approach), -1.0, 1.0))
        if self.closing is not None:
            turn = np.arccos(np.clip(np.abs(rotations[..., :, 1] @ _unit(self.closing)), 0, 1))
        return tilt, turn

    def allows(self, tilt: np.ndarray, turn: np.ndarray) -> np.ndarray:
        """Whether orientations with these errors are within the hand's cones."""
        slack = DEGENERATE + 1e-9
        return (tilt <= self.approach_tolerance + slack) & (turn <= self.closing_tolerance + slack)


def _unit(v: tuple[float, float, float] | None) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    return a / np.linalg.norm(a)


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
