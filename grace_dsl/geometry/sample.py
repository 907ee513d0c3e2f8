"""Area-weighted surface samples with exact normals, drawn face by face from the analytic surface.

Sampling the mesh would put points on chords of curved faces (off the true surface by up to
r(1 - cos(pi/n))); here every face type (rectangle, triangle, annular sector, cylinder side,
sphere, spherical zone, cone side, torus) is sampled in closed form, so |sdf| of a sample is
round-off.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from grace_dsl.geometry import boards
from grace_dsl.geometry.errors import GeometryError
from grace_dsl.geometry.primitives import FULL_TURN, Params, validate
from grace_dsl.geometry.props import cap_base_radius, prism_vertices
from grace_dsl.geometry.sdf import TAPER_FACES, NumpyOps, taper_corners, taper_normals

Arr = NDArray[np.float64]
Draw = Callable[[np.random.Generator, int], tuple[Arr, Arr]]
Patch = tuple[float, Draw]  # (area, draw k points with their outward normals)
_FULL_TOL = 1e-9


def _rect(origin: Any, e1: Any, e2: Any, normal: Any) -> Patch:
    o, a, b, nrm = (np.asarray(v, dtype=float) for v in (origin, e1, e2, normal))

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        uv = rng.random((k, 2))
        return o + uv[:, :1] * a + uv[:, 1:] * b, np.tile(nrm, (k, 1))

    return float(np.linalg.norm(a) * np.linalg.norm(b)), draw


def _triangle(a: Any, b: Any, c: Any, normal: Any) -> Patch:
    """A flat triangle; folding the unit square onto it keeps the density uniform."""
    o, e1, e2, nrm = (
        np.asarray(v, dtype=float) for v in (a, np.subtract(b, a), np.subtract(c, a), normal)
    )

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        uv = rng.random((k, 2))
        flip = uv.sum(axis=1) > 1
        uv[flip] = 1 - uv[flip]
        return o + uv[:, :1] * e1 + uv[:, 1:] * e2, np.tile(nrm, (k, 1))

    return float(np.linalg.norm(np.cross(e1, e2)) / 2), draw


def _sector_cap(r_in: float, r_out: float, a0: float, span: float, z: float, nz: float) -> Patch:
    """A flat annular sector (angles a0..a0+span from +x) at height z, normal (0, 0, nz)."""

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        r = np.sqrt(rng.uniform(r_in**2, r_out**2, k))
        a = a0 + span * rng.random(k)
        pts = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(k, z)])
        return pts, np.tile([0.0, 0.0, nz], (k, 1))

    return span / 2 * (r_out**2 - r_in**2), draw


def _cyl_side(r: float, a0: float, span: float, h: float, sign: float) -> Patch:
    """Cylinder wall of radius r over |z| <= h/2; normals point out (sign=1) or to the axis (-1)."""

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        a = a0 + span * rng.random(k)
        c, s = np.cos(a), np.sin(a)
        pts = np.column_stack([r * c, r * s, h * (rng.random(k) - 0.5)])
        return pts, sign * np.column_stack([c, s, np.zeros(k)])

    return r * span * h, draw


def _ball(r: float, zc: float, half: float) -> Patch:
    """Sphere of radius r centred at (0, 0, zc); ``half`` = +1/-1 keeps only that z-hemisphere."""

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        d = rng.normal(size=(k, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        if half:
            d[:, 2] = half * np.abs(d[:, 2])
        return d * r + [0.0, 0.0, zc], d

    return (2.0 if half else 4.0) * math.pi * r * r, draw


def _cone_side(r1: float, r2: float, h: float) -> Patch:
    """Lateral frustum surface; area density grows with radius, so r^2 is drawn uniformly."""
    slant = math.hypot(r2 - r1, h)
    n_r, n_z = h / slant, (r1 - r2) / slant

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        if abs(r2 - r1) > 1e-12 * max(r1, r2):
            r = np.sqrt(r1 * r1 + (r2 * r2 - r1 * r1) * rng.random(k))
            t = (r - r1) / (r2 - r1)
        else:
            t = rng.random(k)
            r = r1 + (r2 - r1) * t
        a = FULL_TURN * rng.random(k)
        c, s = np.cos(a), np.sin(a)
        pts = np.column_stack([r * c, r * s, h * (t - 0.5)])
        return pts, np.column_stack([n_r * c, n_r * s, np.full(k, n_z)])

    return math.pi * (r1 + r2) * slant, draw


def _zone(r: float, zc: float, z_lo: float) -> Patch:
    """The sphere of radius r centred at (0, 0, zc) above z = z_lo: Archimedes' hat-box theorem
    makes the area uniform in z, so z and the azimuth are drawn uniformly."""
    lo = max(-1.0, min(1.0, (z_lo - zc) / r))

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        c = rng.uniform(lo, 1.0, k)
        s = np.sqrt(np.maximum(1 - c * c, 0.0))
        a = FULL_TURN * rng.random(k)
        d = np.column_stack([s * np.cos(a), s * np.sin(a), c])
        return d * r + [0.0, 0.0, zc], d

    return FULL_TURN * r * r * (1 - lo), draw


def _torus_side(big: float, small: float, a0: float, span: float) -> Patch:
    """The tube's surface over the arc a0..a0+span; the area element r (R + r cos v) du dv is
    drawn by rejection (acceptance >= (R - r) / (R + r)), repeating until k points are kept."""

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        v = np.empty(0)
        while len(v) < k:
            cand = FULL_TURN * rng.random(2 * (k - len(v)) + 8)
            keep = rng.random(len(cand)) * (big + small) < big + small * np.cos(cand)
            v = np.concatenate([v, cand[keep]])
        v = v[:k]
        u = a0 + span * rng.random(k)
        d = np.column_stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)])
        centre = big * np.column_stack([np.cos(u), np.sin(u), np.zeros(k)])
        return centre + small * d, d

    return span * FULL_TURN * small * big, draw


def _torus_end(big: float, small: float, a: float, sign: float) -> Patch:
    """The disk closing a torus segment at arc angle a; normal ``sign`` * d/du (tangent)."""
    radial, tangent = (
        np.array([math.cos(a), math.sin(a), 0.0]),
        np.array([-math.sin(a), math.cos(a), 0.0]),
    )

    def draw(rng: np.random.Generator, k: int) -> tuple[Arr, Arr]:
        rho = small * np.sqrt(rng.random(k))
        t = FULL_TURN * rng.random(k)
        pts = (big + rho * np.cos(t))[:, None] * radial + np.outer(rho * np.sin(t), [0.0, 0.0, 1.0])
        return pts, np.tile(sign * tangent, (k, 1))

    return math.pi * small * small, draw


def _torus(p: Params) -> list[Patch]:
    big, small, ang = _fl(p["r_major"]), _fl(p["r_minor"]), _fl(p["radian"])
    a0 = -math.pi / 2 - ang / 2
    patches = [_torus_side(big, small, a0, ang)]
    if ang < FULL_TURN - _FULL_TOL:
        patches += [_torus_end(big, small, a0, -1.0), _torus_end(big, small, a0 + ang, 1.0)]
    return patches


def _spherical_cap(p: Params) -> list[Patch]:
    r, h = _fl(p["radius"]), _fl(p["height"])
    return [
        _zone(r, h / 2 - r, -h / 2),
        _sector_cap(0.0, cap_base_radius(r, h), 0.0, FULL_TURN, -h / 2, -1.0),
    ]


def _tapered_cuboid(p: Params) -> list[Patch]:
    """Each planar face (a trapezoid; a triangle or segment where the top has no width) as two
    triangles, with the formula's own unit normals."""
    corners, normals = taper_corners(p), taper_normals(NumpyOps, p)
    out = []
    for quad, nrm in zip(TAPER_FACES, normals):
        a, b, c, d = (corners[k] for k in quad)
        out += [_triangle(a, b, c, nrm), _triangle(a, c, d, nrm)]
    return out


