"""Exact convex splits of the primitives that are not convex, for collision and simulation.

Simulators collide convex solids: MuJoCo replaces a mesh geom by its convex hull, so a carcass
exported as one mesh would be a solid block. Where a primitive is a union of boxes its split is
exact and analytic: a ``BoardBox`` is its boards, a ``RectRing`` its four bars. Each piece is a
``Cuboid`` (a native box in URDF and MJCF) posed in the primitive's frame.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.geometry import boards
from grace_dsl.geometry.primitives import validate


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


def _rect_ring(p: Mapping[str, Any]) -> tuple[ConvexPiece, ...]:
    """Two full-width bars (top, bottom) and two between them (left, right)."""
    (ox, oy), (ix, iy), d = p["outer"], p["inner"], float(p["depth"])
    bar_y, bar_x = (oy - iy) / 2, (ox - ix) / 2
    return (
        _box("top", (0.0, (oy - bar_y) / 2, 0.0), (ox, bar_y, d)),
        _box("bottom", (0.0, -(oy - bar_y) / 2, 0.0), (ox, bar_y, d)),
        _box("left", (-(ox - bar_x) / 2, 0.0, 0.0), (bar_x, iy, d)),
        _box("right", ((ox - bar_x) / 2, 0.0, 0.0), (bar_x, iy, d)),
    )


SPLITS = {
    "BoardBox": lambda p: tuple(_box(b.name, b.center, b.size) for b in boards.boards(p)),
    "RectRing": _rect_ring,
}


def convex_pieces(name: str, params: Mapping[str, Any]) -> tuple[ConvexPiece, ...] | None:
    """The exact convex split of primitive ``name`` (disjoint boxes whose union is the solid),
    or None for a primitive without one (convex ones need none)."""
    p = validate(name, params)
    split = SPLITS.get(name)
    return None if split is None else split(p)
