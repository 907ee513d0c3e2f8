"""Convex splits of the primitives that are not convex, for collision and simulation.

Simulators collide convex solids: MuJoCo replaces a mesh geom by its convex hull, so a carcass
exported as one mesh would be a solid block and a ring handle a disc. Every non-convex primitive
has an analytic split here, each piece itself a primitive (so it keeps its exact mesh and, where
the simulator has one, its native geom), posed in the primitive's frame:

- ``BoardBox``: its boards; ``RectRing``: its four bars (exact, disjoint boxes);
- ``Cylinder`` sectors wider than a half turn: two halves (exact; a sector up to pi is convex);
- ``Tube`` and ``Ring``: annular segments, each a ``TaperedCuboid`` whose inner face is tangent
  to the inner circle and whose outer face is a chord of the outer one, so every piece lies
  inside the solid (nothing pokes into the hole) and the union misses only chord slivers;
- ``Torus``: capsules along the chords of the centre arc, the sag kept under a fifth of the
  tube's radius.

``carve_boxes`` splits a box minus axis-aligned boxes (the recesses and notches of the library's
``difference`` shapes) into disjoint boxes. Other shapes are convex already (None).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.geometry import boards
from grace_dsl.geometry.primitives import FULL_TURN, validate

SEGMENTS = 24  # pieces per full turn of a ring, tube or torus (at least; thin walls need more)
MAX_SEGMENTS = 256
WALL = 0.85  # the share of a ring's wall thickness each annular piece keeps at its middle
_HALF_TURN = math.pi + 1e-9


@dataclass(frozen=True)
class ConvexPiece:
    """One convex solid of a split: a primitive, its SI parameters and its pose (4x4, the
    primitive's frame <- the piece's frame)."""

    name: str
    primitive: str
    params: Mapping[str, Any]
    pose: np.ndarray


def _box(name: str, center: Any, size: Any) -> ConvexPiece:
    pose = np.eye(4)
    pose[:3, 3] = center
    return ConvexPiece(name, "Cuboid", {"size": tuple(float(s) for s in size)}, pose)


def _rect_ring(p: Mapping[str, Any], segments: int) -> tuple[ConvexPiece, ...]:
    """Two full-width bars (top, bottom) and two between them (left, right)."""
    (ox, oy), (ix, iy), d = p["outer"], p["inner"], float(p["depth"])
    bar_y, bar_x = (oy - iy) / 2, (ox - ix) / 2
    return (
        _box("top", (0.0, (oy - bar_y) / 2, 0.0), (ox, bar_y, d)),
        _box("bottom", (0.0, -(oy - bar_y) / 2, 0.0), (ox, bar_y, d)),
        _box("left", (-(ox - bar_x) / 2, 0.0, 0.0), (bar_x, iy, d)),
        _box("right", ((ox - bar_x) / 2, 0.0, 0.0), (bar_x, iy, d)),
    )


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    return out


def _count(angle: float, segments: int, half_max: float) -> int:
    """Pieces for an arc of ``angle``: ``segments`` per full turn, and each at most
    ``2 * half_max`` wide."""
    n = max(math.ceil(angle * segments / FULL_TURN - 1e-9), math.ceil(angle / (2 * half_max)))
    return int(min(max(n, 1), MAX_SEGMENTS))


def _annulus(
    r_in: float, r_out: float, height: float, start: float, angle: float, segments: int
) -> tuple[ConvexPiece, ...]:
    """Annular segments between ``start`` and ``start + angle`` (from +x, about z)."""
    # each piece keeps WALL of the wall's thickness: cos(phi) r_out - r_in >= WALL (r_out - r_in)
    half_max = math.acos(min(1.0, (r_in + WALL * (r_out - r_in)) / r_out))
    n = _count(angle, segments, half_max)
    phi = angle / n / 2
    depth = r_out * math.cos(phi) - r_in  # radial extent of each piece
    params = {
        "size": (2 * r_in * math.tan(phi), depth, height),
        "top": (2 * r_out * math.sin(phi), height),
        "offset": (0.0, 0.0),
    }
    out = []
    for k in range(n):
        theta = start + (2 * k + 1) * phi
        radial = np.array([math.cos(theta), math.sin(theta), 0.0])
        pose = np.eye(4)  # the piece's y outward, z the primitive's axis
        pose[:3, 0] = np.cross(radial, [0.0, 0.0, 1.0])
        pose[:3, 1] = radial
        pose[:3, 2] = (0.0, 0.0, 1.0)
        pose[:3, 3] = radial * (r_in + depth / 2)
        out.append(ConvexPiece(f"segment_{k}", "TaperedCuboid", dict(params), pose))
    return tuple(out)


def _tube(p: Mapping[str, Any], segments: int) -> tuple[ConvexPiece, ...]:
    return _annulus(p["r_in"], p["r_out"], p["height"], 0.0, FULL_TURN, segments)


def _ring(p: Mapping[str, Any], segments: int) -> tuple[ConvexPiece, ...]:
    angle = float(p["radian"])  # centred on -y, as the mesh and the distance
    return _annulus(p["r_in"], p["r_out"], p["height"], -math.pi / 2 - angle / 2, angle, segments)


def _cylinder(p: Mapping[str, Any], segments: int) -> tuple[ConvexPiece, ...] | None:
    """A sector wider than a half turn (and not whole): its two halves, each convex."""
    angle = float(p["radian"])
    if angle <= _HALF_TURN or angle >= FULL_TURN - 1e-9:
        return None
    half = {"radius": p["radius"], "height": p["height"], "radian": angle / 2}
    return tuple(  # the sector is centred on +y: the halves on either side of it
        ConvexPiece(name, "Cylinder", dict(half), _rot_z(sign * angle / 4))
        for name, sign in (("half_0", -1.0), ("half_1", 1.0))
    )


def _torus(p: Mapping[str, Any], segments: int) -> tuple[ConvexPiece, ...]:
    big, small, angle = float(p["r_major"]), float(p["r_minor"]), float(p["radian"])
    half_max = math.acos(max(0.0, 1 - 0.2 * small / big))  # sag R (1 - cos phi) <= r / 5
    n = _count(angle, segments, half_max)
    phi = angle / n / 2
    start = -math.pi / 2 - angle / 2  # centred on -y, as the mesh
    params = {"radius": small, "length": max(2 * big * math.sin(phi), 1e-9)}
    out = []
    for k in range(n):
        theta = start + (2 * k + 1) * phi
        radial = np.array([math.cos(theta), math.sin(theta), 0.0])
        pose = np.eye(4)  # the capsule's axis (z) along the chord
        pose[:3, 0] = radial
        pose[:3, 1] = (0.0, 0.0, -1.0)
        pose[:3, 2] = (-math.sin(theta), math.cos(theta), 0.0)
        pose[:3, 3] = radial * big * math.cos(phi)
        out.append(ConvexPiece(f"segment_{k}", "Capsule", dict(params), pose))
    return tuple(out)


SPLITS = {
    "BoardBox": lambda p, n: tuple(_box(b.name, b.center, b.size) for b in boards.boards(p)),
    "RectRing": _rect_ring,
    "Cylinder": _cylinder,
    "Tube": _tube,
    "Ring": _ring,
    "Torus": _torus,
}


def convex_pieces(
    name: str, params: Mapping[str, Any], segments: int = SEGMENTS
) -> tuple[ConvexPiece, ...] | None:
    """The convex split of primitive ``name`` (pieces inside the solid whose union is it, up to
    the chords of curved faces), or None for a convex primitive. ``segments``: pieces per full
    turn of a curved one."""
    p = validate(name, params)
    split = SPLITS.get(name)
    return None if split is None else split(p, segments)


def _axis_map(rotation: np.ndarray) -> np.ndarray | None:
    """For a rotation that permutes the axes (up to sign), the index of the box axis each of
    the hole's axes lies along; None for any other rotation."""
    r = np.abs(rotation)
    if not np.allclose(np.sort(r, axis=0)[-1], 1.0, atol=1e-9) or not np.allclose(
        r.sum(axis=0), 1.0, atol=1e-9
    ):
        return None
    return np.argmax(r, axis=0)


