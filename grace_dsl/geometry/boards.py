"""The board box (``BoardBox``): a hollow box of boards, a furniture carcass or a drawer's tray.

One layout serves every view of the solid. Along each axis the box splits at the board faces
(``-h, -h + b, h - b, h``) into a 3 x 3 x 3 grid of cells; the middle cell is the cavity, and an
open top (or front) also empties the cell above (or in front of) it. So:

- the **mesh** is the faces between solid and empty cells, on the shared 4 x 4 x 4 vertex grid
  (watertight by construction, no T-junctions);
- the **surface samples** are drawn from the same faces (each an exact rectangle);
- the **convex pieces** are the boards, disjoint boxes whose union is the solid (sides full
  height and depth, bottom and top between the sides, back and front between those), which is
  what a simulator collides with (a mesh geom would become its convex hull: a solid box);
- the **signed distance** is exact: inside, ``max(d_outer, -d_cavity)`` (the cavity, extended
  through the open faces, is a convex box, and so is the outer box); outside, the minimum of the
  boards' box distances (the distance to a union is the nearest member's, overlaps or not).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

Arr = NDArray[np.float64]
_ABSENT = 1e9  # the distance of a board that is not there (a flag may be symbolic)


@dataclass(frozen=True)
class Board:
    """One board: its name, centre and full size (x, y, z) in the box's frame."""

    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]


def _flags(p: Mapping[str, Any]) -> tuple[bool, bool]:
    return bool(p["top"]), bool(p["front"])


def boards(p: Mapping[str, Any]) -> list[Board]:
    """The boards of a (validated) board box, disjoint, their union the solid."""
    (sx, sy, sz), b = (float(v) for v in p["size"]), float(p["board"])
    hx, hy, hz = sx / 2, sy / 2, sz / 2
    top, front = _flags(p)
    y_hi = hy - b if top else hy  # the back and front reach the top board or the open top
    mid_y, span_y = (-hy + b + y_hi) / 2, y_hi - (-hy + b)
    out = [
        Board("left", (-hx + b / 2, 0.0, 0.0), (b, sy, sz)),
        Board("right", (hx - b / 2, 0.0, 0.0), (b, sy, sz)),
        Board("bottom", (0.0, -hy + b / 2, 0.0), (sx - 2 * b, b, sz)),
        Board("back", (0.0, mid_y, -hz + b / 2), (sx - 2 * b, span_y, b)),
    ]
    if top:
        out.append(Board("top", (0.0, hy - b / 2, 0.0), (sx - 2 * b, b, sz)))
    if front:
        out.append(Board("front", (0.0, mid_y, hz - b / 2), (sx - 2 * b, span_y, b)))
    return out


def _solid_cells(p: Mapping[str, Any]) -> NDArray[np.bool_]:
    """(3, 3, 3) booleans: which cells of the board grid hold material."""
    top, front = _flags(p)
    solid = np.ones((3, 3, 3), dtype=bool)
    for j in (1, 2) if not top else (1,):
        for k in (1, 2) if not front else (1,):
            solid[1, j, k] = False
    return solid


def grid(p: Mapping[str, Any]) -> list[Arr]:
    """The four split coordinates per axis: ``-h, -h + b, h - b, h``."""
    b = float(p["board"])
    return [np.array([-s / 2, -s / 2 + b, s / 2 - b, s / 2]) for s in (float(v) for v in p["size"])]


Face = tuple[Arr, Arr, Arr, Arr]  # origin, edge u, edge v (u x v along the normal), normal


def faces(p: Mapping[str, Any]) -> list[Face]:
    """The boundary rectangles of the solid, each between a solid and an empty cell, with its
    outward normal; ``origin + [0,1] u + [0,1] v`` is the rectangle."""
    solid, g = _solid_cells(p), grid(p)
    out: list[Face] = []
    for i, j, k in zip(*np.nonzero(solid)):
        cell = (int(i), int(j), int(k))
        for axis in range(3):
            for step in (-1, 1):
                nb = list(cell)
                nb[axis] += step
                if 0 <= nb[axis] <= 2 and solid[tuple(nb)]:
                    continue
                out.append(_cell_face(g, cell, axis, step))
    return out