def _prism(p: Params) -> list[Patch]:
    h = _fl(p["height"])
    v = prism_vertices(round(_fl(p["sides"])), _fl(p["radius"]))
    out = []
    for k in range(len(v)):
        a, b = v[k], v[(k + 1) % len(v)]
        for z, nz in ((h / 2, 1.0), (-h / 2, -1.0)):
            out.append(_triangle([0.0, 0.0, z], [*a, z], [*b, z], [0.0, 0.0, nz]))
        edge = b - a
        nrm = np.array([edge[1], -edge[0], 0.0]) / np.linalg.norm(edge)  # vertices go CCW
        out.append(_rect([*a, -h / 2], [*edge, 0.0], [0.0, 0.0, h], nrm))
    return out


def _prism_of_sector(r_in: float, r_out: float, ang: float, axis: float, h: float) -> list[Patch]:
    """Faces of an annular sector (r_in may be 0) of angle ``ang`` centred on ``axis``."""
    a0 = axis - ang / 2
    patches = [
        _sector_cap(r_in, r_out, a0, ang, h / 2, 1.0),
        _sector_cap(r_in, r_out, a0, ang, -h / 2, -1.0),
        _cyl_side(r_out, a0, ang, h, 1.0),
    ]
    if r_in > 0:
        patches.append(_cyl_side(r_in, a0, ang, h, -1.0))
    if ang < FULL_TURN - _FULL_TOL:
        for a, sign in ((a0, -1.0), (a0 + ang, 1.0)):
            d = np.array([math.cos(a), math.sin(a), 0.0])
            nrm = sign * np.array([-d[1], d[0], 0.0])
            patches.append(_rect(r_in * d + [0, 0, -h / 2], (r_out - r_in) * d, [0, 0, h], nrm))
    return patches


