"""Signed distances of the primitives, negative inside, written once for numpy and CasADi.

Each formula is a function of an ``Ops`` backend (numpy arrays or CasADi expressions) so the
two versions cannot drift apart; the CasADi one is differentiable in the parameters, which the
model fitting needs. All distances are exact (Inigo Quilez's closed forms, adapted to the frames
of ``primitives.eac``): boxes, spheres, capsules, capped cones, spherical caps, torus segments,
2D cross-sections (disk, circular sector, annulus, annular sector, box-minus-box, regular
polygon) extruded exactly along z, the tapered box as a convex polytope (nearest face, edge
or corner), and the board box as its outer box minus its cavity inside, its nearest board outside
(``grace_dsl.geometry.boards``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from grace_dsl.geometry import boards
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
    atan2 = staticmethod(np.arctan2)
    floor = staticmethod(np.floor)

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
    atan2 = staticmethod(ca.atan2)
    floor = staticmethod(ca.floor)

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


def _sphere_cap(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    """The ball above the plane z' = c = R - h (z' from the ball's centre, at z = h/2 - R).

    The solid is convex, so its distance is the distance to whichever of ball and plane owns the
    projection: ``max(|q| - R, c - z')`` unless the point lies in the rim circle's normal cone
    (beyond the rim: rho > w and c rho - w z' > 0), where it is the distance to the rim.
    """
    big, h = p["radius"], p["height"]
    c = big - h
    w = o.sqrt0(h * (2 * big - h))  # radius of the flat face
    zc = z - h / 2 + big
    rho = _norm(o, x, y)
    rim = _norm(o, rho - w, zc - c)
    body = o.max(_norm(o, rho, zc) - big, c - zc)
    return o.where(o.min(rho - w, c * rho - w * zc) > 0, rim, body)


def _torus(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    """A torus about z cut to the wedge ``radian`` centred on -y by two planes through the axis.

    Like the annular sector: max of the whole torus and the signed distance to the nearer end
    disk (folded to x >= 0), which lies in the half-plane of direction (sin half, cos half)
    about -y: ``s`` is the distance beyond that plane, ``t`` the position along it.
    """
    big, small, ang = p["r_major"], p["r_minor"], p["radian"]
    torus = _norm(o, _norm(o, x, y) - big, z) - small
    half = o.min(ang, FULL_TURN) / 2
    ax, u, sa, co = o.abs(x), -y, o.sin(half), o.cos(half)
    s = co * ax - sa * u
    t = sa * ax + co * u
    disk = o.max(_norm(o, t - big, z) - small, 0)  # distance within the end's plane
    cap = _norm(o, s, disk) * o.sign(s)
    return o.where(ang >= FULL_TURN - _FULL_TOL, torus, o.max(torus, cap))


def _polygon(o: Ops, x: Any, y: Any, n: Any, r: Any) -> Any:
    """Quilez's exact regular n-gon of circumradius r, turned so that an edge is centred on -y:
    fold the angle from -y into one edge's sector, then the distance to that edge segment."""
    an = np.pi / n
    theta = o.atan2(x, -y) + an + FULL_TURN  # > 0, so floor splits it into sectors
    bn = theta - 2 * an * o.floor(theta / (2 * an)) - an  # in [-an, an), 0 at an edge's middle
    rho = _norm(o, x, y)
    px = rho * o.cos(bn) - r * o.cos(an)
    py = rho * o.abs(o.sin(bn)) - r * o.sin(an)
    py = py + o.clip(-py, 0, r * o.sin(an))
    return _norm(o, px, py) * o.sign(px)


def _prism(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    return _extrude(o, _polygon(o, x, y, p["sides"], p["radius"]), z, p["height"] / 2)


Vec3 = tuple[Any, Any, Any]


def _sub(a: Vec3, b: Vec3) -> Vec3:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _dot(a: Vec3, b: Vec3) -> Any:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _fold(op: Callable[[Any, Any], Any], values: list[Any]) -> Any:
    out = values[0]
    for v in values[1:]:
        out = op(out, v)
    return out


def _segment(o: Ops, q: Vec3, a: Vec3, b: Vec3) -> Any:
    """Distance from q to the segment ab (a point when a == b)."""
    e, v = _sub(b, a), _sub(q, a)
    t = o.clip(_dot(v, e) / o.max(_dot(e, e), 1e-300), 0, 1)
    return _norm(o, v[0] - t * e[0], v[1] - t * e[1], v[2] - t * e[2])


# The faces of the tapered box as corner indices (i = x-sign, j = z-sign, k = 0 bottom / 1 top),
# counter-clockwise seen from outside, and the unit outward normals' index in ``_taper_faces``.
TAPER_FACES = (
    ((1, -1, 0), (1, -1, 1), (1, 1, 1), (1, 1, 0)),  # +x
    ((-1, -1, 0), (-1, 1, 0), (-1, 1, 1), (-1, -1, 1)),  # -x
    ((-1, -1, 1), (-1, 1, 1), (1, 1, 1), (1, -1, 1)),  # top (+y)
    ((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)),  # bottom (-y)
    ((-1, 1, 0), (1, 1, 0), (1, 1, 1), (-1, 1, 1)),  # +z
    ((-1, -1, 0), (-1, -1, 1), (1, -1, 1), (1, -1, 0)),  # -z
)


def taper_corners(p: Mapping[str, Any]) -> dict[tuple[int, int, int], Vec3]:
    """The eight corners: the bottom rectangle ``size.x`` by ``size.z`` at y = -size.y/2 and the
    top one ``top`` at y = +size.y/2, shifted by ``offset`` (x, z)."""
    size, top, off = p["size"], p["top"], p["offset"]
    out: dict[tuple[int, int, int], Vec3] = {}
    for i in (-1, 1):
        for j in (-1, 1):
            out[(i, j, 0)] = (i * size[0] / 2, -size[1] / 2, j * size[2] / 2)
            out[(i, j, 1)] = (off[0] + i * top[0] / 2, size[1] / 2, off[1] + j * top[1] / 2)
    return out


def taper_normals(o: Ops, p: Mapping[str, Any]) -> tuple[Vec3, ...]:
    """Unit outward normals of the faces of ``TAPER_FACES``; a side face through the bottom edge at
    x = size.x/2 and the top edge at x = offset.x + top.x/2 leans by a = top edge - bottom edge:
    its normal is (h, -a) / |(h, a)| in (x, y), and likewise for -x and the z sides."""
    size, top, off = p["size"], p["top"], p["offset"]
    h = size[1]
    out = []
    for axis in (0, 2):
        t, c = top[0 if axis == 0 else 1], off[0 if axis == 0 else 1]
        for sign in (1, -1):
            lean = sign * c + t / 2 - size[axis] / 2
            n = _norm(o, h, lean)
            v = [0.0, -lean / n, 0.0]
            v[axis] = sign * h / n
            out.append((v[0], v[1], v[2]))
        if axis == 0:
            out += [(0.0, 1.0, 0.0), (0.0, -1.0, 0.0)]
    return tuple(out)


def _tapered_cuboid(o: Ops, x: Any, y: Any, z: Any, p: Mapping[str, Any]) -> Any:
    """Exact distance to a convex polytope: inside, the nearest face plane (max of the planes);
    outside, the nearest face if the point projects into it, else the nearest edge."""
    corners, normals, q = taper_corners(p), taper_normals(o, p), (x, y, z)
    edges: dict[frozenset[tuple[int, int, int]], Any] = {}
    planes, faces = [], []
    top = p["top"]
    for f, (quad, n) in enumerate(zip(TAPER_FACES, normals)):
        plane = _dot(n, _sub(q, corners[quad[0]]))
        sides, rims = [], []
        for a, b in zip(quad, quad[1:] + quad[:1]):
            sides.append(_dot(_cross(n, _sub(corners[b], corners[a])), _sub(q, corners[a])))
            key = frozenset((a, b))
            if key not in edges:
                edges[key] = _segment(o, q, corners[a], corners[b])
            rims.append(edges[key])
        inside, rim = _fold(o.min, sides), _fold(o.min, rims)
        if f == 2:  # a top of no width and no depth is a point: every edge test passes
            inside = o.where(top[0] + top[1] > 0, inside, -1.0)
        planes.append(plane)
        faces.append(o.where(inside >= 0, o.abs(plane), rim))
    deepest = _fold(o.max, planes)
    return o.where(deepest > 0, _fold(o.min, faces), deepest)


FORMULAS: dict[str, Formula] = {
    "Cuboid": _cuboid,
    "Cylinder": _cylinder,
    "Tube": _tube,
    "Ring": _ring,
    "RectRing": _rect_ring,
    "Sphere": _sphere,
    "Capsule": _capsule,
    "Frustum": _frustum,
    "TaperedCuboid": _tapered_cuboid,
    "SphericalCap": _sphere_cap,
    "Torus": _torus,
    "Prism": _prism,
    "BoardBox": boards.sdf,
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
