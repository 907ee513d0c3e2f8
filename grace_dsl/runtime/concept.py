"""A compiled concept: its parameter schema, and instantiation with validated values.

The schema comes from the manifest; evaluation goes through the fastest evaluator available
(native code generated from the CasADi graph, or CasADi's VM).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from grace_dsl.compiler.types import format_si
from grace_dsl.lang.diagnostics import closest
from grace_dsl.runtime.errors import ParameterError, RequirementError, UnknownNameError
from grace_dsl.runtime.inputs import as_array, show_value
from grace_dsl.tolerances import RANGE_SLACK

Evaluate = Callable[..., Any]


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: SI units; ``lo``/``hi``/``default`` are floats or tuples for vectors."""

    name: str
    type: str
    kind: str  # num | int | vec | bool | choice
    dim: str | None
    size: int
    offset: int
    lo: Any
    hi: Any
    default: Any
    choices: tuple[str, ...] | None
    help: str | None
    doc: str

    @staticmethod
    def from_entry(e: Mapping[str, Any]) -> ParamSpec:
        def tup(v: Any) -> Any:
            return tuple(v) if isinstance(v, list) else v

        return ParamSpec(
            e["name"],
            e["type"],
            e["kind"],
            e["dim"],
            e["size"],
            e["offset"],
            tup(e["lo"]),
            tup(e["hi"]),
            tup(e["default"]),
            tuple(e["choices"]) if e["choices"] else None,
            e["help"],
            e["doc"],
        )

    def encode(self, value: Any) -> np.ndarray:
        """A user value as the entries of the parameter vector, validated."""
        if self.kind == "choice":
            assert self.choices is not None
            if not isinstance(value, str) or value not in self.choices:
                raise ParameterError(
                    f"{self.name} must be one of {list(self.choices)}, not {value!r}"
                )
            return np.array([float(self.choices.index(value))])
        if self.kind == "bool":
            if not isinstance(value, (bool, np.bool_)):
                raise ParameterError(f"{self.name} is a bool, not {value!r}")
            return np.array([float(value)])
        if _has_bool(value):
            raise ParameterError(
                f"{self.name} is a {self.type}, not a bool: got {show_value(value)}"
            )
        try:
            arr = as_array(self.name, value)
        except ParameterError:
            raise ParameterError(
                f"{self.name} must be {'a number' if self.size == 1 else f'{self.size} numbers'}"
                f" ({self.type}), not {show_value(value)}"
            ) from None
        if arr.ndim > 1:  # [[0.1]] is a matrix, not a number or a vector
            raise ParameterError(
                f"{self.name} must be {'a number' if self.size == 1 else f'{self.size} numbers'}"
                f" ({self.type}), not a nested list: {show_value(value)}"
            )
        arr = arr.reshape(-1)
        if arr.size != self.size:
            raise ParameterError(
                f"{self.name} takes {self.size} value(s) ({self.type}), got {arr.size}"
            )
        if not np.all(np.isfinite(arr)):
            raise ParameterError(f"{self.name} must be finite, got {show_value(value)}")
        if self.kind == "int" and not np.all(arr == np.round(arr)):
            raise ParameterError(f"{self.name} is an int, got {show_value(value)}")
        self._check_range(arr)
        return arr

    def _check_range(self, arr: np.ndarray) -> None:
        if self.lo is None:
            return
        lo, hi = np.atleast_1d(self.lo), np.atleast_1d(self.hi)
        # written so that a NaN bound fails the check instead of disabling it
        if not (np.all(arr >= lo - RANGE_SLACK) and np.all(arr <= hi + RANGE_SLACK)):
            hint = (
                '; the range is the typical real-world spread: instantiate(..., ranges="valid")'
                " accepts any value the concept's requirements and shapes allow"
                if self.kind in ("num", "vec", "int") and np.all(np.isfinite(arr))
                else ""
            )
            raise ParameterError(
                f"{self.name} = {format_si(arr, self.dim)} is outside its range "
                f"[{format_si(lo, self.dim)}, {format_si(hi, self.dim)}] (values are in SI units: "
                f"{_SI_UNITS.get(self.dim or '', 'no unit')}){hint}"
            )

    def unbounded(self) -> ParamSpec:
        """The same parameter without its typical range (``ranges="valid"`` packs with it and
        checks the domain with :func:`check_domain` instead)."""
        return replace(self, lo=None, hi=None)

    def decode(self, entries: np.ndarray) -> Any:
        if self.kind == "choice":
            assert self.choices is not None
            return self.choices[int(round(entries[0]))]
        if self.kind == "bool":
            return bool(entries[0])
        return tuple(float(x) for x in entries) if self.kind == "vec" else float(entries[0])