def _cuboid(p: Params) -> list[Patch]:
    s = np.asarray(p["size"], dtype=float)
    out = []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        ej, ek = np.eye(3)[j] * s[j], np.eye(3)[k] * s[k]
        for sign in (1.0, -1.0):
            nrm = sign * np.eye(3)[i]
            out.append(_rect(nrm * s[i] / 2 - ej / 2 - ek / 2, ej, ek, nrm))
    return out


def _rect_ring(p: Params) -> list[Patch]:
    (ox, oy), (ix, iy), d = p["outer"], p["inner"], _fl(p["depth"])  # type: ignore[misc]
    out = []
    for z, nz in ((d / 2, 1.0), (-d / 2, -1.0)):  # each face: two full-width bars, two short ones
        for sy in (1.0, -1.0):
            out.append(
                _rect(
                    [-ox / 2, sy * iy / 2 if sy > 0 else -oy / 2, z],
                    [ox, 0, 0],
                    [0, (oy - iy) / 2, 0],
                    [0, 0, nz],
                )
            )
        for sx in (1.0, -1.0):
            out.append(
                _rect(
                    [ix / 2 if sx > 0 else -ox / 2, -iy / 2, z],
                    [(ox - ix) / 2, 0, 0],
                    [0, iy, 0],
                    [0, 0, nz],
                )
            )
    for (hx, hy), sign in (((ox / 2, oy / 2), 1.0), ((ix / 2, iy / 2), -1.0)):
        for s in (1.0, -1.0):
            out.append(_rect([s * hx, -hy, -d / 2], [0, 2 * hy, 0], [0, 0, d], [sign * s, 0, 0]))
            out.append(_rect([-hx, s * hy, -d / 2], [2 * hx, 0, 0], [0, 0, d], [0, sign * s, 0]))
    return out


def _fl(v: Any) -> float:
    return float(v)


def _frustum(p: Params) -> list[Patch]:
    r1, r2, h = _fl(p["r_bottom"]), _fl(p["r_top"]), _fl(p["height"])
    caps = [
        _sector_cap(0.0, r, 0.0, FULL_TURN, z, nz)
        for r, z, nz in ((r1, -h / 2, -1.0), (r2, h / 2, 1.0))
        if r > 0
    ]
    return caps + [_cone_side(r1, r2, h)]


PATCHES: dict[str, Callable[[Params], list[Patch]]] = {
    "Cuboid": _cuboid,
    "Cylinder": lambda p: _prism_of_sector(
        0.0, _fl(p["radius"]), _fl(p["radian"]), math.pi / 2, _fl(p["height"])
    ),
    "Tube": lambda p: _prism_of_sector(
        _fl(p["r_in"]), _fl(p["r_out"]), FULL_TURN, 0.0, _fl(p["height"])
    ),
    "Ring": lambda p: _prism_of_sector(
        _fl(p["r_in"]), _fl(p["r_out"]), _fl(p["radian"]), -math.pi / 2, _fl(p["height"])
    ),
    "RectRing": _rect_ring,
    "Sphere": lambda p: [_ball(_fl(p["radius"]), 0.0, 0.0)],
    "Capsule": lambda p: [
        _cyl_side(_fl(p["radius"]), 0.0, FULL_TURN, _fl(p["length"]), 1.0),
        _ball(_fl(p["radius"]), _fl(p["length"]) / 2, 1.0),
        _ball(_fl(p["radius"]), -_fl(p["length"]) / 2, -1.0),
    ],
    "Frustum": _frustum,
    "TaperedCuboid": _tapered_cuboid,
    "SphericalCap": _spherical_cap,
    "Torus": _torus,
    "Prism": _prism,
    "BoardBox": lambda p: [_rect(o, u, v, n) for o, u, v, n in boards.faces(p)],
}


def surface_area(name: str, params: Mapping[str, Any]) -> float:
    """The analytic surface area (the sum of the sampled faces)."""
    return sum(area for area, _ in PATCHES[name](validate(name, params)))


def sample_surface(
    name: str, params: Mapping[str, Any], n: int, seed: int | np.random.Generator = 0
) -> tuple[Arr, Arr]:
    """``n`` points uniformly (by area) on the exact surface and their outward unit normals.

    The same seed gives the same samples; the order is shuffled so any prefix is uniform too.
    """
    p = validate(name, params)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise GeometryError(f"n must be a non-negative integer, got {n!r}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    patches = [(a, draw) for a, draw in PATCHES[name](p) if a > 0]
    areas = np.array([a for a, _ in patches])
    counts = rng.multinomial(int(n), areas / areas.sum())
    drawn = [draw(rng, int(k)) for (_, draw), k in zip(patches, counts)]
    pts = np.vstack([d[0] for d in drawn]).reshape(-1, 3)
    nrm = np.vstack([d[1] for d in drawn]).reshape(-1, 3)
    order = rng.permutation(int(n))
    return pts[order], nrm[order]
