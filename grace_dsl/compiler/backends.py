"""Numeric backends that lowering writes to: CasADi SX, SymPy and NumPy.

Lowering is written once against this small set of scalar operations; each backend gives them
its own meaning: symbolic graphs for fast code (CasADi), exact formulas for people and prompts
(SymPy), and plain numbers for checks at the defaults (NumPy, elementwise over arrays too).
Arithmetic (+ - * / and unary -) uses Python operators, which all three types support.
The SymPy backend lives in ``sympy_backend`` so that importing the runtime does not import SymPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import casadi as ca
import numpy as np

from grace_dsl.compiler.types import UNIT_FACTORS
from grace_dsl.lang import ast


def literal_fraction(n: ast.Number) -> tuple[Fraction, bool]:
    """A literal as an exact rational of SI units, and whether it is a multiple of pi."""
    value = Fraction(n.text)
    if n.unit is None:
        return value, False
    _, num, den, with_pi = UNIT_FACTORS[n.unit]
    return value * Fraction(num, den), with_pi


def literal_value(n: ast.Number) -> float:
    frac, with_pi = literal_fraction(n)
    return float(frac) * (math.pi if with_pi else 1.0)


@dataclass(frozen=True)
class NumpyBackend:
    name: str = "numpy"

    def literal(self, n: ast.Number) -> Any:
        return np.float64(literal_value(n))

    def num(self, x: float) -> Any:
        return np.float64(x)

    pi = np.float64(math.pi)

    def sin(self, x: Any) -> Any:
        return np.sin(x)

    def cos(self, x: Any) -> Any:
        return np.cos(x)

    def tan(self, x: Any) -> Any:
        return np.tan(x)

    def asin(self, x: Any) -> Any:
        return np.arcsin(x)

    def acos(self, x: Any) -> Any:
        return np.arccos(x)

    def atan2(self, y: Any, x: Any) -> Any:
        return np.arctan2(y, x)

    def sqrt(self, x: Any) -> Any:
        return np.sqrt(x)

    def abs(self, x: Any) -> Any:
        return np.abs(x)

    def min(self, a: Any, b: Any) -> Any:
        return np.minimum(a, b)

    def max(self, a: Any, b: Any) -> Any:
        return np.maximum(a, b)

    def pow(self, a: Any, b: Any) -> Any:
        return np.power(a, b)

    def if_else(self, c: Any, a: Any, b: Any) -> Any:
        return np.where(c, a, b)

    def compare(self, op: str, a: Any, b: Any) -> Any:
        return {
            "<": np.less,
            "<=": np.less_equal,
            ">": np.greater,
            ">=": np.greater_equal,
            "==": np.equal,
            "!=": np.not_equal,
        }[op](a, b)

    def and_(self, a: Any, b: Any) -> Any:
        return np.logical_and(a, b)

    def or_(self, a: Any, b: Any) -> Any:
        return np.logical_or(a, b)

    def not_(self, a: Any) -> Any:
        return np.logical_not(a)

    def boolean(self, b: bool) -> Any:
        return np.bool_(b)

    def truth(self, x: Any) -> Any:
        """A stored 0/1 parameter as a condition."""
        return np.not_equal(x, 0)

    def as_number(self, c: Any) -> Any:
        """A condition as 0/1."""
        return np.where(c, 1.0, 0.0)


@dataclass(frozen=True)
class CasadiBackend:
    name: str = "casadi"

    def literal(self, n: ast.Number) -> Any:
        return ca.SX(literal_value(n))

    def num(self, x: float) -> Any:
        return ca.SX(x)

    pi = ca.SX(math.pi)

    def sin(self, x: Any) -> Any:
        return ca.sin(x)

    def cos(self, x: Any) -> Any:
        return ca.cos(x)

    def tan(self, x: Any) -> Any:
        return ca.tan(x)

    def asin(self, x: Any) -> Any:
        return ca.asin(x)

    def acos(self, x: Any) -> Any:
        return ca.acos(x)

    def atan2(self, y: Any, x: Any) -> Any:
        return ca.atan2(y, x)

    def sqrt(self, x: Any) -> Any:
        return ca.sqrt(x)

    def abs(self, x: Any) -> Any:
        return ca.fabs(x)

    def min(self, a: Any, b: Any) -> Any:
        return ca.fmin(a, b)

    def max(self, a: Any, b: Any) -> Any:
        return ca.fmax(a, b)

    def pow(self, a: Any, b: Any) -> Any:
        return a**b

    def if_else(self, c: Any, a: Any, b: Any) -> Any:
        return ca.if_else(c, a, b)

    def compare(self, op: str, a: Any, b: Any) -> Any:
        a, b = ca.SX(a), ca.SX(b)
        return {"<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b, "==": a == b, "!=": a != b}[op]

    def and_(self, a: Any, b: Any) -> Any:
        return ca.logic_and(a, b)

    def or_(self, a: Any, b: Any) -> Any:
        return ca.logic_or(a, b)

    def not_(self, a: Any) -> Any:
        return ca.logic_not(a)

    def boolean(self, b: bool) -> Any:
        return ca.SX(1.0 if b else 0.0)

    def truth(self, x: Any) -> Any:
        return x != 0

    def as_number(self, c: Any) -> Any:
        return ca.if_else(c, 1.0, 0.0)


Backend = Any  # NumpyBackend | CasadiBackend | sympy_backend.SympyBackend: same methods
NUMPY = NumpyBackend()
CASADI = CasadiBackend()
