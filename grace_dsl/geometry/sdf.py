"""Signed distances of the primitives, negative inside, written once for numpy and CasADi.

Each formula is a function of an ``Ops`` backend (numpy arrays or CasADi expressions) so the
two versions cannot drift apart; the CasADi one is differentiable in the parameters, which the
model fitting needs. All distances are exact (Inigo Quilez's closed forms, adapted to the frames
of ``primitives.eac``): boxes, spheres, capsules, capped cones, and 2D cross-sections (disk,
circular sector, annulus, annular sector, box-minus-box) extruded exactly along z.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from grace_dsl.geometry.errors import GeometryError
from grace_dsl.geometry.primitives import FULL_TURN, check_names, validate

_FULL_TOL = 1e-9  # a sector within this of a full turn is the full solid (no seam)


class NumpyOps:
    """Elementwise operations on numpy arrays."""

    max = staticmethod(np.maximum)
    min = staticmethod(np.minimum)
    abs = staticmethod(np.abs)
    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sign = staticmethod(np.sign)
    where = staticmethod(np.where)

    @staticmethod
    def sqrt0(s: Any) -> Any:
        """sqrt of a value that is >= 0 (clamped against round-off)."""
        return np.sqrt(np.maximum(s, 0.0))

    @staticmethod
    def clip(a: Any, lo: Any, hi: Any) -> Any:
        return np.minimum(np.maximum(a, lo), hi)


class CasadiOps:
    """The same operations as CasADi expressions; no Python branch looks at a symbolic value."""

    max = staticmethod(ca.fmax)
    min = staticmethod(ca.fmin)
    abs = staticmethod(ca.fabs)
    sin = staticmethod(ca.sin)
    cos = staticmethod(ca.cos)
    sign = staticmethod(ca.sign)
    where = staticmethod(ca.if_else)

    @staticmethod
    def sqrt0(s: Any) -> Any:
        """sqrt whose derivative is 0, not NaN, at s = 0 (interior points of extrusions)."""
        return ca.if_else(s > 0, ca.sqrt(ca.fmax(s, 0)), 0)

    @staticmethod
    def clip(a: Any, lo: Any, hi: Any) -> Any:
        return ca.fmin(ca.fmax(a, lo), hi)


Ops = Any  # NumpyOps or CasadiOps: the same static methods
Formula = Callable[[Ops, Any, Any, Any, Mapping[str, Any]], Any]


def _norm(o: Ops, *xs: Any) -> Any:
    return o.sqrt0(sum(x * x for x in xs))


def _extrude(o: Ops, d2: Any, z: Any, half: Any) -> Any:
    """Exact 3D distance of a 2D cross-section (exact distance ``d2``) extruded over |z| <= half."""
    wz = o.abs(z) - half
    return o.min(o.max(d2, wz), 0) + _norm(o, o.max(d2, 0), o.max(wz, 0))


def _box2(o: Ops, x: Any, y: Any, hx: Any, hy: Any) -> Any:
    qx, qy = o.abs(x) - hx, o.abs(y) - hy
    return _norm(o, o.max(qx, 0), o.max(qy, 0)) + o.min(o.max(qx, qy), 0)


def _annular_sector(o: Ops, x: Any, u: Any, r_in: Any, r_out: Any, half: Any) -> Any:
    """2D annular sector about the axis ``u`` (half-angle ``half`` <= pi); r_in = 0 gives a pie.

    Exact: the annulus distance, or (folded to x >= 0) the distance to the straight end cap
    ``[r_in, r_out] * (sin half, cos half)``, signed by the side of the cap's line.
    """
    rc, w = (r_in + r_out) / 2, (r_out - r_in) / 2
    annulus = o.abs(_norm(o, x, u) - rc) - w
    ax, sa, co = o.abs(x), o.sin(half), o.cos(half)
    s = co * ax - sa * u  # > 0 beyond the cap's line, outside the wedge
    t = sa * ax + co * u  # position along the cap
    cap = _norm(o, s, o.max(o.abs(t - rc) - w, 0)) * o.sign(s)
    return o.max(annulus, cap)


def _cuboid(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    size = p["size"]
    qx, qy, qz = o.abs(x) - size[0] / 2, o.abs(y) - size[1] / 2, o.abs(z) - size[2] / 2
    outside = _norm(o, o.max(qx, 0), o.max(qy, 0), o.max(qz, 0))
    return outside + o.min(o.max(qx, o.max(qy, qz)), 0)


def _cylinder(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    r, ang = p["radius"], p["radian"]
    disk = _norm(o, x, y) - r
    pie = _annular_sector(o, x, y, 0.0, r, o.min(ang, FULL_TURN) / 2)  # symmetric about +y
    return _extrude(o, o.where(ang >= FULL_TURN - _FULL_TOL, disk, pie), z, p["height"] / 2)


def _tube(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    rc, w = (p["r_in"] + p["r_out"]) / 2, (p["r_out"] - p["r_in"]) / 2
    return _extrude(o, o.abs(_norm(o, x, y) - rc) - w, z, p["height"] / 2)


def _ring(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    r_in, r_out, ang = p["r_in"], p["r_out"], p["radian"]
    rc, w = (r_in + r_out) / 2, (r_out - r_in) / 2
    annulus = o.abs(_norm(o, x, y) - rc) - w
    sector = _annular_sector(o, x, -y, r_in, r_out, o.min(ang, FULL_TURN) / 2)  # arc on -y
    d2 = o.where(ang >= FULL_TURN - _FULL_TOL, annulus, sector)
    return _extrude(o, d2, z, p["height"] / 2)


def _rect_ring(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    out, inn = p["outer"], p["inner"]
    d2 = o.max(_box2(o, x, y, out[0] / 2, out[1] / 2), -_box2(o, x, y, inn[0] / 2, inn[1] / 2))
    return _extrude(o, d2, z, p["depth"] / 2)


def _sphere(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    return _norm(o, x, y, z) - p["radius"]


def _capsule(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    h = p["length"] / 2
    return _norm(o, x, y, z - o.clip(z, -h, h)) - p["radius"]


def _frustum(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    """Quilez's exact capped cone: nearest of the end disks (``a``) and the slanted side (``b``)."""
    r1, r2, h = p["r_bottom"], p["r_top"], p["height"] / 2
    rho = _norm(o, x, y)
    ax = rho - o.min(rho, o.where(z < 0, r1, r2))
    ay = o.abs(z) - h
    k2x, k2y = r2 - r1, 2 * h
    t = o.clip(((r2 - rho) * k2x + (h - z) * k2y) / (k2x * k2x + k2y * k2y), 0, 1)
    bx, by = rho - r2 + k2x * t, z - h + k2y * t
    sign = o.where(o.max(bx, ay) < 0, -1.0, 1.0)
    return sign * o.sqrt0(o.min(ax * ax + ay * ay, bx * bx + by * by))