_SI_UNITS = {"length": "metres", "angle": "radians"}

RANGES = ("typical", "valid")
"""What ``Concept.instantiate(..., ranges=...)`` checks the parameters against: ``typical`` the
declared ranges (the real-world spread that sampling, ``eacc verify`` and perception priors use),
``valid`` the domain below plus the instance's own validity (see ``Instance.create``)."""

ONE_TURN = 2 * math.pi  # rad: the largest angle magnitude a valid parameter may take


def check_ranges_mode(ranges: Any) -> str:
    """``ranges`` as given to ``instantiate``, or a ``ParameterError`` naming the choices."""
    if not isinstance(ranges, str) or ranges not in RANGES:
        raise ParameterError(f'ranges must be "typical" or "valid", not {ranges!r:.60}')
    return ranges


def check_domain(specs: Sequence[ParamSpec], p: np.ndarray, concept: str) -> None:
    """Raise unless every number of ``p`` lies in its parameter's valid domain.

    Why: outside its typical range a value is still a real object as long as it keeps the sign
    that range gives it (a length whose range is positive stays positive, one that starts at 0
    stays non-negative, a signed offset may take any value) and an angle stays within one turn
    either way; requirements and shapes are checked by the caller.
    """
    for s in specs:
        if s.kind not in ("num", "vec", "int") or s.lo is None or s.hi is None:
            continue
        lo, hi = np.atleast_1d(np.asarray(s.lo, float)), np.atleast_1d(np.asarray(s.hi, float))
        values = p[s.offset : s.offset + s.size]
        for k, v in enumerate(values.tolist()):
            problem = _domain_problem(float(lo[k]), float(hi[k]), v, s.dim)
            if problem:
                part = f"{s.name}[{k}]" if s.size > 1 else s.name
                shown = format_si(np.array([v]), s.dim)
                typical = f"[{format_si(lo[k : k + 1], s.dim)}, {format_si(hi[k : k + 1], s.dim)}]"
                raise ParameterError(
                    f"{concept}: {part} = {shown} is not a valid value: {problem} "
                    f"(its typical range is {typical})"
                )


def _domain_problem(lo: float, hi: float, v: float, dim: str | None) -> str:
    """Why ``v`` leaves the domain of a parameter whose typical range is [lo, hi], or ''."""
    if lo > 0 and not v > 0:
        return "it must be positive"
    if lo == 0 and not v >= 0:
        return "it must not be negative"
    if hi < 0 and not v < 0:
        return "it must be negative"
    if hi == 0 and not v <= 0:
        return "it must not be positive"
    if dim == "angle" and not abs(v) <= ONE_TURN + RANGE_SLACK:
        return "an angle lies within one turn (360deg) either way"
    return ""


def _has_bool(value: Any) -> bool:
    """True for a bool, or a tuple or list holding one (numpy would read them as 0 and 1)."""
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype == np.bool_
    return isinstance(value, (tuple, list)) and any(isinstance(v, (bool, np.bool_)) for v in value)


def suggest(name: Any, known: Any) -> str:
    """The tail of an unknown-name error: the likely name, or every known one."""
    if not isinstance(name, str):
        return f"; names are strings, not {type(name).__name__}; known: {', '.join(known)}"
    match = closest(name, known)
    return f"; did you mean {match!r}?" if match else f"; known: {', '.join(known)}"


def pack_params(
    specs: tuple[ParamSpec, ...], values: Mapping[str, Any], concept: str
) -> np.ndarray:
    """The flat parameter vector of ``values`` (missing ones take their defaults)."""
    return ParamPacker.of(specs).pack(values, concept)


_FLOATS = frozenset((float, int, np.float64))
_Slot = tuple[int, int, tuple[float, ...] | None, tuple[float, ...] | None]
_TOL = 1e-12  # the tolerance of ParamSpec._check_range


