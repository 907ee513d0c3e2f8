"""A concept's signed distance as one differentiable CasADi graph of its parameters, joints and a
pose increment, compiled to native code for the fit.

The compiled concept already holds each shape's placement and arguments and each link's pose
as CasADi functions of the parameter vector ``p`` and the joints ``q``
(``Concept.symbolic``); composing them with the primitives' CasADi distances
(``geometry.primitive_sdf_casadi``) gives the instance's distance with parameters as symbolic
inputs, so Gauss-Newton gets exact derivatives instead of finite differences. Inputs:

- ``theta`` the estimated (float) entries of ``p``, ``pfix`` the whole ``p`` (its other entries,
  choices and counts, are read from it), ``q`` the moving joints;
- ``w`` = (rotation vector, translation) of a pose increment ``D``: a point ``y`` in the frame
  of the current pose estimate is at ``D^-1 y`` in the concept frame. The rotation is
  ``I + [w]x + [w]x^2 / 2``, exact to first order at ``w = 0``, where the fit evaluates it.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from grace_dsl.compiler import native
from grace_dsl.geometry import primitive_sdf_casadi
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.shapes import primitive_own_shape


@dataclass(frozen=True)
class SdfModel:
    """The compiled distance of one concept (for one set of present shapes)."""

    concept: Concept
    float_index: tuple[int, ...]  # positions in p of the estimated entries
    n_joints: int
    value: native.Evaluator  # (theta, pfix, q, w, y) -> d
    gradient: native.Evaluator  # (theta, pfix, q, w, y) -> (d, dd/d[theta, q, w])

    @property
    def n_vars(self) -> int:
        return len(self.float_index) + self.n_joints + 6


def float_index(concept: Concept) -> tuple[int, ...]:
    """The entries of ``p`` that are real-valued parameters (``num`` and ``vec``)."""
    out: list[int] = []
    for s in concept.params:
        if s.kind in ("num", "vec"):
            out += range(s.offset, s.offset + s.size)
    return tuple(out)


def _skew(w: Any) -> Any:
    return ca.vertcat(
        ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]), ca.horzcat(-w[1], w[0], 0)
    )


def _inverse(t: Any) -> Any:
    r = t[:3, :3]
    out = ca.SX.eye(4)
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ t[:3, 3]
    return out


def _apply(t: Any, y: Any) -> Any:
    return t[:3, :3] @ y + t[:3, 3]


class _Graph:
    """Builds the distance of the present shapes at symbolic ``p`` and ``q``."""

    def __init__(self, concept: Concept, shapes: tuple[str, ...], p: Any, q: Any):
        self.concept, self.p, self.q = concept, p, q
        self.entries = {s["name"]: s for s in concept.entry["shapes"] if s["name"] in shapes}
        self.q0 = ca.SX.zeros(q.shape[0])
        self._evaluated: dict[str, tuple[Any, Any, Any]] = {}

    def shape(self, name: str) -> tuple[Any, Any, Any]:
        if name not in self._evaluated:
            fn = self.concept.symbolic("shape", name)
            self._evaluated[name] = tuple(fn(self.p, self.q0))  # type: ignore[assignment]
        return self._evaluated[name]

    def motion(self, link: str) -> Any:
        fn = self.concept.symbolic("link", link)
        return fn(self.p, self.q) @ _inverse(fn(self.p, self.q0))

    def sdf(self, name: str, place: Any, y: Any) -> Any:
        """Distance of concept-frame point ``y`` to shape ``name`` placed at ``place``."""
        s = self.entries[name]
        if s["primitive"] in ("union", "difference"):
            ds = [self.sdf(op, place @ self.shape(op)[2], y) for op in s["operands"]]
            if s["primitive"] == "union":
                return _min(ds)
            return ca.fmax(ds[0], -_min(ds[1:]))
        args = self.shape(name)[1]
        values: dict[str, Any] = {}
        i = 0
        for a in s["args"]:
            values[a["name"]] = args[i] if a["size"] == 1 else args[i : i + a["size"]]
            i += a["size"]
        return primitive_sdf_casadi(s["primitive"], values, _apply(_inverse(place), y))

    def outermost(self) -> list[str]:
        consumed = {op for s in self.entries.values() for op in s["operands"]}
        return [n for n in self.entries if n not in consumed]


def _min(ds: list[Any]) -> Any:
    out = ds[0]
    for d in ds[1:]:
        out = ca.fmin(out, d)
    return out


@dataclass(frozen=True)
class PartsModel:
    """The distance to each outermost shape apart, for a fit whose points carry part labels:
    a point is measured against the shapes of its own part (the min over that group's columns)
    and free space against all of them (the union). One function for every labelling, so a
    concept compiles once whatever parts a segmenter names."""

    concept: Concept
    float_index: tuple[int, ...]
    n_joints: int
    shapes: tuple[str, ...]  # the outermost shapes, the columns of the outputs
    links: tuple[str, ...]  # the link of each shape
    value: native.Evaluator  # (theta, pfix, q, w, y) -> d (S,)
    gradient: native.Evaluator  # (theta, pfix, q, w, y) -> (d (S,), dd/d[theta, q, w] (S, n))

    @property
    def n_vars(self) -> int:
        return len(self.float_index) + self.n_joints + 6


def _symbols(concept: Concept) -> tuple[Any, ...]:
    """(theta, pfix, q, w, y, p, local): the inputs and the point in the concept frame."""
    index = float_index(concept)
    n_p = len(np.atleast_1d(concept.pack()))
    theta = ca.SX.sym("theta", len(index))
    pfix = ca.SX.sym("pfix", n_p)
    q = ca.SX.sym("q", len(concept.moving_joints))
    w = ca.SX.sym("w", 6)
    y = ca.SX.sym("y", 3)
    where = {j: k for k, j in enumerate(index)}
    p = ca.vertcat(*[theta[where[i]] if i in where else pfix[i] for i in range(n_p)])
    k = _skew(w[:3])
    rot = ca.SX.eye(3) + k + 0.5 * (k @ k)
    local = rot.T @ (y - w[3:])
    return theta, pfix, q, w, y, p, local


def _shape_distances(
    concept: Concept, shapes: tuple[str, ...], p: Any, q: Any, local: Any
) -> tuple[list[str], list[str], list[Any]]:
    """Names, links and distances of the outermost shapes at concept-frame point ``local``."""
    own = primitive_own_shape(concept)
    if own is not None and not concept.entry["shapes"]:
        values = {
            s.name: p[s.offset] if s.size == 1 else p[s.offset : s.offset + s.size]
            for s in concept.params
        }
        link = concept.links[0] if concept.links else "base"
        return [own["name"]], [link], [primitive_sdf_casadi(concept.name, values, local)]
    g = _Graph(concept, shapes, p, q)
    names = g.outermost()
    links = [g.entries[n]["link"] for n in names]
    ds = [g.sdf(n, g.motion(g.entries[n]["link"]) @ g.shape(n)[0], local) for n in names]
    return names, links, ds


@lru_cache(maxsize=32)
def _build_parts(concept: Concept, shapes: tuple[str, ...]) -> PartsModel:
    theta, pfix, q, w, y, p, local = _symbols(concept)
    names, links, ds = _shape_distances(concept, shapes, p, q, local)
    d = ca.vertcat(*ds)
    x = ca.vertcat(theta, q, w)
    name = f"fitparts_{concept.name.lower()}_{zlib.crc32('|'.join(shapes).encode()):08x}"
    fns = {
        f"{name}_d": ca.Function(f"{name}_d", [theta, pfix, q, w, y], [d]),
        f"{name}_g": ca.Function(f"{name}_g", [theta, pfix, q, w, y], [d, ca.jacobian(d, x)]),
    }
    fast = native.fast_functions(fns)
    return PartsModel(
        concept,
        float_index(concept),
        len(concept.moving_joints),
        tuple(names),
        tuple(links),
        fast[f"{name}_d"],
        fast[f"{name}_g"],
    )


def parts_model(concept: Concept, shapes: tuple[str, ...]) -> PartsModel:
    """The per-shape distances of ``concept`` over ``shapes`` (as ``sdf_model``), for the
    part-labelled fit; built once per concept and shape set."""
    return _build_parts(concept, tuple(shapes))


@lru_cache(maxsize=32)
def _build(concept: Concept, shapes: tuple[str, ...]) -> SdfModel:
    index = float_index(concept)
    theta, pfix, q, w, y, p, local = _symbols(concept)
    d = _min(_shape_distances(concept, shapes, p, q, local)[2])
    x = ca.vertcat(theta, q, w)
    name = f"fit_{concept.name.lower()}_{zlib.crc32('|'.join(shapes).encode()):08x}"
    value = ca.Function(f"{name}_d", [theta, pfix, q, w, y], [d])
    grad = ca.Function(f"{name}_g", [theta, pfix, q, w, y], [d, ca.jacobian(d, x)])
    return SdfModel(
        concept,
        index,
        len(concept.moving_joints),
        native.fast_function(value),
        native.fast_function(grad),
    )


def sdf_model(concept: Concept, shapes: tuple[str, ...]) -> SdfModel:
    """The compiled distance of ``concept`` over ``shapes`` (the shapes an instance has:
    ``ShapeTree(inst).shapes``); built once per concept and shape set, native code cached on
    disk by content."""
    return _build(concept, tuple(shapes))