def carve_boxes(
    size: Sequence[float], holes: Sequence[tuple[np.ndarray, Sequence[float]]]
) -> tuple[ConvexPiece, ...] | None:
    """A box of ``size`` (centred on its frame) minus the boxes ``holes`` ((pose in the box's
    frame, size) each), as disjoint boxes: the cells of the grid of every face that are in the
    box and in no hole, merged greedily into blocks. None when a hole is turned other than by
    a multiple of 90 degrees (no such grid)."""
    half = np.asarray(size, float) / 2
    boxes = []
    for pose, hole in holes:
        axes = _axis_map(np.asarray(pose)[:3, :3])
        if axes is None:
            return None
        extent = np.zeros(3)
        extent[axes] = np.asarray(hole, float) / 2
        centre = np.asarray(pose)[:3, 3]
        boxes.append((np.maximum(centre - extent, -half), np.minimum(centre + extent, half)))
    cuts = [
        np.unique(
            np.round(
                np.concatenate([[-half[a], half[a]], *[[lo[a], hi[a]] for lo, hi in boxes]]), 12
            )
        )
        for a in range(3)
    ]
    cuts = [c[(c >= -half[a] - 1e-12) & (c <= half[a] + 1e-12)] for a, c in enumerate(cuts)]
    mids = [(c[:-1] + c[1:]) / 2 for c in cuts]
    grid = np.stack(np.meshgrid(*mids, indexing="ij"), axis=-1)
    solid = np.ones(grid.shape[:3], bool)
    for lo, hi in boxes:
        solid &= ~np.all((grid > lo) & (grid < hi), axis=-1)
    return tuple(_merge(solid, cuts))


def _merge(solid: np.ndarray, cuts: list[np.ndarray]) -> list[ConvexPiece]:
    """Greedy blocks: from each free solid cell grow along x, then y, then z."""
    free = solid.copy()
    out: list[ConvexPiece] = []
    nx, ny, nz = free.shape
    for i, j, k in zip(*np.nonzero(solid)):
        if not free[i, j, k]:
            continue
        i1 = i + 1
        while i1 < nx and free[i1, j, k]:
            i1 += 1
        j1 = j + 1
        while j1 < ny and free[i:i1, j1, k].all():
            j1 += 1
        k1 = k + 1
        while k1 < nz and free[i:i1, j:j1, k1].all():
            k1 += 1
        free[i:i1, j:j1, k:k1] = False
        lo = np.array([cuts[0][i], cuts[1][j], cuts[2][k]])
        hi = np.array([cuts[0][i1], cuts[1][j1], cuts[2][k1]])
        out.append(_box(f"block_{len(out)}", (lo + hi) / 2, hi - lo))
    return out
