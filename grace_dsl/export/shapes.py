"""The solid pieces (geoms) of a link: its shapes evaluated at the instance's parameters.

Shapes that are operands of a ``union`` or ``difference`` are building blocks, not geometry of
their own: only the outermost shapes are exported. A union becomes its operands as separate
geoms (simulators collide with each piece; nothing is lost). A difference needs a mesh boolean,
which trimesh only does with ``manifold3d``; without it the shape is skipped with a warning.

A composite's ``at`` moves its operands with it: an operand's pose relative to its link is
applied in the composite's frame.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.geometry import primitive_mesh

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance

FULL_TURN = 2 * math.pi


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
        """The simulator-native form: (box|cylinder|sphere|capsule, full SI dimensions)."""
        p = self.params
        if self.primitive == "Cuboid":
            return "box", tuple(float(v) for v in p["size"])
        if self.primitive == "Sphere":
            return "sphere", (float(p["radius"]),)
        if self.primitive == "Cylinder" and float(p["radian"]) >= FULL_TURN - 1e-9:
            return "cylinder", (float(p["radius"]), float(p["height"]))
        if self.primitive == "Capsule":
            return "capsule", (float(p["radius"]), float(p["length"]))
        return None

    def mesh_in_link(self) -> trimesh.Trimesh:
        return self.mesh.copy().apply_transform(self.pose)


@dataclass(frozen=True)
class _Piece:
    name: str
    primitive: str
    params: Mapping[str, Any]
    pose: np.ndarray  # concept frame at q = 0
    mesh: trimesh.Trimesh


def link_geoms(
    inst: Instance, link: str, frame: np.ndarray, resolution: int, warnings: list[str]
) -> tuple[Geom, ...]:
    """The geoms of ``link``, posed relative to its exported ``frame`` (concept frame, q = 0)."""
    shapes = {s["name"]: s for s in inst.concept.entry["shapes"]}
    consumed = {op for s in shapes.values() for op in s["operands"]}
    ctx = _Context(inst, shapes, resolution, warnings)
    inv = np.linalg.inv(frame)
    out: list[Geom] = []
    for name, s in shapes.items():
        if s["link"] != link or name in consumed:
            continue
        place = ctx.link_pose(link) @ ctx.relative(name)
        for piece in ctx.pieces(name, place):
            geom = Geom(piece.name, piece.primitive, piece.params, inv @ piece.pose, piece.mesh)
            out.append(geom)
    return tuple(out)


class _Context:
    """Evaluates shapes at q = 0 and expands composites into pieces."""

    def __init__(
        self,
        inst: Instance,
        shapes: Mapping[str, Mapping[str, Any]],
        resolution: int,
        warnings: list[str],
    ):
        self.inst, self.shapes, self.resolution, self.warnings = inst, shapes, resolution, warnings
        self.q0 = np.zeros_like(inst.q)

    def link_pose(self, link: str) -> np.ndarray:
        return np.asarray(self.inst.concept.function("link", link)(self.inst.p, self.q0), float)

    def evaluate(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        pose, args = self.inst.concept.function("shape", name)(self.inst.p, self.q0)
        return np.asarray(pose, float), np.asarray(args, float).reshape(-1)

    def relative(self, name: str) -> np.ndarray:
        """The shape's pose relative to its link (what its ``at`` says)."""
        pose, _ = self.evaluate(name)
        return np.linalg.solve(self.link_pose(self.shapes[name]["link"]), pose)

    def params(self, name: str) -> dict[str, Any]:
        _, args = self.evaluate(name)
        out: dict[str, Any] = {}
        i = 0
        for a in self.shapes[name]["args"]:
            size = a["size"]
            out[a["name"]] = float(args[i]) if size == 1 else tuple(map(float, args[i : i + size]))
            i += size
        return out

    def pieces(self, name: str, place: np.ndarray) -> list[_Piece]:
        """The solids of shape ``name`` placed at ``place`` (concept frame)."""
        s = self.shapes[name]
        if s["primitive"] == "union":
            return [p for op in s["operands"] for p in self.pieces(op, place @ self.relative(op))]
        if s["primitive"] == "difference":
            return self._difference(name, place)
        params = self.params(name)
        mesh = primitive_mesh(s["primitive"], params, resolution=self.resolution)
        return [_Piece(name, s["primitive"], params, place, mesh)]

    def _difference(self, name: str, place: np.ndarray) -> list[_Piece]:
        if importlib.util.find_spec("manifold3d") is None:
            self.warnings.append(
                f"shape {name} (a difference) skipped: mesh booleans need the manifold3d package"
            )
            return []
        ops = self.shapes[name]["operands"]
        solids = [self._solid(op, place @ self.relative(op)) for op in ops]
        result = trimesh.boolean.difference(solids, engine="manifold")
        result.apply_transform(np.linalg.inv(place))
        return [_Piece(name, "mesh", {}, place, result)]

    def _solid(self, name: str, place: np.ndarray) -> trimesh.Trimesh:
        """One mesh (concept frame) of all the pieces of a difference's operand."""
        meshes = [p.mesh.copy().apply_transform(p.pose) for p in self.pieces(name, place)]
        merged = trimesh.util.concatenate(meshes)
        assert isinstance(merged, trimesh.Trimesh)
        return merged
