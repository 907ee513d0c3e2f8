"""Interval arithmetic as a lowering backend: every value is an interval that holds it.

``evaluate.Evaluator`` over ``INTERVALS`` gives each sub-expression an interval containing all
its values when the parameters range over their intervals (up to float rounding; the tests sample
this).  Conditions are sub-intervals of [0, 1]: [1, 1] surely true, [0, 0] surely false, [0, 1]
either; ``if`` takes the branch a sure condition picks, else the hull of both.  A division by an
interval holding 0 and a fractional power of a base reaching 0 give the whole line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from grace_dsl.compiler.backends import literal_value
from grace_dsl.lang import ast

INF = math.inf


@dataclass(frozen=True)
class Interval:
    """The closed real interval [lo, hi]; infinite ends allowed, never NaN."""

    lo: float
    hi: float

    def __post_init__(self) -> None:
        if math.isnan(self.lo) or math.isnan(self.hi):
            object.__setattr__(self, "lo", -INF)
            object.__setattr__(self, "hi", INF)

    @property
    def finite(self) -> bool:
        return math.isfinite(self.lo) and math.isfinite(self.hi)

    def contains(self, x: float) -> bool:
        return self.lo <= x <= self.hi

    def __add__(self, other: Any) -> Interval:
        o = iv(other)
        return Interval(self.lo + o.lo, self.hi + o.hi)

    __radd__ = __add__

    def __sub__(self, other: Any) -> Interval:
        o = iv(other)
        return Interval(self.lo - o.hi, self.hi - o.lo)

    def __rsub__(self, other: Any) -> Interval:
        return iv(other) - self

    def __neg__(self) -> Interval:
        return Interval(-self.hi, -self.lo)

    def __pos__(self) -> Interval:
        return self

    def __mul__(self, other: Any) -> Interval:
        if other is self:  # a square is never negative
            a, b = abs(self.lo), abs(self.hi)
            low = 0.0 if self.contains(0.0) else _mul(min(a, b), min(a, b))
            return Interval(low, _mul(max(a, b), max(a, b)))
        o = iv(other)
        ends = [_mul(x, y) for x in (self.lo, self.hi) for y in (o.lo, o.hi)]
        return Interval(min(ends), max(ends))

    __rmul__ = __mul__

    def __truediv__(self, other: Any) -> Interval:
        o = iv(other)
        if o.contains(0.0):
            return ENTIRE
        return self * Interval(*sorted((1.0 / o.hi, 1.0 / o.lo)))

    def __rtruediv__(self, other: Any) -> Interval:
        return iv(other) / self


ENTIRE = Interval(-INF, INF)
FALSE, TRUE, EITHER = Interval(0.0, 0.0), Interval(1.0, 1.0), Interval(0.0, 1.0)


def iv(x: Any) -> Interval:
    """A number or interval as an interval."""
    if isinstance(x, Interval):
        return x
    return Interval(float(x), float(x))


def hull(a: Any, b: Any) -> Any:
    """The smallest interval (per component) holding both."""
    if isinstance(a, tuple):
        return tuple(hull(x, y) for x, y in zip(a, b))
    if isinstance(a, str):
        return a
    x, y = iv(a), iv(b)
    return Interval(min(x.lo, y.lo), max(x.hi, y.hi))


def _mul(x: float, y: float) -> float:
    return 0.0 if x == 0.0 or y == 0.0 else x * y


def _monotone(f: Callable[[float], float], x: Interval, increasing: bool = True) -> Interval:
    with np.errstate(all="ignore"):
        a, b = float(f(x.lo)), float(f(x.hi))
    return Interval(a, b) if increasing else Interval(b, a)


def _wave(x: Interval, f: Callable[[float], float], peak: float) -> Interval:
    """``f`` = sin or cos over x: 1 where x holds a peak ``peak + 2k pi``, -1 where it holds a
    trough ``peak + pi + 2k pi``, else the larger or smaller end value."""
    if not x.finite or x.hi - x.lo >= 2 * math.pi:
        return Interval(-1.0, 1.0)
    ends = [f(x.lo), f(x.hi)]

    def holds(at: float) -> bool:
        return math.floor((x.hi - at) / (2 * math.pi)) * 2 * math.pi + at >= x.lo

    return Interval(-1.0 if holds(peak + math.pi) else min(ends), 1.0 if holds(peak) else max(ends))


def _tan(x: Interval) -> Interval:
    if not x.finite or x.hi - x.lo >= math.pi:
        return ENTIRE
    pole = math.floor((x.hi - math.pi / 2) / math.pi) * math.pi + math.pi / 2
    if pole >= x.lo:
        return ENTIRE
    return _monotone(math.tan, x)


def _atan2(y: Interval, x: Interval) -> Interval:
    """Over a box off the origin and off the branch cut (x < 0, y = 0) the angle's extremes
    are at the corners; otherwise the whole circle."""
    if (x.contains(0.0) and y.contains(0.0)) or (x.lo < 0 and y.contains(0.0)):
        return Interval(-math.pi, math.pi)
    ends = [math.atan2(b, a) for a in (x.lo, x.hi) for b in (y.lo, y.hi)]
    return Interval(min(ends), max(ends))


def _pow(a: Interval, b: Interval) -> Interval:
    with np.errstate(all="ignore"):
        if b.lo == b.hi and float(b.lo).is_integer():
            n = int(b.lo)
            if n == 0:
                return Interval(1.0, 1.0)
            if n < 0:
                return Interval(1.0, 1.0) / _pow(a, Interval(-n, -n))
            ends = [float(np.power(a.lo, n)), float(np.power(a.hi, n))]
            if n % 2 == 0 and a.contains(0.0):
                return Interval(0.0, max(ends))
            return Interval(min(ends), max(ends))
        if a.lo <= 0:
            return ENTIRE  # a negative base to a fractional power is undefined
        ends = [float(np.power(x, y)) for x in (a.lo, a.hi) for y in (b.lo, b.hi)]
        return Interval(min(ends), max(ends))


def _compare(op: str, a: Interval, b: Interval) -> Interval:
    if op in ("<", "<="):
        sure, never = (a.hi < b.lo, a.lo >= b.hi) if op == "<" else (a.hi <= b.lo, a.lo > b.hi)
    elif op in (">", ">="):
        return _compare("<" if op == ">" else "<=", b, a)
    else:
        same = a.lo == a.hi == b.lo == b.hi
        apart = a.hi < b.lo or b.hi < a.lo
        sure, never = (same, apart) if op == "==" else (apart, same)
    return TRUE if sure else FALSE if never else EITHER


@dataclass(frozen=True)
class IntervalBackend:
    """The backend interface over intervals; conditions are sub-intervals of [0, 1]."""

    name: str = "interval"
    pi = Interval(math.pi, math.pi)

    def literal(self, n: ast.Number) -> Interval:
        return iv(literal_value(n))

    def num(self, x: float) -> Interval:
        return iv(x)

    def sin(self, x: Any) -> Interval:
        return _wave(iv(x), math.sin, math.pi / 2)

    def cos(self, x: Any) -> Interval:
        return _wave(iv(x), math.cos, 0.0)

    def tan(self, x: Any) -> Interval:
        return _tan(iv(x))

    def asin(self, x: Any) -> Interval:
        c = iv(x)
        return _monotone(math.asin, Interval(max(c.lo, -1.0), min(c.hi, 1.0)))

    def acos(self, x: Any) -> Interval:
        c = iv(x)
        return _monotone(math.acos, Interval(max(c.lo, -1.0), min(c.hi, 1.0)), increasing=False)

    def atan2(self, y: Any, x: Any) -> Interval:
        return _atan2(iv(y), iv(x))

    def sqrt(self, x: Any) -> Interval:
        c = iv(x)
        return Interval(math.sqrt(max(c.lo, 0.0)), math.sqrt(max(c.hi, 0.0)))

    def abs(self, x: Any) -> Interval:
        c = iv(x)
        if c.contains(0.0):
            return Interval(0.0, max(-c.lo, c.hi))
        return Interval(min(abs(c.lo), abs(c.hi)), max(abs(c.lo), abs(c.hi)))

    def min(self, a: Any, b: Any) -> Interval:
        x, y = iv(a), iv(b)
        return Interval(min(x.lo, y.lo), min(x.hi, y.hi))

    def max(self, a: Any, b: Any) -> Interval:
        x, y = iv(a), iv(b)
        return Interval(max(x.lo, y.lo), max(x.hi, y.hi))

    def pow(self, a: Any, b: Any) -> Interval:
        return _pow(iv(a), iv(b))

    def if_else(self, c: Any, a: Any, b: Any) -> Any:
        cond = iv(c)
        return a if cond == TRUE else b if cond == FALSE else hull(a, b)

    def compare(self, op: str, a: Any, b: Any) -> Interval:
        return _compare(op, iv(a), iv(b))

    def and_(self, a: Any, b: Any) -> Interval:
        x, y = iv(a), iv(b)
        return Interval(min(x.lo, y.lo), min(x.hi, y.hi))

    def or_(self, a: Any, b: Any) -> Interval:
        x, y = iv(a), iv(b)
        return Interval(max(x.lo, y.lo), max(x.hi, y.hi))

    def not_(self, a: Any) -> Interval:
        x = iv(a)
        return Interval(1.0 - x.hi, 1.0 - x.lo)

    def boolean(self, b: bool) -> Interval:
        return TRUE if b else FALSE

    def truth(self, x: Any) -> Interval:
        return _compare("!=", iv(x), FALSE)

    def as_number(self, c: Any) -> Interval:
        return iv(c)


INTERVALS = IntervalBackend()
