"""Watertight, outward-oriented triangle meshes of the primitives in their own frames.

Boxes, spheres, capsules, cones and spherical caps come from trimesh's generators; everything
whose cross-section is planar in xy (sectors, tubes, rings, frames, polygons) is one 2D cap
triangulation extruded along z, so sectors of any angle share one code path. The tapered box is
its six planar faces; the torus segment is a circle swept along an arc; the board box the faces
of its board grid (``grace_dsl.geometry.boards``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import trimesh
from numpy.typing import NDArray

from grace_dsl.geometry import boards
from grace_dsl.geometry.errors import GeometryError
from grace_dsl.geometry.primitives import (
    FULL_TURN,
    LENGTH_KINDS,
    PRIMITIVES,
    Params,
    Value,
    validate,
)
from grace_dsl.geometry.props import bounds, cap_base_radius, prism_vertices
from grace_dsl.geometry.sdf import TAPER_FACES, taper_corners

DEFAULT_RESOLUTION = 64  # segments per full circle: volume error ~0.2 % (sphere ~0.3 %)
_FULL_TOL = 1e-9
_SNAP = 1e-6  # relative size below which a radius or a corner offset is built as 0

Arr = NDArray[np.float64]
Tri = NDArray[np.int64]


def _segments(resolution: int, angle: float) -> int:
    return max(1, math.ceil(resolution * angle / FULL_TURN - 1e-9))


def _arc(r: float, start: float, angle: float, n: int, closed: bool) -> Arr:
    """Points on a circle of radius r from angle ``start`` (from +x), n segments."""
    count = n if closed else n + 1
    a = start + angle * np.arange(count) / n
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _strip(n_a: int, n_b: int, n: int, closed: bool) -> Tri:
    """Quads between two point loops of equal length starting at indices n_a and n_b."""
    k = np.arange(n)
    k1 = (k + 1) % n if closed else k + 1
    a0, a1, b0, b1 = n_a + k, n_a + k1, n_b + k, n_b + k1
    return np.vstack([np.column_stack([a0, b0, b1]), np.column_stack([a0, b1, a1])])


def _fan(center: int, n_b: int, n: int, closed: bool) -> Tri:
    k = np.arange(n)
    k1 = (k + 1) % n if closed else k + 1
    return np.column_stack([np.full(n, center), n_b + k, n_b + k1])


def _ccw(v2: Arr, tris: Tri) -> Tri:
    """The triangles with every one turned counter-clockwise (normal +z)."""
    a, b, c = v2[tris[:, 0]], v2[tris[:, 1]], v2[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    out = tris.copy()
    out[cross < 0] = out[cross < 0][:, [0, 2, 1]]
    return out


def _extrude(v2: Arr, tris: Tri, height: float) -> trimesh.Trimesh:
    """Prism of a 2D cap (vertices, CCW triangles) over |z| <= height/2; walls from its border."""
    tris = _ccw(v2, tris)
    n = len(v2)
    edges = np.vstack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    key = np.sort(edges, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    border = edges[counts[inverse.ravel()] == 1]  # CCW boundary: material on the left
    i, j = border[:, 0], border[:, 1]
    walls = np.vstack([np.column_stack([i, j, j + n]), np.column_stack([i, j + n, i + n])])
    verts = np.vstack(
        [
            np.column_stack([v2, np.full(n, -height / 2)]),
            np.column_stack([v2, np.full(n, height / 2)]),
        ]
    )
    faces = np.vstack([tris[:, ::-1], tris + n, walls])
    return trimesh.Trimesh(verts, faces, process=True)


def _sector_cap(r_in: float, r_out: float, angle: float, axis: float, res: int) -> tuple[Arr, Tri]:
    """2D annular sector (r_in may be 0) of ``angle`` centred on direction ``axis``."""
    full = angle >= FULL_TURN - _FULL_TOL
    n = _segments(res, angle)
    outer = _arc(r_out, axis - angle / 2, angle, n, full)
    if r_in > 0:
        inner = _arc(r_in, axis - angle / 2, angle, n, full)
        return np.vstack([inner, outer]), _strip(0, len(inner), n, full)
    return np.vstack([[0.0, 0.0], outer]), _fan(0, 1, n, full)


def _cuboid(p: Params, res: int) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=p["size"])


def _cylinder(p: Params, res: int) -> trimesh.Trimesh:
    v2, tris = _sector_cap(0.0, _f(p["radius"]), _f(p["radian"]), math.pi / 2, res)
    return _extrude(v2, tris, _f(p["height"]))


def _tube(p: Params, res: int) -> trimesh.Trimesh:
    v2, tris = _sector_cap(_f(p["r_in"]), _f(p["r_out"]), FULL_TURN, 0.0, res)
    return _extrude(v2, tris, _f(p["height"]))


def _ring(p: Params, res: int) -> trimesh.Trimesh:
    v2, tris = _sector_cap(_f(p["r_in"]), _f(p["r_out"]), _f(p["radian"]), -math.pi / 2, res)
    return _extrude(v2, tris, _f(p["height"]))


def _rect_ring(p: Params, res: int) -> trimesh.Trimesh:
    corners = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], dtype=float) / 2
    v2 = np.vstack([corners * np.asarray(p["inner"]), corners * np.asarray(p["outer"])])
    return _extrude(v2, _strip(0, 4, 4, True), _f(p["depth"]))


def _sphere(p: Params, res: int) -> trimesh.Trimesh:
    return trimesh.creation.uv_sphere(radius=_f(p["radius"]), count=[res, max(res // 2, 4)])


def _capsule(p: Params, res: int) -> trimesh.Trimesh:
    """Built at unit radius and scaled: trimesh merges the rings near the poles of a capsule
    whose radius is small next to its length (a 4 mm x 476 mm bar lost 256 faces)."""
    r = _f(p["radius"])
    mesh = trimesh.creation.capsule(height=_f(p["length"]) / r, radius=1.0, count=[res, res])
    return mesh.apply_scale(r)


def _frustum(p: Params, res: int) -> trimesh.Trimesh:
    """Two rings (a ring of radius 0 is an apex) joined by a strip, closed by fans, built at
    unit height and unit larger radius, then scaled per axis (a frustum scaled in z stays one),
    with no vertex merging: trimesh's revolve dropped the faces of a radius tiny next to the
    other. A radius below ``_SNAP`` of the larger is the apex."""
    r1, r2, h = _f(p["r_bottom"]), _f(p["r_top"]), _f(p["height"])
    big = max(r1, r2)
    n = res
    rings, faces = [], []
    for r, z in ((r1 / big, -0.5), (r2 / big, 0.5)):
        if r > _SNAP:
            rings.append(np.column_stack([_arc(r, 0.0, FULL_TURN, n, True), np.full(n, z)]))
        else:
            rings.append(np.array([[0.0, 0.0, z]]))
    bottom, top = rings
    centres = [np.array([[0.0, 0.0, -0.5]])] if len(bottom) > 1 else []
    centres += [np.array([[0.0, 0.0, 0.5]])] if len(top) > 1 else []
    verts = np.vstack([bottom, top, *centres])
    nb = len(bottom)
    # every triangle outward: the rings run counter-clockwise seen from +z
    if nb > 1 and len(top) > 1:
        faces.append(_strip(0, nb, n, True)[:, [0, 2, 1]])
    elif nb > 1:  # apex on top
        faces.append(_fan(nb, 0, n, True))
    else:  # apex at the bottom
        faces.append(_fan(0, 1, n, True)[:, [0, 2, 1]])
    at = nb + len(top)
    if nb > 1:  # bottom cap, facing -z
        faces.append(_fan(at, 0, n, True)[:, [0, 2, 1]])
        at += 1
    if len(top) > 1:
        faces.append(_fan(at, nb, n, True))
    mesh = trimesh.Trimesh(verts, np.vstack(faces), process=False)
    return mesh.apply_transform(np.diag([big, big, h, 1.0]))


def _tapered_cuboid(p: Params, res: int) -> trimesh.Trimesh:
    """The six faces as two triangles each (exact: the faces are planar). A top of zero width
    or depth (a wedge or a pyramid) merges corners; the triangles that collapse are dropped.
    The corners are built per axis in units of the solid's extent and snapped to ``_SNAP`` of
    it (scaling an axis keeps faces planar), so a top or size tiny next to the rest merges
    into an edge or apex instead of leaving slivers that tear the mesh."""
    corners = taper_corners(p)
    index = {k: i for i, k in enumerate(corners)}
    verts = np.array(list(corners.values()))
    lo, extent = verts.min(axis=0), np.ptp(verts, axis=0)
    unit = np.round((verts - lo) / extent / _SNAP) * _SNAP
    quads = np.array([[index[k] for k in quad] for quad in TAPER_FACES])
    faces = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    mesh = trimesh.Trimesh(unit, faces, process=True)  # merges the corners a collapsed top shares
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    scale = np.diag([*extent, 1.0])
    scale[:3, 3] = lo
    return mesh.apply_transform(scale)


def _spherical_cap(p: Params, res: int) -> trimesh.Trimesh:
    """Revolve the profile: the flat face's radius, then the arc from the rim to the pole.

    The arc gets its share of ``res`` segments per full circle but at least res/4: a chord's
    sag relative to a thin cap's height is about 1/(4 n^2) whatever the cap's angle."""
    r, h = _f(p["radius"]), _f(p["height"])
    zc = h / 2 - r  # the ball's centre
    polar = math.acos(max(-1.0, min(1.0, (r - h) / r)))  # from the pole to the rim
    n = max(2, _segments(res, polar), math.ceil(res / 4))
    a = polar * np.arange(n, -1, -1) / n  # rim first, pole last
    arc = np.column_stack([r * np.sin(a), zc + r * np.cos(a)])
    arc[-1, 0] = 0.0
    w = cap_base_radius(r, h)  # 0 for the whole ball: the profile starts at the south pole
    profile = np.vstack([[[0.0, -h / 2]] + ([[w, -h / 2]] if w > 0 else []), arc[1:]])
    return trimesh.creation.revolve(profile, sections=res)


def _torus(p: Params, res: int) -> trimesh.Trimesh:
    """A ``res``-gon tube swept along the arc (its share of ``res``), capped by two fans.

    Vertex (u, v) is ((R + r cos v) cos u, (R + r cos v) sin u, r sin v); quads (u, v) ->
    (u + du, v) -> (u + du, v + dv) turn by d/du x d/dv, the outward normal."""
    big, small, ang = _f(p["r_major"]), _f(p["r_minor"]), _f(p["radian"])
    full = ang >= FULL_TURN - _FULL_TOL
    n, m = _segments(res, ang), res
    u = -math.pi / 2 - ang / 2 + ang * np.arange(n if full else n + 1) / n
    v = FULL_TURN * np.arange(m) / m
    rho = big + small * np.cos(v)
    ring = len(u)
    verts = np.column_stack(
        [
            (np.cos(u)[:, None] * rho[None, :]).ravel(),
            (np.sin(u)[:, None] * rho[None, :]).ravel(),
            np.tile(small * np.sin(v), ring),
        ]
    )
    k, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    a = k * m + j
    b = ((k + 1) % ring) * m + j
    a1, b1 = k * m + (j + 1) % m, ((k + 1) % ring) * m + (j + 1) % m
    faces = [np.column_stack([a.ravel(), b.ravel(), b1.ravel()])]
    faces.append(np.column_stack([a.ravel(), b1.ravel(), a1.ravel()]))
    if not full:
        centres = np.array([[big * math.cos(e), big * math.sin(e), 0.0] for e in (u[0], u[-1])])
        c0, c1 = len(verts), len(verts) + 1
        verts = np.vstack([verts, centres])
        faces.append(_fan(c0, 0, m, True))  # normal -d/du: out of the start
        faces.append(_fan(c1, (ring - 1) * m, m, True)[:, ::-1])
    return trimesh.Trimesh(verts, np.vstack(faces), process=True)


def _prism(p: Params, res: int) -> trimesh.Trimesh:
    """Exact: the polygon is its own mesh (``res`` does not apply)."""
    corners = prism_vertices(round(_f(p["sides"])), _f(p["radius"]))
    v2 = np.vstack([np.zeros((1, 2)), corners])
    return _extrude(v2, _fan(0, 1, len(v2) - 1, True), _f(p["height"]))


def _board_box(p: Params, res: int) -> trimesh.Trimesh:
    """Exact: the faces between solid and empty cells of the board grid, as two triangles each,
    on the grid's shared vertices (so the mesh is closed wherever the boards meet)."""
    g = boards.grid(p)
    verts = np.array([[x, y, z] for x in g[0] for y in g[1] for z in g[2]])
    index = {tuple(np.round(v, 12)): i for i, v in enumerate(verts)}
    quads = [
        [index[tuple(np.round(c, 12))] for c in (o, o + u, o + u + v, o + v)]
        for o, u, v, _ in boards.faces(p)
    ]
    q = np.array(quads)
    mesh = trimesh.Trimesh(verts, np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]), process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


