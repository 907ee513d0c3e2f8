"""The primitive registry: names, parameters (in the order of ``concepts/primitives.eac``), checks.

Every public function of :mod:`grace_dsl.geometry` starts here, so a misspelt name or a
negative radius fails once, with one clear message, instead of as a NaN deep in a formula.
Values are SI (metres, radians); missing parameters take the defaults of ``primitives.eac``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from grace_dsl.geometry.errors import GeometryError

Kind = Literal["length", "angle", "int", "bool", "vec2", "vec3"]
Value = float | int | tuple[float, ...]
Params = dict[str, Value]

FULL_TURN = 2.0 * math.pi
_ANGLE_SLACK = 1e-9  # 360deg converted through degrees may land a hair above 2*pi


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name, kind and default (SI); a length may be zero only if ``allow_zero``,
    negative only if ``signed`` (a shift, not a size)."""

    name: str
    kind: Kind
    default: Value
    allow_zero: bool = False
    signed: bool = False

    @property
    def size(self) -> int:
        return {"vec2": 2, "vec3": 3}.get(self.kind, 1)


@dataclass(frozen=True)
class PrimitiveSpec:
    """A primitive: its parameters in declaration order and its cross-parameter requirements."""

    name: str
    params: tuple[ParamSpec, ...]
    requires: tuple[tuple[Callable[[Params], bool], str], ...] = ()

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def defaults(self) -> Params:
        return {p.name: p.default for p in self.params}


def _p(
    name: str, kind: Kind, default: Value, allow_zero: bool = False, signed: bool = False
) -> ParamSpec:
    return ParamSpec(name, kind, default, allow_zero, signed)


def _f(params: Params, name: str) -> float:
    value = params[name]
    assert isinstance(value, float)
    return value


def _v(params: Params, name: str) -> tuple[float, ...]:
    value = params[name]
    assert isinstance(value, tuple)
    return value


def _i(params: Params, name: str) -> int:
    value = params[name]
    assert isinstance(value, int)
    return value


LENGTH_KINDS = ("length", "vec2", "vec3")  # the kinds that scale with the primitive


PRIMITIVES: dict[str, PrimitiveSpec] = {
    spec.name: spec
    for spec in (
        PrimitiveSpec("Cuboid", (_p("size", "vec3", (0.1, 0.1, 0.1)),)),
        PrimitiveSpec(
            "Cylinder",
            (
                _p("radius", "length", 0.02),
                _p("height", "length", 0.1),
                _p("radian", "angle", FULL_TURN),
            ),
        ),
        PrimitiveSpec(
            "Tube",
            (_p("r_in", "length", 0.015), _p("r_out", "length", 0.02), _p("height", "length", 0.1)),
            ((lambda q: _f(q, "r_out") > _f(q, "r_in"), "r_out > r_in (the wall needs material)"),),
        ),
        PrimitiveSpec(
            "Ring",
            (
                _p("r_in", "length", 0.04),
                _p("r_out", "length", 0.048),
                _p("height", "length", 0.012),
                _p("radian", "angle", math.radians(120.0)),
            ),
            ((lambda q: _f(q, "r_out") > _f(q, "r_in"), "r_out > r_in (the ring needs material)"),),
        ),
        PrimitiveSpec(
            "RectRing",
            (
                _p("outer", "vec2", (0.4, 0.6)),
                _p("inner", "vec2", (0.36, 0.56)),
                _p("depth", "length", 0.02),
            ),
            (
                (
                    lambda q: all(i < o for i, o in zip(_v(q, "inner"), _v(q, "outer"))),
                    "inner.x < outer.x and inner.y < outer.y (the frame needs material)",
                ),
            ),
        ),
        PrimitiveSpec("Sphere", (_p("radius", "length", 0.02),)),
        PrimitiveSpec("Capsule", (_p("radius", "length", 0.01), _p("length", "length", 0.1))),
        PrimitiveSpec(
            "Frustum",
            (
                _p("r_bottom", "length", 0.02, allow_zero=True),
                _p("r_top", "length", 0.01, allow_zero=True),
                _p("height", "length", 0.05),
            ),
            (
                (
                    lambda q: _f(q, "r_bottom") + _f(q, "r_top") > 0,
                    "r_bottom + r_top > 0 (one end needs a radius)",
                ),
            ),
        ),
        PrimitiveSpec(
            "TaperedCuboid",
            (
                _p("size", "vec3", (0.1, 0.1, 0.1)),
                _p("top", "vec2", (0.06, 0.06), allow_zero=True),
                _p("offset", "vec2", (0.0, 0.0), allow_zero=True, signed=True),
            ),
        ),
        PrimitiveSpec(
            "SphericalCap",
            (_p("radius", "length", 0.02), _p("height", "length", 0.01)),
            (
                (
                    lambda q: _f(q, "height") <= 2 * _f(q, "radius"),
                    "height <= 2 * radius (a cap is at most the whole ball)",
                ),
            ),
        ),
        PrimitiveSpec(
            "Torus",
            (
                _p("r_major", "length", 0.04),
                _p("r_minor", "length", 0.005),
                _p("radian", "angle", FULL_TURN),
            ),
            (
                (
                    lambda q: _f(q, "r_minor") < _f(q, "r_major"),
                    "r_minor < r_major (the tube must not reach the axis)",
                ),
            ),
        ),
        PrimitiveSpec(
            "Prism",
            (_p("sides", "int", 6), _p("radius", "length", 0.02), _p("height", "length", 0.02)),
            ((lambda q: _i(q, "sides") >= 3, "sides >= 3 (a polygon has at least three)"),),
        ),
        PrimitiveSpec(
            "BoardBox",
            (
                _p("size", "vec3", (0.6, 0.72, 0.56)),
                _p("board", "length", 0.018),
                _p("top", "bool", True),
                _p("front", "bool", False),
            ),
            (
                (
                    lambda q: all(2 * _f(q, "board") < s for s in _v(q, "size")),
                    "2 * board < every side of size (the boards leave a cavity)",
                ),
            ),
        ),
    )
}