def _cell_face(g: list[Arr], cell: tuple[int, int, int], axis: int, step: int) -> Face:
    u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
    origin = np.array([g[a][cell[a]] for a in range(3)])
    origin[axis] = g[axis][cell[axis] + (1 if step > 0 else 0)]
    u, v, n = np.zeros(3), np.zeros(3), np.zeros(3)
    u[u_ax] = g[u_ax][cell[u_ax] + 1] - g[u_ax][cell[u_ax]]
    v[v_ax] = g[v_ax][cell[v_ax] + 1] - g[v_ax][cell[v_ax]]
    n[axis] = step
    if step < 0:  # keep u x v along the outward normal
        origin, u, v = origin + u, -u, v
    return origin, u, v, n


def volume(p: Mapping[str, Any]) -> float:
    """The boards' volume: the outer box minus the part of the cavity inside it."""
    (sx, sy, sz), b = (float(v) for v in p["size"]), float(p["board"])
    top, front = _flags(p)
    cavity = (sx - 2 * b) * (sy - (2 if top else 1) * b) * (sz - (2 if front else 1) * b)
    return sx * sy * sz - cavity


def _box(o: Any, x: Any, y: Any, z: Any, hx: Any, hy: Any, hz: Any) -> Any:
    qx, qy, qz = o.abs(x) - hx, o.abs(y) - hy, o.abs(z) - hz
    mx, my, mz = o.max(qx, 0), o.max(qy, 0), o.max(qz, 0)
    return o.sqrt0(mx * mx + my * my + mz * mz) + o.min(o.max(qx, o.max(qy, qz)), 0)


def sdf(o: Any, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    """Exact signed distance on a numpy or CasADi backend ``o``; ``top`` and ``front`` may be
    symbolic (0 or 1), so every branch is an ``o.where``."""
    size, b = p["size"], p["board"]
    hx, hy, hz = size[0] / 2, size[1] / 2, size[2] / 2
    top, front = p["top"] > 0.5, p["front"] > 0.5
    # the cavity, through an open face one board beyond the outer box (any margin > 0 is exact:
    # the inside points it decides are within the outer box)
    y1, z1 = o.where(top, hy - b, hy + b), o.where(front, hz - b, hz + b)
    cy, cz = (y1 - hy + b) / 2, (z1 - hz + b) / 2
    cavity = _box(o, x, y - cy, z - cz, hx - b, (y1 + hy - b) / 2, (z1 + hz - b) / 2)
    inside = o.max(_box(o, x, y, z, hx, hy, hz), -cavity)
    # outside: the nearest board; the back and front run up to the top board or the open top
    yb = o.where(top, hy - b, hy)
    my, ey = (yb - hy + b) / 2, (yb + hy - b) / 2
    wx = hx - b
    side = o.min(
        _box(o, x - (-hx + b / 2), y, z, b / 2, hy, hz),
        _box(o, x - (hx - b / 2), y, z, b / 2, hy, hz),
    )
    bottom = _box(o, x, y + hy - b / 2, z, wx, b / 2, hz)
    back = _box(o, x, y - my, z + hz - b / 2, wx, ey, b / 2)
    lid = o.where(top, _box(o, x, y - hy + b / 2, z, wx, b / 2, hz), _ABSENT)
    face = o.where(front, _box(o, x, y - my, z - hz + b / 2, wx, ey, b / 2), _ABSENT)
    outside = o.min(o.min(side, bottom), o.min(back, o.min(lid, face)))
    return o.where(inside < 0, inside, outside)


def cuboid_pose(board: Board) -> Arr:
    """The 4x4 pose (box frame <- board frame) of a board: a translation."""
    pose = np.eye(4)
    pose[:3, 3] = board.center
    return pose
