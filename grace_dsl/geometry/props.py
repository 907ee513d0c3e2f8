"""Closed-form properties of the primitives: volume, bounds and simple grasp affordances."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from grace_dsl.geometry import boards
from grace_dsl.geometry.primitives import FULL_TURN, Params, validate


def _fl(v: Any) -> float:
    return float(v)


def _tapered_volume(p: Params) -> float:
    """Prismatoid rule h/6 (A_bottom + 4 A_middle + A_top): exact, the section area being
    quadratic in y; the offset shears the solid without changing its volume (Cavalieri)."""
    (sx, h, sz), (tx, tz) = p["size"], p["top"]  # type: ignore[misc]
    return h / 6 * (sx * sz + tx * tz + (sx + tx) * (sz + tz))


def cap_base_radius(radius: float, height: float) -> float:
    """Radius of the flat face of a spherical cap: sqrt(h (2R - h))."""
    return math.sqrt(max(height * (2 * radius - height), 0.0))


def prism_vertices(sides: int, radius: float) -> NDArray[np.float64]:
    """The (sides, 2) xy corners of the regular polygon with one edge centred on -y."""
    a = (2 * np.arange(sides) + 1) * math.pi / sides  # measured from -y towards +x
    return radius * np.column_stack([np.sin(a), -np.cos(a)])


VOLUMES: dict[str, Callable[[Params], float]] = {
    "BoardBox": boards.volume,
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
    "TaperedCuboid": _tapered_volume,
    "SphericalCap": lambda p: (
        math.pi * _fl(p["height"]) ** 2 * (3 * _fl(p["radius"]) - _fl(p["height"])) / 3
    ),
    "Torus": lambda p: (  # Pappus: the tube's section swept along its centre circle
        _fl(p["radian"]) * _fl(p["r_major"]) * math.pi * _fl(p["r_minor"]) ** 2
    ),
    "Prism": lambda p: (
        _fl(p["sides"])
        / 2
        * _fl(p["radius"]) ** 2
        * math.sin(FULL_TURN / _fl(p["sides"]))
        * _fl(p["height"])
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


def _tapered_bounds(p: Params) -> NDArray[np.float64]:
    (sx, h, sz), top, off = (np.asarray(p[k], dtype=float) for k in ("size", "top", "offset"))
    lo = [min(-sx / 2, off[0] - top[0] / 2), -h / 2, min(-sz / 2, off[1] - top[1] / 2)]
    hi = [max(sx / 2, off[0] + top[0] / 2), h / 2, max(sz / 2, off[1] + top[1] / 2)]
    return np.array([lo, hi])


def _cap_bounds(p: Params) -> NDArray[np.float64]:
    r, h = _fl(p["radius"]), _fl(p["height"])
    half = cap_base_radius(r, h) if h <= r else r  # past the equator the ball is widest
    return np.array([[-half, -half, -h / 2], [half, half, h / 2]])


def _torus_bounds(p: Params) -> NDArray[np.float64]:
    """The xy shadow is the annular sector R - r <= rho <= R + r (the end disks are radial)."""
    big, small = _fl(p["r_major"]), _fl(p["r_minor"])
    lo, hi = _sector_xy(big - small, big + small, _fl(p["radian"]), -math.pi / 2)
    return np.array([[lo[0], lo[1], -small], [hi[0], hi[1], small]])


def _prism_bounds(p: Params) -> NDArray[np.float64]:
    v = prism_vertices(round(_fl(p["sides"])), _fl(p["radius"]))
    h = _fl(p["height"]) / 2
    return np.array([[*v.min(axis=0), -h], [*v.max(axis=0), h]])


_BOUNDS: dict[str, Callable[[Params], NDArray[np.float64]]] = {
    "TaperedCuboid": _tapered_bounds,
    "SphericalCap": _cap_bounds,
    "Torus": _torus_bounds,
    "Prism": _prism_bounds,
}


def bounds(name: str, params: Mapping[str, Any]) -> NDArray[np.float64]:
    """The exact axis-aligned bounding box (2, 3) in the primitive's frame."""
    p = validate(name, params)
    if name in ("Cuboid", "BoardBox"):
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
    if name in _BOUNDS:
        return _BOUNDS[name](p)
    r = max(_fl(p["r_bottom"]), _fl(p["r_top"]))
    h = _fl(p["height"]) / 2
    return np.array([[-r, -r, -h], [r, r, h]])


def affordances(name: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """Simple grasp hints in the primitive's frame (a starting point, not a grasp planner).

    - ``principal_axis``: unit vector along which a hand would slide: the axis of revolution or
      of a prism, the tangent of a ring's or torus's arc at its middle (x), or the longest side
      of a box, tapered box or frame.
    - ``graspable_width``: the width the fingers close across when grasping around that axis:
      the smallest bounding-box extent across the axis (for a prism: across flats, or from a
      face to the opposite corner), or for rings, tori and frames their bar.
    - ``front_normal``: +z, the face a robot approaches (the frame convention of DESIGN.md).
    """
    p = validate(name, params)
    lo, hi = bounds(name, p)
    extent = hi - lo
    if name in ("Cylinder", "Tube", "Capsule", "Frustum", "Sphere", "SphericalCap", "Prism"):
        axis = 2
    elif name in ("Ring", "Torus"):
        axis = 0
    else:
        axis = int(np.argmax(extent))
    width = float(min(extent[i] for i in range(3) if i != axis))
    if name == "Ring":
        width = min(_fl(p["r_out"]) - _fl(p["r_in"]), _fl(p["height"]))
    elif name == "Torus":
        width = 2 * _fl(p["r_minor"])
    elif name == "RectRing":
        bar = (np.asarray(p["outer"]) - np.asarray(p["inner"])) / 2
        width = min(float(bar[1 - axis]), _fl(p["depth"]))
    return {
        "principal_axis": np.eye(3)[axis],
        "graspable_width": width,
        "front_normal": np.array([0.0, 0.0, 1.0]),
    }
