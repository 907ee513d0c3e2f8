"""Closed-form properties of the primitives: volume, bounds and simple grasp affordances."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from grace_dsl.geometry.primitives import FULL_TURN, Params, validate


def _fl(v: Any) -> float:
    return float(v)


VOLUMES: dict[str, Callable[[Params], float]] = {
    "Cuboid": lambda p: float(np.prod(p["size"])),
    "Cylinder": lambda p: _fl(p["radian"]) / 2 * _fl(p["radius"]) ** 2 * _fl(p["height"]),
    "Tube": lambda p: math.pi * (_fl(p["r_out"]) ** 2 - _fl(p["r_in"]) ** 2) * _fl(p["height"]),
    "Ring": lambda p: (
        _fl(p["radian"]) / 2 * (_fl(p["r_out"]) ** 2 - _fl(p["r_in"]) ** 2) * _fl(p["height"])
    ),
    "RectRing": lambda p: (
        (float(np.prod(p["outer"])) - float(np.prod(p["inner"]))) * _fl(p["depth"])
    ),
    "Sphere": lambda p: 4 / 3 * math.pi * _fl(p["radius"]) ** 3,
    "Capsule": lambda p: (
        math.pi * _fl(p["radius"]) ** 2 * _fl(p["length"]) + 4 / 3 * math.pi * _fl(p["radius"]) ** 3
    ),
    "Frustum": lambda p: (
        math.pi
        * _fl(p["height"])
        / 3
        * (_fl(p["r_bottom"]) ** 2 + _fl(p["r_bottom"]) * _fl(p["r_top"]) + _fl(p["r_top"]) ** 2)
    ),
}


def volume(name: str, params: Mapping[str, Any]) -> float:
    """The analytic volume in cubic metres."""
    p = validate(name, params)  # first: an unknown name is a GeometryError, not a KeyError
    return VOLUMES[name](p)


def _sector_xy(r_in: float, r_out: float, ang: float, axis: float) -> tuple[Any, Any]:
    """xy bounds of an annular sector: its corners plus the axis-aligned extremes it contains."""
    if ang >= FULL_TURN - 1e-9:
        return np.array([-r_out, -r_out]), np.array([r_out, r_out])
    a0, a1 = axis - ang / 2, axis + ang / 2
    angles = [a0, a1] + [k * math.pi / 2 for k in range(-4, 5) if a0 <= k * math.pi / 2 <= a1]
    pts = [(r * math.cos(a), r * math.sin(a)) for a in angles for r in (r_in, r_out)]
    pts += [(r_in * math.cos(a), r_in * math.sin(a)) for a in (a0, a1)]
    arr = np.array(pts)
    return arr.min(axis=0), arr.max(axis=0)


def bounds(name: str, params: Mapping[str, Any]) -> NDArray[np.float64]:
    """The exact axis-aligned bounding box (2, 3) in the primitive's frame."""
    p = validate(name, params)
    if name == "Cuboid":
        half = np.asarray(p["size"]) / 2
        return np.array([-half, half])
    if name in ("Cylinder", "Ring", "Tube"):
        r_in = 0.0 if name == "Cylinder" else _fl(p["r_in"])
        r_out = _fl(p["radius"] if name == "Cylinder" else p["r_out"])
        ang = FULL_TURN if name == "Tube" else _fl(p["radian"])
        lo, hi = _sector_xy(r_in, r_out, ang, math.pi / 2 if name == "Cylinder" else -math.pi / 2)
        h = _fl(p["height"]) / 2
        return np.array([[lo[0], lo[1], -h], [hi[0], hi[1], h]])
    if name == "RectRing":
        half = np.array([*np.asarray(p["outer"]) / 2, _fl(p["depth"]) / 2])
        return np.array([-half, half])
    if name == "Sphere":
        return np.full((2, 3), _fl(p["radius"])) * [[-1], [1]]
    if name == "Capsule":
        r, h = _fl(p["radius"]), _fl(p["length"]) / 2 + _fl(p["radius"])
        return np.array([[-r, -r, -h], [r, r, h]])
    r = max(_fl(p["r_bottom"]), _fl(p["r_top"]))
    h = _fl(p["height"]) / 2
    return np.array([[-r, -r, -h], [r, r, h]])


def affordances(name: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """Simple grasp hints in the primitive's frame (a starting point, not a grasp planner).

    - ``principal_axis``: unit vector along which a hand would slide: the axis of revolution,
      the tangent of a ring's arc at its middle (x), or the longest side of a box or frame.
    - ``graspable_width``: the width the fingers close across when grasping around that axis:
      the smallest bounding-box extent across the axis, or for rings and frames their bar.
    - ``front_normal``: +z, the face a robot approaches (the frame convention of DESIGN.md).
    """
    p = validate(name, params)
    lo, hi = bounds(name, p)
    extent = hi - lo
    if name in ("Cylinder", "Tube", "Capsule", "Frustum", "Sphere"):
        axis = 2
    elif name == "Ring":
        axis = 0
    else:
        axis = int(np.argmax(extent))
    width = float(min(extent[i] for i in range(3) if i != axis))
    if name == "Ring":
        width = min(_fl(p["r_out"]) - _fl(p["r_in"]), _fl(p["height"]))
    elif name == "RectRing":
        bar = (np.asarray(p["outer"]) - np.asarray(p["inner"])) / 2
        width = min(float(bar[1 - axis]), _fl(p["depth"]))
    return {
        "principal_axis": np.eye(3)[axis],
        "graspable_width": width,
        "front_normal": np.array([0.0, 0.0, 1.0]),
    }
