"""Affordance cues of shapes: what an author may read off a shape by name (``bar.principal_axis``).

A cue is computed from the shape's primitive arguments and its placement ``at``, in the frame of
the concept that declares it (which coincides with the shape's link frame at q = 0, so a grasp
on that link may use it directly).  The formulas are written once against the backend
interface, so CasADi, SymPy and NumPy agree, and they match ``grace_dsl.geometry.affordances``
for the primitives whose hints are defined the same way there.

- ``pose``: the shape's placement; ``center``: its origin.
- ``front_normal``: +z of the shape, the face a robot approaches.
- ``principal_axis``: the direction a hand would slide along: the axis of revolution, the tangent
  of a ring's arc at its middle, or the longest side of a box or frame.
- ``graspable_width``: the width fingers close across when grasping around that axis.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from grace_dsl.compiler import se3
from grace_dsl.compiler import types as T
from grace_dsl.compiler.backends import Backend
from grace_dsl.lang import ast

CUE_TYPES: dict[str, T.Type] = {
    "pose": T.POSE,
    "center": T.vec(3, T.LENGTH),
    "front_normal": T.vec(3),
    "principal_axis": T.vec(3),
    "graspable_width": T.num(T.LENGTH),
}
PLACEMENT_CUES = ("pose", "center", "front_normal")  # defined for unions and differences too

Vec = tuple[Any, Any, Any]
Hint = Callable[[Backend, dict[str, Any]], tuple[Vec, Any]]  # (axis, width) in the shape frame

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def _longest_side(b: Backend, size: Any) -> Vec:
    """The unit axis of the largest of three extents (x wins ties, then y)."""
    sx, sy, sz = size
    x_first = b.and_(b.compare(">=", sx, sy), b.compare(">=", sx, sz))
    y_next = b.compare(">=", sy, sz)
    return tuple(b.if_else(x_first, X[i], b.if_else(y_next, Y[i], Z[i])) for i in range(3))


def _cuboid(b: Backend, a: dict[str, Any]) -> tuple[Vec, Any]:
    sx, sy, sz = a["size"]
    return _longest_side(b, a["size"]), b.min(sx, b.min(sy, sz))


def _rect_ring(b: Backend, a: dict[str, Any]) -> tuple[Vec, Any]:
    (ox, oy), (ix, iy) = a["outer"], a["inner"]
    along_x = b.compare(">=", ox, oy)
    axis = tuple(b.if_else(along_x, X[i], Y[i]) for i in range(3))
    bar = b.if_else(along_x, (oy - iy) / 2, (ox - ix) / 2)
    return axis, b.min(bar, a["depth"])


def _spherical_cap(b: Backend, a: dict[str, Any]) -> tuple[Vec, Any]:
    """Across the axis: the flat face's diameter, or the ball's once the cap passes its equator."""
    r, h = a["radius"], a["height"]
    face = 2 * b.sqrt(b.max(h * (2 * r - h), 0.0))
    return Z, b.if_else(b.compare(">=", h, r), 2 * r, face)


def _tapered_cuboid(b: Backend, a: dict[str, Any]) -> tuple[Vec, Any]:
    """Like a box, over the bounding box of the bottom and the shifted top face."""
    (sx, h, sz), (tx, tz), (ox, oz) = a["size"], a["top"], a["offset"]
    ex = b.max(sx / 2, ox + tx / 2) - b.min(-sx / 2, ox - tx / 2)
    ez = b.max(sz / 2, oz + tz / 2) - b.min(-sz / 2, oz - tz / 2)
    return _longest_side(b, (ex, h, ez)), b.min(ex, b.min(h, ez))


def _prism(b: Backend, a: dict[str, Any]) -> tuple[Vec, Any]:
    """From the face on -y to the opposite face (even sides) or corner (odd): cos(pi n) is the
    parity (-1)^n of the whole number n, so the width needs no branch."""
    n, r = a["sides"], a["radius"]
    apothem, even = r * b.cos(b.pi / n), (1 + b.cos(b.pi * n)) / 2
    return Z, apothem + even * apothem + (1 - even) * r


HINTS: dict[str, Hint] = {
    "Cuboid": _cuboid,
    "RectRing": _rect_ring,
    "Cylinder": lambda b, a: (Z, 2 * a["radius"]),
    "Tube": lambda b, a: (Z, 2 * a["r_out"]),
    "Sphere": lambda b, a: (Z, 2 * a["radius"]),
    "Capsule": lambda b, a: (Z, 2 * a["radius"]),
    "Frustum": lambda b, a: (Z, 2 * b.max(a["r_bottom"], a["r_top"])),
    "Ring": lambda b, a: (X, b.min(a["r_out"] - a["r_in"], a["height"])),
    "Torus": lambda b, a: (X, 2 * a["r_minor"]),
    "SphericalCap": _spherical_cap,
    "TaperedCuboid": _tapered_cuboid,
    "Prism": _prism,
}


def has_cue(primitive: str, field: str) -> bool:
    """Whether shapes made with ``primitive`` (or ``union``/``difference``) have cue ``field``."""
    return field in PLACEMENT_CUES or (field in CUE_TYPES and primitive in HINTS)


def cue(b: Backend, primitive: str, args: dict[str, Any], placement: Any, field: str) -> Any:
    """The value of cue ``field`` for a shape placed at ``placement`` (4x4, concept frame)."""
    rot = se3.rotation_of(placement)
    if field == "pose":
        return placement
    if field == "center":
        return se3.translation_of(placement)
    if field == "front_normal":
        return se3.matvec(rot, Z)
    axis, width = HINTS[primitive](b, args)
    return se3.matvec(rot, axis) if field == "principal_axis" else width


def shape_cue(
    b: Backend,
    ev: Callable[[ast.Expr], Any],
    shape: ast.Shape,
    defaults: dict[str, Any],
    field: str,
) -> Any:
    """Cue ``field`` of a declared shape, its arguments and placement evaluated by ``ev``
    (``defaults``: the primitive's parameter defaults, for arguments the shape leaves out)."""
    call = shape.value
    assert isinstance(call, ast.Call)
    placement = se3.identity(4) if shape.at is None else ev(shape.at)
    if len(placement) == 3:  # a rotation placed at the origin
        placement = se3.pose(placement, (0.0, 0.0, 0.0))
    args: dict[str, Any] = {}
    if call.func not in ("union", "difference"):
        args = {**defaults, **{a.name: ev(a.value) for a in call.args if a.name is not None}}
    return cue(b, call.func, args, placement, field)
