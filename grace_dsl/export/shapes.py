"""The solid pieces (geoms) of a link, as the exporters write them.

The shape tree itself (outermost shapes, unions as separate pieces, differences as one boolean
mesh) is ``grace_dsl.runtime.shapes``; here each piece is posed in its link's exported frame
and, where the simulators have one, given its native geom.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.geometry import convex_pieces, primitive_mesh
from grace_dsl.runtime.shapes import ShapeTree
from grace_dsl.tolerances import DEGENERATE, EXACT

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

FULL_TURN = 2 * math.pi
SPLIT = ("BoardBox",)  # primitives exported as their exact convex pieces


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
    """The geoms of ``link``, posed relative to its exported ``frame`` (concept frame, q = 0).

    A ``BoardBox`` is written as its boards (``grace_dsl.geometry.convex_pieces``): native boxes
    a simulator collides exactly, where one mesh would collide as its convex hull."""
    tree = ShapeTree(inst, resolution)
    inv = np.linalg.inv(frame)
    out = []
    for name in tree.outermost(link):
        for piece in tree.pieces(name, tree.placement(name), warnings):
            split = (
                convex_pieces(piece.primitive, piece.params) if piece.primitive in SPLIT else None
            )
            if split is None:
                out.append(
                    Geom(piece.name, piece.primitive, piece.params, inv @ piece.pose, piece.mesh)
                )
                continue
            for c in split:
                mesh = primitive_mesh(c.primitive, c.params, resolution)
                out.append(
                    Geom(
                        f"{piece.name}.{c.name}",
                        c.primitive,
                        c.params,
                        inv @ piece.pose @ c.pose,
                        mesh,
                    )
                )
    return tuple(out)
