"""Validation of what a user hands the runtime: numbers, counts, poses, points.

Why one module: every entry point (instantiate, grasp, force, follow, sdf...) must turn any
Python value, however wrong (text, bytes, None, 10**400, NaN, ragged lists, dicts), into either a
float64 value or a ``ParameterError`` that says what was expected. Text is never read as a
number (numpy would happily parse ``'0.05'``).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from typing import Any

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.tolerances import EXACT, ROTATION

# Documented limits (docs/api.md): counts beyond these would take minutes or gigabytes.
MAX_GRASPS = 100_000  # inst.grasps(name, n)
MAX_SAMPLES = 1_000_000  # inst.sample_surface(n)
MAX_STEPS = 100_000  # inst.follow(..., steps)
MAX_RANK_SAMPLES = 4096  # inst.rank(..., samples)
MAX_RESOLUTION = 1024  # inst.mesh(resolution)
MAX_COORDINATE = 1e6  # metres: world points and pose translations (1000 km)

_EYE3 = np.eye(3)
_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_NUMERIC = frozenset("iuf")


def as_number(what: str, value: Any) -> float:
    """A real number as a float; bools, text, None, containers and overflowing ints are refused.
    Non-finite floats pass: the caller's range check words that error."""
    if type(value) is float:
        return value
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in _NUMERIC:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{what} takes one number, not {show_value(value)}")
    try:
        return float(value)
    except (OverflowError, TypeError, ValueError):
        raise ParameterError(f"{what} = {show_value(value)} is too large for a float") from None


def as_array(what: str, value: Any) -> np.ndarray:
    """Numbers (a scalar, a flat sequence or an array) as a flat float64 array."""
    if isinstance(value, (str, bytes, bytearray)) or value is None:
        raise ParameterError(f"{what} must be numbers, not {show_value(value)}")
    try:
        arr = np.asarray(value)
    except (ValueError, TypeError, OverflowError, RecursionError):  # ragged, too deep, odd
        raise ParameterError(f"{what} must be numbers, not {show_value(value)}") from None
    if arr.dtype.kind == "O":
        flat = arr.reshape(-1)
        arr = np.array([as_number(what, x) for x in flat.tolist()]).reshape(arr.shape)
    elif arr.dtype.kind not in _NUMERIC:
        raise ParameterError(f"{what} must be numbers, not {show_value(value)}")
    return arr.astype(np.float64, copy=False)


def merge_names(what: str, mapping: Any, keywords: dict[str, Any]) -> Mapping[str, Any]:
    """A ``params=``/``free=``/``joints=`` mapping together with keyword values: the mapping
    carries names that collide with the method's own arguments (``pose``, ``reference``...)."""
    if mapping is None:
        return keywords
    if not isinstance(mapping, Mapping):
        raise ParameterError(
            f"{what} must be a mapping {{name: value}}, not {type(mapping).__name__}"
        )
    if not keywords:
        return mapping
    both = sorted(str(k) for k in keywords if k in mapping)
    if both:
        raise ParameterError(f"{', '.join(both)} given both in {what}= and as a keyword")
    return {**mapping, **keywords}