FORMULAS: dict[str, Formula] = {
    "Cuboid": _cuboid,
    "Cylinder": _cylinder,
    "Tube": _tube,
    "Ring": _ring,
    "RectRing": _rect_ring,
    "Sphere": _sphere,
    "Capsule": _capsule,
    "Frustum": _frustum,
}


def as_points(points: ArrayLike) -> NDArray[np.float64]:
    """``points`` as a finite (N, 3) float array, or a :class:`GeometryError`."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim == 1 and pts.shape == (3,):
        pts = pts[None, :]
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise GeometryError(f"points must have shape (N, 3), got {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise GeometryError("points must be finite (found NaN or inf)")
    return pts


def primitive_sdf(name: str, params: Mapping[str, Any], points: ArrayLike) -> NDArray[np.float64]:
    """Exact signed distance (N,) of ``points`` (N, 3) in the primitive frame, negative inside."""
    p = validate(name, params)
    pts = as_points(points)
    with np.errstate(invalid="ignore", divide="ignore"):
        d = FORMULAS[name](NumpyOps, pts[:, 0], pts[:, 1], pts[:, 2], p)
    return np.asarray(d, dtype=float)


def primitive_sdf_casadi(name: str, params: Mapping[str, Any], p: Any) -> Any:
    """The same exact distance as a CasADi expression of a 3-vector ``p`` and the parameters.

    ``params`` maps names to floats or CasADi SX/MX (vectors as 2/3-vectors or lists); missing
    ones take their defaults. Numeric values are validated; symbolic ones cannot be.
    """
    check_names(name, params)
    numeric = {k: v for k, v in params.items() if not isinstance(v, ca.SX | ca.MX)}
    full: dict[str, Any] = dict(validate(name, numeric))
    full.update({k: v for k, v in params.items() if k not in numeric})
    if (p.numel() if hasattr(p, "numel") else len(p)) != 3:
        raise GeometryError(f"p must be a CasADi 3-vector, got {p!r}")
    return FORMULAS[name](CasadiOps, p[0], p[1], p[2], full)