def get_spec(name: str) -> PrimitiveSpec:
    """The spec of primitive ``name``, or a :class:`GeometryError` naming the known ones."""
    try:
        return PRIMITIVES[name]
    except (KeyError, TypeError):
        known = ", ".join(PRIMITIVES)
        raise GeometryError(f"unknown primitive {name!r}; known primitives: {known}") from None


def check_names(name: str, params: Mapping[str, Any]) -> PrimitiveSpec:
    """The spec, after checking that every key of ``params`` is one of its parameters."""
    spec = get_spec(name)
    unknown = [k for k in params if k not in spec.param_names]
    if unknown:
        raise GeometryError(
            f"{name} has no parameter {', '.join(map(repr, unknown))}; "
            f"its parameters are: {', '.join(spec.param_names)}"
        )
    return spec


def _check_value(prim: str, ps: ParamSpec, raw: Any) -> Value:
    where = f"{prim}.{ps.name}"
    try:
        arr = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise GeometryError(f"{where} must be a number, got {raw!r}") from None
    if arr.size != ps.size or (ps.size == 1 and arr.ndim > 1) or arr.ndim > 1:
        shape = "a number" if ps.size == 1 else f"{ps.size} numbers (a {ps.kind})"
        raise GeometryError(f"{where} must be {shape}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise GeometryError(f"{where} must be finite, got {raw!r}")
    if ps.kind == "bool":
        if arr.item() not in (0.0, 1.0):
            raise GeometryError(f"{where} must be true or false (1 or 0), got {raw!r}")
        return bool(arr.item())
    if ps.kind == "int":
        if isinstance(raw, bool) or arr.item() != round(arr.item()):
            raise GeometryError(f"{where} must be a whole number, got {raw!r}")
        return int(round(arr.item()))
    if ps.signed:
        return tuple(float(a) for a in arr.ravel()) if ps.size > 1 else float(arr.item())
    if np.any(arr < 0) or (not ps.allow_zero and np.any(arr == 0)):
        bound = ">= 0" if ps.allow_zero else "> 0"
        raise GeometryError(f"{where} must be {bound} (SI units: metres, radians), got {raw!r}")
    if ps.kind == "angle":
        if arr.item() > FULL_TURN + _ANGLE_SLACK:
            raise GeometryError(f"{where} must be at most 2*pi rad (360deg), got {raw!r}")
        return min(float(arr.item()), FULL_TURN)
    return float(arr.item()) if ps.size == 1 else tuple(float(a) for a in arr.ravel())


def validate(name: str, params: Mapping[str, Any] | None = None) -> Params:
    """Checked SI parameters (floats, tuples for vectors), defaults filled in for missing ones."""
    params = {} if params is None else params
    if not isinstance(params, Mapping):
        raise GeometryError(f"parameters of {name} must be a dict, got {type(params).__name__}")
    spec = check_names(name, params)
    out: Params = {}
    for ps in spec.params:
        out[ps.name] = _check_value(name, ps, params[ps.name]) if ps.name in params else ps.default
    for ok, message in spec.requires:
        if not ok(out):
            raise GeometryError(f"{name} needs {message}; got {out}")
    return out


def default_params(name: str) -> Params:
    """The defaults of ``primitives.eac`` in SI units."""
    return get_spec(name).defaults()