@dataclass(frozen=True)
class ParamPacker:
    """Packs user values into the flat parameter vector, fast for plain numbers and tuples.

    Why: a perception loop instantiates a concept per estimate, and numpy's per-value overhead
    (asarray, reshape, any/all) dominated that call. Plain Python numbers inside their ranges
    are checked here with float comparisons; anything else (arrays, choices, ints, bools, values
    out of range, NaN) goes through ``ParamSpec.encode``, which validates and raises the errors.
    """

    specs: tuple[ParamSpec, ...]
    by_name: dict[str, ParamSpec]
    default: np.ndarray
    # name -> (offset, size, lo, hi) of real-valued parameters, bounds as floats (None: unbounded)
    fast: dict[str, _Slot]

    @staticmethod
    def of(specs: tuple[ParamSpec, ...]) -> ParamPacker:
        default = np.empty(sum(s.size for s in specs))
        fast = {}
        for s in specs:
            default[s.offset : s.offset + s.size] = np.atleast_1d(
                np.asarray(s.default, dtype=float)
            )
            if s.kind in ("num", "vec"):
                # bounds widened by the tolerance of ParamSpec._check_range
                lo = None if s.lo is None else tuple(float(x) - _TOL for x in np.atleast_1d(s.lo))
                hi = None if s.hi is None else tuple(float(x) + _TOL for x in np.atleast_1d(s.hi))
                if all(b is None or len(b) == s.size for b in (lo, hi)):
                    fast[s.name] = (s.offset, s.size, lo, hi)
        return ParamPacker(specs, {s.name: s for s in specs}, default, fast)

    def pack(self, values: Mapping[str, Any], concept: str) -> np.ndarray:
        by_name = self.by_name
        for name in values:
            if name not in by_name:
                raise UnknownNameError(
                    f"{concept} has no parameter {name!r}" + suggest(name, by_name)
                )
        p = self.default.copy()
        slow = [
            by_name[name]
            for name, value in values.items()
            if (slot := self.fast.get(name)) is None or not _put_fast(p, slot, value)
        ]
        for s in sorted(slow, key=lambda s: s.offset):  # errors in declaration order
            p[s.offset : s.offset + s.size] = s.encode(values[s.name])
        return p


def _put_fast(p: np.ndarray, slot: _Slot, value: Any) -> bool:
    """Write a plain number or tuple of numbers that is finite and in range; False otherwise
    (the caller then takes the validating path, which raises the right error)."""
    offset, size, lo, hi = slot
    if size == 1 and type(value) in _FLOATS:
        try:
            v = float(value)
        except OverflowError:  # an int beyond float: the validating path words the error
            return False
        # NaN fails every comparison, inf the range
        ok = math.isfinite(v) if lo is None or hi is None else lo[0] <= v <= hi[0]
        if ok:
            p[offset] = v
        return ok
    if type(value) is not tuple or len(value) != size:
        return False
    vs = []
    for k, x in enumerate(value):
        if type(x) not in _FLOATS:
            return False
        try:
            v = float(x)
        except OverflowError:
            return False
        if not (math.isfinite(v) if lo is None or hi is None else lo[k] <= v <= hi[k]):
            return False
        vs.append(v)
    p[offset : offset + size] = vs
    return True


def check_requirements(
    holds: Sequence[float],
    requires: Sequence[Mapping[str, Any]],
    specs: Sequence[ParamSpec],
    p: np.ndarray,
    concept: str,
) -> None:
    """Raise if any requirement is false (``holds`` is 1 where one is true, 0 or NaN where not),
    naming each failed one with its condition and the values of the parameters it reads, so
    the user sees which value to change."""
    by_name = {s.name: s for s in specs}
    bad = [
        _explain(i, r, by_name, p)
        for i, (h, r) in enumerate(zip(holds, requires, strict=True))
        if h != 1
    ]
    if bad:
        count = f"{len(bad)} requirement{'s' if len(bad) > 1 else ''}"
        raise RequirementError(f"{concept}: the parameters violate {count}: " + "; ".join(bad))


def _explain(i: int, req: Mapping[str, Any], specs: Mapping[str, ParamSpec], p: np.ndarray) -> str:
    """``message (condition, file.eac:N) with a = ..., b = ...`` for one failed requirement."""
    text = req.get("message") or f"requirement {i + 1}"
    where = ", ".join(x for x in (req.get("condition"), req.get("where")) if x)
    values = [_value_text(specs[n], p) for n in req.get("params", ()) if n in specs]
    return (
        text + (f" ({where})" if where else "") + (f" with {', '.join(values)}" if values else "")
    )


def _value_text(spec: ParamSpec, p: np.ndarray) -> str:
    value = spec.decode(p[spec.offset : spec.offset + spec.size])
    if spec.kind in ("num", "vec"):
        return f"{spec.name} = {format_si(np.atleast_1d(np.asarray(value, float)), spec.dim)}"
    return f"{spec.name} = {value!r}"
