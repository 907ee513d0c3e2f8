"""Values with units on the command line (``--joint hinge=45deg``, ``--param size=600mm,...``).

The language's unit table (``compiler.types.UNIT_FACTORS``) converts them, so ``45deg`` means
on the command line what it means in a ``.eac`` file. A bare number is SI (m, rad), as before.
A regular expression reads each number; nothing is evaluated.
"""

from __future__ import annotations

import math
import re

from grace_dsl.compiler.types import UNIT_FACTORS

_QUANTITY = re.compile(r"([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z]*)")


class UnitSyntaxError(ValueError):
    """A value that is not a number with an optional unit of the right kind."""


def unit_names(dim: str) -> str:
    """The units of a dimension, for messages: ``"mm, cm, m"``."""
    return ", ".join(u for u, (d, *_rest) in UNIT_FACTORS.items() if str(d) == dim)


def quantity(text: str, dim: str | None) -> float:
    """``"45deg"`` (``dim="angle"``) -> 0.785...; ``"0.5"`` -> 0.5 (a bare number is SI).

    ``dim`` is the dimension the value must have ("length", "angle", "scalar" or None for a
    plain number); a unit of another dimension is refused."""
    match = _QUANTITY.fullmatch(text.strip())
    if match is None:
        raise UnitSyntaxError(f"{text.strip()!r} is not a number")
    number, unit = match.groups()
    value = float(number)
    if unit:
        if unit not in UNIT_FACTORS:
            raise UnitSyntaxError(f"unknown unit {unit!r} in {text.strip()!r}")
        unit_dim, num, den, with_pi = UNIT_FACTORS[unit]
        if dim is not None and str(unit_dim) != dim:
            wanted = unit_names(dim) if dim in ("length", "angle") else ""
            raise UnitSyntaxError(
                f"{text.strip()!r} is {_a(str(unit_dim))}, expected {_a(dim)}"
                + (f" ({wanted}, or a bare number in SI)" if wanted else "")
            )
        value = value * num / den * (math.pi if with_pi else 1.0)
    if not math.isfinite(value):
        raise UnitSyntaxError(f"{text.strip()!r} is not a finite number")
    return value


def _a(noun: str) -> str:
    return ("an " if noun[0] in "aeiou" else "a ") + noun


def quantities(text: str, dim: str | None) -> list[float]:
    """``"600mm, 400mm, 20mm"`` or ``"(0.6 0.4 0.02)"`` -> [0.6, 0.4, 0.02]."""
    parts = [x for x in text.strip().strip("()[]").replace(",", " ").split() if x]
    if not parts:
        raise UnitSyntaxError(f"{text!r} holds no number")
    return [quantity(p, dim) for p in _glue(parts)]


def _glue(parts: list[str]) -> list[str]:
    """``["45", "deg"]`` -> ``["45deg"]``: a unit written after a space belongs to its number."""
    out: list[str] = []
    for p in parts:
        if out and p.isalpha() and p in UNIT_FACTORS and not out[-1][-1:].isalpha():
            out[-1] += p
        else:
            out.append(p)
    return out
