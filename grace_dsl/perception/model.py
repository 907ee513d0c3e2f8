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
from collections.abc import Callable
from dataclasses import dataclass, field
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
        return self.leaf(s["primitive"], values, place, y)

    def leaf(self, primitive: str, values: dict[str, Any], place: Any, y: Any) -> Any:
        """A primitive's distance at ``y`` (concept frame), the primitive placed at ``place``."""
        return primitive_sdf_casadi(primitive, values, _apply(_inverse(place), y))

    def outermost(self) -> list[str]:
        consumed = {op for s in self.entries.values() for op in s["operands"]}
        return [n for n in self.entries if n not in consumed]


def _min(ds: list[Any]) -> Any:
    out = ds[0]
    for d in ds[1:]:
        out = ca.fmin(out, d)
    return out


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


# -- the part-labelled fit's model: per-point kernels fed by a once-per-evaluation setup ---------


class _Inputs:
    """What a primitive's distance takes from the parameters and joints (its placement's
    inverse and its arguments) does not depend on the point: each non-constant entry becomes a
    symbol ``z[i]`` of the per-point kernels, its expression goes to ``setup``, evaluated once
    per call instead of once per point. Constant entries (an axis-aligned box's rotation) stay
    constants, so the kernels keep their simplifications."""

    def __init__(self) -> None:
        self.symbols: list[Any] = []
        self.exprs: list[Any] = []

    def __call__(self, e: Any) -> Any:
        e = ca.SX(e)
        out = ca.SX.zeros(*e.shape)
        for i in range(e.numel()):
            x = e[i]
            if x.is_constant():
                out[i] = x
            else:
                z = ca.SX.sym(f"z{len(self.symbols)}")
                self.symbols.append(z)
                self.exprs.append(x)
                out[i] = z
        return out


class _SplitGraph(_Graph):
    """``_Graph`` whose primitives read their placement and arguments from ``_Inputs``."""

    def __init__(self, concept: Concept, shapes: tuple[str, ...], p: Any, q: Any, inputs: _Inputs):
        super().__init__(concept, shapes, p, q)
        self.inputs = inputs

    def leaf(self, primitive: str, values: dict[str, Any], place: Any, y: Any) -> Any:
        inv = _inverse(place)
        rot, shift = self.inputs(inv[:3, :3]), self.inputs(inv[:3, 3])
        own = {k: self.inputs(v) for k, v in values.items()}
        return primitive_sdf_casadi(primitive, own, rot @ y + shift)


@dataclass(frozen=True)
class _Batch:
    """An evaluation with the ``batch`` call of an ``Evaluator`` (the model's older API)."""

    fn: Callable[..., Any]

    def batch(self, *args: Any) -> Any:
        return self.fn(*args)