def _f(v: Any) -> float:
    return float(v)


def _scaled(v: Value, k: float) -> Value:
    return tuple(x * k for x in v) if isinstance(v, tuple) else v * k


BUILDERS: dict[str, Callable[[Params, int], trimesh.Trimesh]] = {
    "Cuboid": _cuboid,
    "Cylinder": _cylinder,
    "Tube": _tube,
    "Ring": _ring,
    "RectRing": _rect_ring,
    "Sphere": _sphere,
    "Capsule": _capsule,
    "Frustum": _frustum,
    "TaperedCuboid": _tapered_cuboid,
    "SphericalCap": _spherical_cap,
    "Torus": _torus,
    "Prism": _prism,
    "BoardBox": _board_box,
}


def primitive_mesh(
    name: str, params: Mapping[str, Any], resolution: int = DEFAULT_RESOLUTION
) -> trimesh.Trimesh:
    """Watertight, outward-oriented mesh of the primitive in its frame.

    ``resolution`` is the number of segments per full circle (sectors get their share); the
    facets of curved faces are chords, so the mesh lies inside the true surface on those faces.
    """
    p = validate(name, params)
    if isinstance(resolution, bool) or not isinstance(resolution, int) or resolution < 3:
        raise GeometryError(f"resolution must be an integer >= 3, got {resolution!r}")
    # trimesh merges vertices on an absolute tolerance, which tears small spheres and capsules
    # at the poles: build at unit size and scale.
    scale = float(np.ptp(bounds(name, p), axis=0).max())
    unit = {
        k: _scaled(v, 1 / scale) if kind in LENGTH_KINDS else v
        for (k, v), kind in zip(p.items(), (ps.kind for ps in PRIMITIVES[name].params))
    }
    mesh = BUILDERS[name](unit, resolution)
    mesh.apply_scale(scale)
    if _signed_volume(mesh) < 0:
        mesh.invert()
    return mesh


def _signed_volume(mesh: trimesh.Trimesh) -> float:
    """Sum of the tetrahedra (origin, face): the orientation test without trimesh's full mass
    properties (which cost most of the time of building a small mesh)."""
    a, b, c = (np.asarray(mesh.vertices)[np.asarray(mesh.faces)[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6