def as_count(what: str, value: Any, least: int, most: int) -> int:
    """A whole-number argument such as ``n`` or ``steps`` in [least, most]."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{what} must be a whole number, not {show_value(value)}")
    if value < least:
        raise ParameterError(f"{what} must be at least {least}, got {value}")
    if value > most:
        raise ParameterError(
            f"{what} = {show_value(value)} is more than the limit of {most:,} (see docs/api.md, "
            "'Limits'); ask in smaller batches"
        )
    return int(value)


def as_pose(value: Any, what: str = "pose") -> np.ndarray:
    """A validated rigid 4x4 pose, a fresh array the caller owns (the identity for None)."""
    if (
        type(value) is np.ndarray
        and value.shape == (4, 4)
        and value.dtype == np.float64
        and _plainly_rigid(value.tolist())
    ):
        return value.copy()  # the common case, without a second call
    return np.eye(4) if value is None else check_pose(value, what).copy()


def check_pose(value: Any, what: str = "pose") -> np.ndarray:
    """A validated rigid 4x4 pose: a float64 array is returned as is (do not write to it)."""
    if value is None:
        return np.eye(4)
    if (
        type(value) is np.ndarray
        and value.shape == (4, 4)
        and value.dtype == np.float64
        and _plainly_rigid(value.tolist())
    ):
        return value
    m = as_array(what, value)
    if m.shape != (4, 4) or not np.all(np.isfinite(m)):
        raise ParameterError(f"{what} must be a finite 4x4 matrix, got shape {m.shape}")
    problem = rigid_problem(m)
    if problem is not None:
        raise ParameterError(f"{what} must be a rigid transform: {problem}")
    if np.abs(m[:3, 3]).max() > MAX_COORDINATE:
        raise ParameterError(_far(what))
    return m


def as_rotation(value: Any, what: str = "reference") -> np.ndarray:
    """A rotation given as a 3x3 matrix or as a 4x4 pose (its rotation is taken)."""
    m = as_array(what, value)
    if m.shape == (4, 4):
        m = m[:3, :3]
    if m.shape != (3, 3) or not np.all(np.isfinite(m)) or not _is_rotation(m):
        raise ParameterError(
            f"{what} must be a rotation (3x3, orthonormal, det +1) or a pose (4x4), e.g. the "
            f"hand's current orientation; got shape {m.shape}"
        )
    return m


def as_points(points: Any) -> np.ndarray:
    """World points as a finite float (N, 3) array within the coordinate limit."""
    pts = as_array("points", points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        hint = "; for one point use [point]" if pts.shape == (3,) else ""
        raise ParameterError(f"points must be an (N, 3) array, got shape {pts.shape}{hint}")
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise ParameterError(
            f"points must be finite: {int(bad.sum())} row(s) hold NaN or inf "
            f"(first at row {int(np.flatnonzero(bad)[0])})"
        )
    if pts.size and np.abs(pts).max() > MAX_COORDINATE:
        raise ParameterError(_far("points"))
    return pts


def rigid_problem(m: np.ndarray) -> str | None:
    """Why a finite 4x4 matrix is not a rigid transform (None when it is): the one test behind
    every pose the project accepts, from the API or the command line."""
    r = m[:3, :3]
    if np.abs(r.T @ r - _EYE3).max() > ROTATION or np.abs(m[3] - _LAST_ROW).max() > EXACT:
        return "its rotation must be orthonormal with determinant +1 and its last row 0 0 0 1"
    if np.linalg.det(r) < 0:
        return "its rotation is a mirror image (determinant -1; a rotation has determinant +1)"
    return None


def _is_rotation(r: np.ndarray) -> bool:
    return bool(np.abs(r.T @ r - _EYE3).max() < ROTATION and np.linalg.det(r) > 0)


def _far(what: str) -> str:
    return (
        f"{what}: coordinates must lie within {MAX_COORDINATE:g} m of the origin (docs/api.md, "
        "'Limits'); move the world origin closer"
    )


def _plainly_rigid(rows: list[list[float]]) -> bool:
    """The checks of ``as_pose`` in plain floats (numpy's per-call overhead is 20x the work);
    False sends the pose through the numpy checks, which decide and explain."""
    (a, b, c, x), (d, e, f, y), (g, h, i, z), last = rows
    if (
        last != [0.0, 0.0, 0.0, 1.0]
        or not math.isfinite(a + b + c + d + e + f + g + h + i + x + y + z)
        or not (
            -MAX_COORDINATE <= x <= MAX_COORDINATE
            and -MAX_COORDINATE <= y <= MAX_COORDINATE
            and -MAX_COORDINATE <= z <= MAX_COORDINATE
        )
    ):
        return False
    tol = ROTATION  # columns orthonormal: R^T R = I, and no mirror: det R = +1
    return (
        abs(a * a + d * d + g * g - 1.0) <= tol
        and abs(b * b + e * e + h * h - 1.0) <= tol
        and abs(c * c + f * f + i * i - 1.0) <= tol
        and abs(a * b + d * e + g * h) <= tol
        and abs(a * c + d * f + g * i) <= tol
        and abs(b * c + e * f + h * i) <= tol
        and a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g) > 0.0
    )


def show_value(value: Any, limit: int = 60) -> str:
    """A short repr for messages (a 10**400 or a huge list must not flood the error)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**30:
        digits = int(abs(value).bit_length() * math.log10(2))
        return f"{'-' if value < 0 else ''}~1e{digits} (an int)"
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - a broken __repr__ must not hide the real error
        text = f"a {type(value).__name__}"
    return text if len(text) <= limit else text[: limit - 3] + "..."