@dataclass(frozen=True)
class PartsModel:
    """The distance to each outermost shape apart, for a fit whose points carry part labels:
    a point is measured against the shapes of its own part (the min over that group's columns)
    and free space against all of them (the union). One model for every labelling, so a
    concept compiles once whatever parts a segmenter names.

    Evaluated in two steps (why: the placements of a concept's shapes, a chain of link and
    shape transforms of the parameters, cost most of a point's distance and are the same for
    every point): ``setup`` maps (theta, pfix, q) to the primitives' placements and arguments
    ``z`` and their Jacobian; ``point_value`` (z, w, y) gives every shape's distance at a
    point, and ``point_grads[k]`` shape k's distance and its gradient in z's entries of shape
    k (``cuts[k]:cuts[k+1]``) and in w, so the fit differentiates only the shape each point is
    measured against; the chain rule through ``setup``'s Jacobian gives the gradient in
    (theta, q, w)."""

    concept: Concept
    float_index: tuple[int, ...]
    n_joints: int
    shapes: tuple[str, ...]  # the outermost shapes, the columns of the outputs
    links: tuple[str, ...]  # the link of each shape
    setup: native.Evaluator  # (theta, pfix, q) -> (z (m,), dz/d[theta, q] (m, nt + nq))
    point_value: native.Evaluator  # (z, w, y) -> d (S,)
    point_grads: tuple[native.Evaluator, ...]  # per shape: (z, w, y) -> (d, dd/d[z_k, w])
    cuts: tuple[int, ...]  # shape k's entries of z: cuts[k]:cuts[k + 1]
    value: _Batch = field(init=False, repr=False, compare=False)
    gradient: _Batch = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _Batch(self.distances))
        object.__setattr__(self, "gradient", _Batch(self.all_gradients))

    @property
    def n_vars(self) -> int:
        return len(self.float_index) + self.n_joints + 6

    def inputs(
        self, theta: np.ndarray, pfix: np.ndarray, q: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``z`` and its Jacobian in (theta, q) at the given parameters and joints."""
        z, jz = self.setup(theta, pfix, q)
        flat = np.asarray(z, float).reshape(-1)
        return flat, np.asarray(jz, float).reshape(len(flat), -1)

    def distances(
        self, theta: np.ndarray, pfix: np.ndarray, q: np.ndarray, w: np.ndarray, y: np.ndarray
    ) -> np.ndarray:
        """(N, S): every shape's distance at each point ``y`` (N, 3)."""
        z = self.inputs(theta, pfix, q)[0]
        return np.asarray(self.point_value.batch(z, w, y)).reshape(len(y), len(self.shapes))

    def gradients(
        self,
        theta: np.ndarray,
        pfix: np.ndarray,
        q: np.ndarray,
        w: np.ndarray,
        y: np.ndarray,
        k: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Point i's distance to shape ``k[i]`` (N,) and its gradient in (theta, q, w) (N, n)."""
        z, jz = self.inputs(theta, pfix, q)
        n = len(y)
        d, g = np.empty(n), np.empty((n, self.n_vars))
        nz = jz.shape[1]
        for j in np.unique(k):
            rows = np.flatnonzero(k == j)
            a, b = self.cuts[j], self.cuts[j + 1]
            dj, gj = self.point_grads[j].batch(z, w, y[rows])
            gj = np.asarray(gj).reshape(len(rows), -1)
            d[rows] = np.asarray(dj).reshape(-1)
            g[rows, :nz] = gj[:, : b - a] @ jz[a:b]
            g[rows, nz:] = gj[:, b - a :]
        return d, g

    def all_gradients(
        self, theta: np.ndarray, pfix: np.ndarray, q: np.ndarray, w: np.ndarray, y: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N, S) distances and (N, S, n) gradients of every shape at every point."""
        n, s = len(y), len(self.shapes)
        d, g = np.empty((n, s)), np.empty((n, s, self.n_vars))
        for j in range(s):
            d[:, j], g[:, j] = self.gradients(theta, pfix, q, w, y, np.full(n, j))
        return d, g


@lru_cache(maxsize=32)
def _build_parts(concept: Concept, shapes: tuple[str, ...]) -> PartsModel:
    theta, pfix, q, w, y, p, local = _symbols(concept)
    inputs = _Inputs()
    cuts = [0]
    own = primitive_own_shape(concept)
    if own is not None and not concept.entry["shapes"]:
        values = {
            s.name: inputs(p[s.offset] if s.size == 1 else p[s.offset : s.offset + s.size])
            for s in concept.params
        }
        names = [own["name"]]
        links = [concept.links[0] if concept.links else "base"]
        ds = [primitive_sdf_casadi(concept.name, values, local)]
        cuts.append(len(inputs.symbols))
    else:
        g = _SplitGraph(concept, shapes, p, q, inputs)
        names = g.outermost()
        links = [g.entries[n]["link"] for n in names]
        ds = []
        for n in names:
            ds.append(g.sdf(n, g.motion(g.entries[n]["link"]) @ g.shape(n)[0], local))
            cuts.append(len(inputs.symbols))
    z = ca.vertcat(*inputs.symbols) if inputs.symbols else ca.SX.sym("z", 1)
    zexpr = ca.vertcat(*inputs.exprs) if inputs.exprs else ca.SX.zeros(1)
    name = f"fitsplit_{concept.name.lower()}_{zlib.crc32('|'.join(shapes).encode()):08x}"
    fns = {
        f"{name}_s": ca.Function(
            f"{name}_s", [theta, pfix, q], [zexpr, ca.jacobian(zexpr, ca.vertcat(theta, q))]
        ),
        f"{name}_d": ca.Function(f"{name}_d", [z, w, y], [ca.vertcat(*ds)]),
    }
    for k, d in enumerate(ds):
        mine = ca.vertcat(z[cuts[k] : cuts[k + 1]], w)
        fns[f"{name}_g{k}"] = ca.Function(f"{name}_g{k}", [z, w, y], [d, ca.jacobian(d, mine)])
    # z and w are the same for every point: the kernels read them once per batch
    fast = native.fast_functions(
        fns, uniform={n: frozenset({0, 1}) for n in fns if n != f"{name}_s"}
    )
    return PartsModel(
        concept,
        float_index(concept),
        len(concept.moving_joints),
        tuple(names),
        tuple(links),
        fast[f"{name}_s"],
        fast[f"{name}_d"],
        tuple(fast[f"{name}_g{k}"] for k in range(len(ds))),
        tuple(cuts),
    )


def parts_model(concept: Concept, shapes: tuple[str, ...]) -> PartsModel:
    """The per-shape distances of ``concept`` over ``shapes`` (as ``sdf_model``), for the
    part-labelled fit; built once per concept and shape set, native code cached on disk by
    content."""
    return _build_parts(concept, tuple(shapes))
