"""The solid pieces (geoms) of a link, as the exporters write them.

The shape tree itself (outermost shapes, unions as separate pieces, differences as one boolean
mesh) is ``grace_dsl.runtime.shapes``; here each piece is posed in its link's exported frame
and, where the simulators have one, given its native geom. A link has two sets: the visual
geoms (pieces whole) and the collision geoms (every piece convex, since simulators collide a
mesh as its convex hull).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.export.decompose import convex_decomposition
from grace_dsl.geometry import ConvexPiece, convex_pieces, primitive_mesh
from grace_dsl.geometry.pieces import SEGMENTS, carve_boxes
from grace_dsl.runtime.shapes import ShapeTree
from grace_dsl.tolerances import DEGENERATE, EXACT

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

FULL_TURN = 2 * math.pi
SPLIT = ("BoardBox",)  # primitives whose visual geoms are their exact convex pieces too
COLLISION_RESOLUTION = 16  # mesh segments per full circle of a convex piece without native geom


@dataclass(frozen=True)
class Geom:
    """One solid: a primitive (``params`` in SI) or a precomputed mesh, posed in its link's
    frame."""

    name: str  # the qualified shape name (operand name for the pieces of a union)
    primitive: str  # primitive name, or "mesh" for boolean results
    params: Mapping[str, Any]
    pose: np.ndarray  # (4, 4) link frame <- geom frame
    mesh: trimesh.Trimesh  # in the geom frame (also used for mass properties)

    def native(self) -> tuple[str, tuple[float, ...]] | None:
        """The simulator-native form: (box|cylinder|sphere|capsule, full SI dimensions).

        Only exact ones: an untapered TaperedCuboid is a box and a SphericalCap of height
        2 * radius a sphere (its frame is the ball's centre); tapered boxes, other caps, tori and
        prisms have no native geom in MuJoCo or URDF, so they are meshes."""
        p = self.params
        if self.primitive == "Cuboid" or (self.primitive == "TaperedCuboid" and _untapered(p)):
            return "box", tuple(float(v) for v in p["size"])
        if self.primitive == "Sphere":
            return "sphere", (float(p["radius"]),)
        if self.primitive == "SphericalCap" and float(p["height"]) >= 2 * float(p["radius"]):
            return "sphere", (float(p["radius"]),)
        if self.primitive == "Cylinder" and float(p["radian"]) >= FULL_TURN - DEGENERATE:
            return "cylinder", (float(p["radius"]), float(p["height"]))
        if self.primitive == "Capsule":
            return "capsule", (float(p["radius"]), float(p["length"]))
        return None

    def mesh_in_link(self) -> trimesh.Trimesh:
        return self.mesh.copy().apply_transform(self.pose)


def _untapered(p: Mapping[str, Any]) -> bool:
    size, top, offset = (np.asarray(p[k], dtype=float) for k in ("size", "top", "offset"))
    return bool(np.allclose(top, size[[0, 2]], rtol=EXACT, atol=0) and not np.any(offset))


def link_geoms(
    inst: Instance, link: str, frame: np.ndarray, resolution: int, warnings: list[str]
) -> tuple[Geom, ...]:
    """The visual geoms of ``link`` (see ``link_solids``)."""
    return link_solids(inst, link, frame, resolution, warnings)[0]


def link_solids(
    inst: Instance,
    link: str,
    frame: np.ndarray,
    resolution: int,
    warnings: list[str],
    segments: int = SEGMENTS,
    collision: bool = True,
) -> tuple[tuple[Geom, ...], tuple[Geom, ...]]:
    """The visual and the collision geoms of ``link``, posed relative to its exported ``frame``
    (concept frame, q = 0).

    Visual: each piece whole, except that a ``BoardBox`` is written as its boards (native boxes,
    exact). Collision: each piece split into convex ones (``grace_dsl.geometry.convex_pieces``,
    ``segments`` per full turn of a curved one); a difference that is a box minus axis-aligned
    boxes is carved into boxes, any other one decomposed by CoACD (``decompose``); without
    ``collision`` the tuple is empty."""
    tree = ShapeTree(inst, resolution)
    inv = np.linalg.inv(frame)
    visual: list[Geom] = []
    solid: list[Geom] = []
    for name in tree.outermost(link):
        for piece in tree.pieces(name, tree.placement(name), warnings):
            place = inv @ piece.pose
            whole = Geom(piece.name, piece.primitive, piece.params, place, piece.mesh)
            if piece.primitive in SPLIT:
                visual += _split(piece.name, place, convex_pieces(piece.primitive, piece.params))
            else:
                visual.append(whole)
            if collision:
                solid += _collision(tree, piece.name, whole, segments)
    return tuple(visual), tuple(solid)


def _split(name: str, place: np.ndarray, pieces: tuple[ConvexPiece, ...] | None) -> list[Geom]:
    return [
        Geom(
            f"{name}.{c.name}",
            c.primitive,
            c.params,
            place @ c.pose,
            primitive_mesh(c.primitive, c.params, COLLISION_RESOLUTION),
        )
        for c in pieces or ()
    ]


def _collision(tree: ShapeTree, name: str, whole: Geom, segments: int) -> list[Geom]:
    """The convex geoms of one piece (named ``<piece>.<part>``, or the piece's own name when it
    is convex already)."""
    if whole.primitive != "mesh":
        split = convex_pieces(whole.primitive, whole.params, segments)
        return [whole] if split is None else _split(name, whole.pose, split)
    carved = _carve(tree, name)
    if carved is not None:
        return _split(name, whole.pose, carved)
    parts = convex_decomposition(whole.mesh)
    return [Geom(f"{name}.hull_{i}", "mesh", {}, whole.pose, part) for i, part in enumerate(parts)]


def _carve(tree: ShapeTree, name: str) -> tuple[ConvexPiece, ...] | None:
    """A difference of a box and boxes, carved in the piece's frame; None for other operands."""
    operands = tree.shapes[name]["operands"]
    if any(tree.shapes[op]["primitive"] != "Cuboid" for op in operands):
        return None
    base = tree.relative(operands[0])
    to_base = np.linalg.inv(base)
    holes = [(to_base @ tree.relative(op), tree.params(op)["size"]) for op in operands[1:]]
    carved = carve_boxes(tree.params(operands[0])["size"], holes)
    if carved is None:
        return None
    return tuple(ConvexPiece(c.name, c.primitive, c.params, base @ c.pose) for c in carved)
