"""The shapes of an instance: primitives placed on links, and their unions and differences.

Shapes that are operands of a ``union`` or ``difference`` are building blocks, not geometry of
their own; only the outermost shapes of a link count. A composite's ``at`` moves its operands with
it: an operand's pose relative to its link is applied in the composite's frame.

An instance of a primitive concept (``Torus``, ``Cuboid``...) has no declared shapes: it *is*
its shape, so the tree holds one, the primitive itself with the instance's parameters, on its
one link at the concept frame.

Two views of the same tree: *pieces* (solids with meshes, at q = 0 in the concept frame: a union
becomes its operands, a difference one boolean mesh, which needs ``manifold3d``) for meshes and
exports, and the *signed distance* (min over a union, max(a, -b) for a difference: exact outside
a union, a bound elsewhere that is exact on the surface) for fitting and containment.

Parameters inside their declared ranges can still give a shape arguments no solid has (a
``RectRing`` whose opening closes up, a height that divides by a parameter that reached 0): the
tree checks each shape's arguments and pose once, and raises ``ShapeError`` naming the concept,
the shape, its ``file:line``, the problem and the parameter values, never a bare geometry error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh

from grace_dsl.compiler.types import format_si
from grace_dsl.geometry import GeometryError, primitive_mesh, primitive_sdf, validate
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.masks import has_masks, present

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance


class ShapeError(ParameterError):
    """Parameter values, inside their ranges, that give a shape invalid arguments or pose.

    ``concept``, ``shape``, ``primitive``, ``where`` (``file.eac:line`` of the declaration),
    ``problem`` and ``values`` (the instance's parameters, as people read them) are attributes,
    so ``eacc verify`` reports the draw instead of crashing."""

    def __init__(
        self, concept: str, shape: str, primitive: str, where: str, problem: str, values: str
    ):
        self.concept, self.shape, self.primitive = concept, shape, primitive
        self.where, self.problem, self.values = where, problem, values
        at = f"{primitive}, {where}" if where else primitive
        super().__init__(
            f"{concept}: shape {shape} ({at}) cannot be built: {problem}"
            + (f"; with {values}" if values else "")
        )


def parameter_text(inst: Instance) -> str:
    """``a = 20mm, b = (1, 2)``: an instance's parameters in display units (mm, deg)."""
    values = inst.params
    out = []
    for spec in inst.concept.params:
        v = values[spec.name]
        text = format_si(v, spec.dim) if spec.kind in ("num", "vec") else repr(v)
        out.append(f"{spec.name} = {text}")
    return ", ".join(out)


@dataclass(frozen=True)
class Piece:
    """One solid: a primitive (``params`` in SI) or a boolean mesh (``primitive == "mesh"``)."""

    name: str
    link: str
    primitive: str
    params: Mapping[str, Any]
    pose: np.ndarray  # concept frame at q = 0 <- piece frame
    resolution: int = 64
    boolean: trimesh.Trimesh | None = None  # the mesh of a difference, in the piece frame

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """The piece's mesh in its frame; a primitive's is built on first use (surface samples
        and distances never need it)."""
        if self.boolean is not None:
            return self.boolean
        return primitive_mesh(self.primitive, self.params, resolution=self.resolution)


def primitive_own_shape(concept: Any) -> dict[str, Any] | None:
    """The shape entry of a primitive concept's instance: the primitive itself, named after it,
    on the concept's one link, its arguments the concept's parameters (in the same order as
    the flat parameter vector); None for a concept that declares its shapes."""
    entry = concept.entry
    if entry.get("kind") != "primitive" or len(concept.links) != 1:
        return None
    return {
        "name": concept.name,
        "link": concept.links[0],
        "primitive": concept.name,
        "operands": [],
        "operand_of": None,
        "args": [{"name": s.name, "size": s.size} for s in concept.params],
    }


class ShapeTree:
    """Evaluates an instance's shapes at q = 0 and expands composites."""

    def __init__(self, inst: Instance, resolution: int = 64):
        self.inst, self.resolution = inst, resolution
        entry = inst.concept.entry
        params = inst.params if has_masks(entry) else {}
        self.shapes: dict[str, Mapping[str, Any]] = {  # copies the instance lacks drop out
            s["name"]: s for s in entry["shapes"] if not params or present(entry, params, s["name"])
        }
        self.q0 = np.zeros_like(inst.q)
        self._rest = Kinematics.of(inst).in_concept_frame()
        self._links: dict[str, np.ndarray] = {}
        self._evaluated: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._params: dict[str, dict[str, Any]] = {}
        own = primitive_own_shape(inst.concept)
        if own is not None and not self.shapes:
            self.shapes[own["name"]] = own
            eye = np.eye(4)  # the primitive sits on the concept frame; its arguments are p
            self._evaluated[own["name"]] = (eye, np.asarray(inst.p, float).reshape(-1), eye)

    def outermost(self, link: str | None = None) -> list[str]:
        """The shapes that are not operands of another (on ``link``, or on every link)."""
        consumed = {op for s in self.shapes.values() for op in s["operands"]}
        return [
            n
            for n, s in self.shapes.items()
            if n not in consumed and (link is None or s["link"] == link)
        ]

    def link_pose(self, link: str) -> np.ndarray:
        if link not in self._links:  # the concept frame at the closed joints
            self._links[link] = self._rest.link_pose(link, self.q0)
        return self._links[link]

    def evaluate(self, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The shape's pose (concept frame, q = 0), primitive arguments and ``at``; a pose that
        is not finite raises ``ShapeError``."""
        if name not in self._evaluated:
            pose, args, at = self.inst.concept.function("shape", name)(self.inst.p, self.q0)
            pose, at = np.asarray(pose, float), np.asarray(at, float)
            if not (np.all(np.isfinite(pose)) and np.all(np.isfinite(at))):
                raise self.error(name, f"its pose is not finite: {np.round(pose, 6).tolist()}")
            self._evaluated[name] = (pose, np.asarray(args, float).reshape(-1), at)
        return self._evaluated[name]

    def error(self, name: str, problem: str) -> ShapeError:
        """The typed error for shape ``name`` of this instance."""
        s = self.shapes[name]
        where = s.get("where") or self.inst.concept.entry.get("file", "")
        concept = self.inst.concept.name
        return ShapeError(concept, name, s["primitive"], where, problem, parameter_text(self.inst))

    def relative(self, name: str) -> np.ndarray:
        """The shape's ``at``: its pose in the frame that declares it (a part's shapes in the
        part's placed frame), which is what an operand keeps inside its composite's frame."""
        return self.evaluate(name)[2]

    def placement(self, name: str) -> np.ndarray:
        """Where an outermost shape sits in the concept frame at q = 0."""
        return self.evaluate(name)[0]

    def params(self, name: str) -> dict[str, Any]:
        """The primitive's checked arguments (SI); arguments no solid has raise ``ShapeError``."""
        if name not in self._params:
            args = self.evaluate(name)[1]
            out: dict[str, Any] = {}
            i = 0
            for a in self.shapes[name]["args"]:
                size = a["size"]
                value = args[i : i + size]
                out[a["name"]] = float(value[0]) if size == 1 else tuple(map(float, value))
                i += size
            try:
                self._params[name] = dict(validate(self.shapes[name]["primitive"], out))
            except GeometryError as exc:
                raise self.error(name, str(exc)) from None
        return self._params[name]

    def check(self) -> None:
        """Evaluate every outermost shape and its operands: raises ``ShapeError`` for the first
        whose arguments or pose are invalid."""
        for name in self.shapes:
            if self.shapes[name]["primitive"] in ("union", "difference"):
                self.evaluate(name)
            else:
                self.params(name)

    # -- pieces ------------------------------------------------------------------------------
    def pieces(self, name: str, place: np.ndarray, warnings: list[str]) -> list[Piece]:
        """The solids of shape ``name`` placed at ``place`` (concept frame, q = 0)."""
        s = self.shapes[name]
        if s["primitive"] == "union":
            return [
                p
                for op in s["operands"]
                for p in self.pieces(op, place @ self.relative(op), warnings)
            ]
        if s["primitive"] == "difference":
            return self._difference(name, place, warnings)
        return [Piece(name, s["link"], s["primitive"], self.params(name), place, self.resolution)]

    def _difference(self, name: str, place: np.ndarray, warnings: list[str]) -> list[Piece]:
        try:
            solids = [
                self._solid(op, place @ self.relative(op), warnings)
                for op in self.shapes[name]["operands"]
            ]
            result = trimesh.boolean.difference(solids, engine="manifold")
        except ShapeError:
            raise
        except (ImportError, ValueError) as exc:
            warnings.append(f"shape {name} (a difference) skipped: {exc}")
            return []
        result.apply_transform(np.linalg.inv(place))
        link = self.shapes[name]["link"]
        return [Piece(name, link, "mesh", {}, place, self.resolution, result)]

    def _solid(self, name: str, place: np.ndarray, warnings: list[str]) -> trimesh.Trimesh:
        meshes = [p.mesh.copy().apply_transform(p.pose) for p in self.pieces(name, place, warnings)]
        merged = trimesh.util.concatenate(meshes)
        assert isinstance(merged, trimesh.Trimesh)
        return merged

    # -- signed distance ---------------------------------------------------------------------
    def sdf(self, name: str, place: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Signed distance of shape ``name`` placed at ``place`` to ``points`` (same frame)."""
        s = self.shapes[name]
        ops = s["operands"]
        if s["primitive"] in ("union", "difference"):
            dists = [self.sdf(op, place @ self.relative(op), points) for op in ops]
            if s["primitive"] == "union":
                return np.min(dists, axis=0)
            rest = np.min(dists[1:], axis=0)
            return np.maximum(dists[0], -rest)
        local = _apply(np.linalg.inv(place), points)
        return primitive_sdf(s["primitive"], self.params(name), local)


def _apply(m: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ m[:3, :3].T + m[:3, 3]


# -- the whole instance, in the world at its joint values ------------------------------------


def _motions(tree: ShapeTree) -> dict[str, np.ndarray]:
    """World pose change of each link from q = 0 to the instance's joints: world <- q0 frame."""
    kin = Kinematics.of(tree.inst)
    return {
        link: kin.link_pose(link) @ np.linalg.inv(tree.link_pose(link))
        for link in tree.inst.concept.links
    }


def instance_pieces(inst: Instance, resolution: int = 64) -> list[tuple[Piece, np.ndarray]]:
    """Every solid of the instance with its world pose (world <- piece frame, at the instance's
    joint values): what a caller needs to sample or mesh the pieces itself, e.g. a fit that
    draws a fixed number of points per piece so the samples move smoothly with the parameters.
    A difference that cannot be built raises ``ValueError``."""
    tree = ShapeTree(inst, resolution)
    motions = _motions(tree)
    warnings: list[str] = []
    out = [
        (piece, motions[piece.link] @ piece.pose)
        for name in tree.outermost()
        for piece in tree.pieces(name, tree.placement(name), warnings)
    ]
    if warnings:
        raise ValueError("; ".join(warnings))
    return out


def instance_meshes(
    inst: Instance, link: str | None = None, resolution: int = 64
) -> list[trimesh.Trimesh]:
    """A closed mesh per piece of every outermost shape (of ``link``, or of all links), in the
    world: the solids whose union the instance is."""
    tree = ShapeTree(inst, resolution)
    motions = _motions(tree)
    warnings: list[str] = []
    meshes = [
        piece.mesh.copy().apply_transform(motions[piece.link] @ piece.pose)
        for name in tree.outermost(link)
        for piece in tree.pieces(name, tree.placement(name), warnings)
    ]
    if warnings:
        raise ValueError("; ".join(warnings))
    return meshes


def instance_mesh(inst: Instance, link: str | None = None, resolution: int = 64) -> trimesh.Trimesh:
    """One closed solid of every outermost shape (of ``link``, or of all links), in the world:
    the boolean union of the pieces (manifold3d), so ``contains``, ``volume`` and
    ``is_watertight`` are those of the instance. ``instance_mesh_concat`` is the faster soup."""
    meshes = instance_meshes(inst, link, resolution)
    if len(meshes) < 2:
        return meshes[0] if meshes else trimesh.Trimesh()
    return union_mesh(meshes)


def union_mesh(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The boolean union of closed meshes (manifold3d, trimesh's ``manifold`` engine)."""
    merged = trimesh.boolean.union(meshes, engine="manifold")
    assert isinstance(merged, trimesh.Trimesh)
    return merged


def instance_mesh_concat(
    inst: Instance, link: str | None = None, resolution: int = 64
) -> trimesh.Trimesh:
    """The pieces' meshes concatenated, overlaps and buried faces kept: cheaper than
    ``instance_mesh`` and fine for pictures, wrong for ``contains`` and ``volume``."""
    meshes = instance_meshes(inst, link, resolution)
    merged = trimesh.util.concatenate(meshes) if meshes else trimesh.Trimesh()
    assert isinstance(merged, trimesh.Trimesh)
    return merged


def instance_sdf(inst: Instance, points: np.ndarray) -> np.ndarray:
    """Signed distance of world ``points`` (N, 3) to the instance: the union of its shapes."""
    tree = ShapeTree(inst)
    return _tree_sdf(tree, _motions(tree), points)


def _tree_sdf(tree: ShapeTree, motions: dict[str, np.ndarray], points: np.ndarray) -> np.ndarray:
    """``instance_sdf`` on an already evaluated tree (shapes and link motions computed once)."""
    # placed straight in the world (motion times placement): one transform of the points per shape
    dists = [
        tree.sdf(name, motions[tree.shapes[name]["link"]] @ tree.placement(name), points)
        for name in tree.outermost()
    ]
    return np.min(dists, axis=0) if dists else np.full(len(points), np.inf)


def instance_samples(
    inst: Instance, n: int, seed: int, tol: float = 1e-7
) -> tuple[np.ndarray, np.ndarray]:
    """``n`` world points spread by area over the instance's outer surface, and their normals.

    Each piece's surface is sampled exactly (analytically for primitives, weighted by their exact
    areas); points that fall inside another shape, or on a face pressed against another shape's,
    are not on the outer surface and are rejected, so draws repeat (with the same generator,
    hence deterministically) until ``n`` remain. Each round draws every piece at once and tests
    the batch with two distance evaluations; its size follows the share kept so far, so an
    instance whose drawers hide most of their area inside the carcass needs few rounds.
    """
    tree = ShapeTree(inst)
    motions = _motions(tree)
    warnings: list[str] = []
    pieces = [
        p for name in tree.outermost() for p in tree.pieces(name, tree.placement(name), warnings)
    ]
    if not pieces:
        raise ValueError(f"{inst.concept.name} has no shapes to sample")
    areas = np.array([piece_area(p) for p in pieces])
    worlds = [motions[p.link] @ p.pose for p in pieces]
    rng = np.random.default_rng(seed)
    kept_pts: list[np.ndarray] = []
    kept_nrm: list[np.ndarray] = []
    total, drawn, rate = 0, 0, 1 / 1.3  # rate: the share of draws kept (a first guess)
    for _ in range(50):
        want = math.ceil(1.1 * (n - total) / max(rate, 0.02)) + 16
        counts = rng.multinomial(want, areas / areas.sum())
        batch = [piece_samples(piece, int(k), rng) for piece, k in zip(pieces, counts)]
        pts = np.concatenate([_apply(w, b[0]) for w, b in zip(worlds, batch)])
        nrm = np.concatenate([b[1] @ w[:3, :3].T for w, b in zip(worlds, batch)])
        # outside every other shape, and not on a face that touches another shape's face
        outer = (_tree_sdf(tree, motions, pts) > -tol) & (
            _tree_sdf(tree, motions, pts + 1e-6 * nrm) > 0
        )
        kept_pts.append(pts[outer])
        kept_nrm.append(nrm[outer])
        total, drawn = total + int(outer.sum()), drawn + want
        rate = total / drawn
        if total >= n:
            break
    order = rng.permutation(total)[:n]
    return np.concatenate(kept_pts)[order], np.concatenate(kept_nrm)[order]


def piece_area(piece: Piece) -> float:
    """A piece's surface area: analytic for a primitive, the mesh's for a boolean result."""
    from grace_dsl.geometry import surface_area

    if piece.primitive != "mesh":
        return surface_area(piece.primitive, piece.params)
    return float(piece.mesh.area)


def piece_samples(piece: Piece, k: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``k`` surface points and outward normals in the piece's frame, either kind of piece."""
    from grace_dsl.geometry import sample_surface

    if piece.primitive != "mesh":
        return sample_surface(piece.primitive, piece.params, k, rng)
    pts, faces = trimesh.sample.sample_surface(piece.mesh, k, seed=int(rng.integers(2**31)))
    return np.asarray(pts), np.asarray(piece.mesh.face_normals[faces])
