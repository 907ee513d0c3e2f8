"""Rotations and rigid transforms over any backend's scalars, as nested tuples.

Matrices are tuples of rows so the same code builds CasADi graphs, SymPy formulas and floats.
Conventions: right-handed; ``rpy(r, p, y) = Rz(y) Ry(p) Rx(r)`` (fixed-axis roll, pitch, yaw).
"""

from __future__ import annotations

from typing import Any

Mat = tuple[tuple[Any, ...], ...]
Vec = tuple[Any, ...]


def matmul(a: Mat, b: Mat) -> Mat:
    cols = list(zip(*b))
    return tuple(tuple(_dot(row, col) for col in cols) for row in a)


def matvec(a: Mat, v: Vec) -> Vec:
    return tuple(_dot(row, v) for row in a)


def _dot(a: Vec, b: Vec) -> Any:
    terms = [
        y if _is_one(x) else x if _is_one(y) else x * y
        for x, y in zip(a, b)
        if not (_is_zero(x) or _is_zero(y))
    ]
    if not terms:
        return 0
    total = terms[0]
    for t in terms[1:]:
        total = total + t
    return total


def _is_zero(x: Any) -> bool:
    """True only for literal Python zeros; symbolic values are never assumed zero."""
    return isinstance(x, (int, float)) and x == 0


def _is_one(x: Any) -> bool:
    return isinstance(x, (int, float)) and x == 1


def transpose(a: Mat) -> Mat:
    return tuple(zip(*a))


def identity(n: int) -> Mat:
    return tuple(tuple(1 if i == j else 0 for j in range(n)) for i in range(n))


def rot_x(c: Any, s: Any) -> Mat:
    return ((1, 0, 0), (0, c, -s), (0, s, c))


def rot_y(c: Any, s: Any) -> Mat:
    return ((c, 0, s), (0, 1, 0), (-s, 0, c))


def rot_z(c: Any, s: Any) -> Mat:
    return ((c, -s, 0), (s, c, 0), (0, 0, 1))


def axis_angle(axis: Vec, c: Any, s: Any) -> Mat:
    """Rodrigues' formula for a unit ``axis`` with cos/sin of the angle."""
    x, y, z = axis
    t = 1 - c
    return (
        (t * x * x + c, t * x * y - s * z, t * x * z + s * y),
        (t * x * y + s * z, t * y * y + c, t * y * z - s * x),
        (t * x * z - s * y, t * y * z + s * x, t * z * z + c),
    )


def pose(rot: Mat, t: Vec) -> Mat:
    return (
        (*rot[0], t[0]),
        (*rot[1], t[1]),
        (*rot[2], t[2]),
        (0, 0, 0, 1),
    )


def rotation_of(p: Mat) -> Mat:
    return tuple(tuple(row[:3]) for row in p[:3])


def translation_of(p: Mat) -> Vec:
    return tuple(row[3] for row in p[:3])


def translation(t: Vec) -> Mat:
    return pose(identity(3), t)


def invert(p: Mat) -> Mat:
    """Inverse of a rigid transform (or of a rotation, when given 3x3)."""
    if len(p) == 3:
        return transpose(p)
    rt = transpose(rotation_of(p))
    t = matvec(rt, translation_of(p))
    return pose(rt, tuple(-x for x in t))


def transform_point(p: Mat, v: Vec) -> Vec:
    r = matvec(rotation_of(p), v)
    t = translation_of(p)
    return tuple(a + b for a, b in zip(r, t))


def cross(a: Vec, b: Vec) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
