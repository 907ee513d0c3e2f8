"""The SymPy backend: exact formulas (literals stay rationals, degrees become multiples of pi)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import sympy as sp

from grace_dsl.compiler.backends import literal_fraction
from grace_dsl.lang import ast


@dataclass(frozen=True)
class SympyBackend:
    name: str = "sympy"

    def literal(self, n: ast.Number) -> Any:
        frac, with_pi = literal_fraction(n)
        value = sp.Rational(frac.numerator, frac.denominator)
        return value * sp.pi if with_pi else value

    def num(self, x: float) -> Any:
        return sp.nsimplify(x) if float(x).is_integer() else sp.Float(x)

    pi = sp.pi

    def sin(self, x: Any) -> Any:
        return sp.sin(x)

    def cos(self, x: Any) -> Any:
        return sp.cos(x)

    def tan(self, x: Any) -> Any:
        return sp.tan(x)

    def asin(self, x: Any) -> Any:
        return sp.asin(x)

    def acos(self, x: Any) -> Any:
        return sp.acos(x)

    def atan2(self, y: Any, x: Any) -> Any:
        return sp.atan2(y, x)

    def sqrt(self, x: Any) -> Any:
        return sp.sqrt(x)

    def abs(self, x: Any) -> Any:
        return sp.Abs(x)

    def min(self, a: Any, b: Any) -> Any:
        return sp.Min(a, b)

    def max(self, a: Any, b: Any) -> Any:
        return sp.Max(a, b)

    def pow(self, a: Any, b: Any) -> Any:
        return sp.Pow(a, b)

    def if_else(self, c: Any, a: Any, b: Any) -> Any:
        if c is sp.true:
            return a
        if c is sp.false:
            return b
        return sp.Piecewise((a, c), (b, True))

    def compare(self, op: str, a: Any, b: Any) -> Any:
        return {"<": sp.Lt, "<=": sp.Le, ">": sp.Gt, ">=": sp.Ge, "==": sp.Eq, "!=": sp.Ne}[op](
            a, b
        )

    def and_(self, a: Any, b: Any) -> Any:
        return sp.And(a, b)

    def or_(self, a: Any, b: Any) -> Any:
        return sp.Or(a, b)

    def not_(self, a: Any) -> Any:
        return sp.Not(a)

    def boolean(self, b: bool) -> Any:
        return sp.true if b else sp.false

    def truth(self, x: Any) -> Any:
        return sp.Ne(x, 0)

    def as_number(self, c: Any) -> Any:
        return self.if_else(c, sp.Integer(1), sp.Integer(0))


SYMPY = SympyBackend()
