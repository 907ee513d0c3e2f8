"""The static types of .eac values: numbers with dimensions, vectors, rotations and poses.

A dimension is a power of length plus an "angle" tag.  Radians are dimensionless in SI, so the
tag is dropped as soon as an angle is multiplied by a length (an arc length ``r * theta`` is a
length), but it keeps ``length + angle`` and ``angle + 3`` from passing unnoticed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Dim:
    length: int = 0
    angle: bool = False

    def __str__(self) -> str:
        if self.angle:
            return "angle"
        return {0: "scalar", 1: "length"}.get(self.length, f"length^{self.length}")


SCALAR = Dim()
LENGTH = Dim(1)
ANGLE = Dim(0, True)


def mul_dim(a: Dim, b: Dim) -> Dim:
    length = a.length + b.length
    return Dim(length, length == 0 and (a.angle != b.angle))


def div_dim(a: Dim, b: Dim) -> Dim:
    length = a.length - b.length
    return Dim(length, length == 0 and a.angle and not b.angle)


@dataclass(frozen=True)
class Type:
    """kind: num | vec | rot | pose | bool | choice | string | shape."""

    kind: str
    dim: Dim = SCALAR
    size: int = 1
    choices: tuple[str, ...] = ()
    integer: bool = False

    def __str__(self) -> str:
        if self.kind == "num":
            return "int" if self.integer else str(self.dim)
        if self.kind == "vec":
            return f"vec{self.size}" + ("" if self.dim == SCALAR else f" {self.dim}")
        if self.kind == "rot":
            return "rotation"
        if self.kind == "choice":
            return "choice{" + ", ".join(f'"{c}"' for c in self.choices) + "}"
        return self.kind


def num(dim: Dim = SCALAR) -> Type:
    return Type("num", dim)


def vec(size: int, dim: Dim = SCALAR) -> Type:
    return Type("vec", dim, size)


BOOL = Type("bool")
ROT = Type("rot")
POSE = Type("pose")
STRING = Type("string")
SHAPE = Type("shape")
PART = Type("part")  # ``left.handle`` in ``left.handle.length``: a path to a nested part
INT = Type("num", SCALAR, 1, (), True)

UNIT_DIMS = {"scalar": SCALAR, "length": LENGTH, "angle": ANGLE}
SCALAR_TYPES = {
    "scalar": num(),
    "length": num(LENGTH),
    "angle": num(ANGLE),
    "int": INT,
    "bool": BOOL,
}
VECTOR_TYPES = {"vec2": 2, "vec3": 3}
# Literal units: how one of them converts to SI, as an exact fraction and a multiple of pi.
UNIT_FACTORS: dict[str, tuple[Dim, int, int, bool]] = {
    "mm": (LENGTH, 1, 1000, False),
    "cm": (LENGTH, 1, 100, False),
    "m": (LENGTH, 1, 1, False),
    "deg": (ANGLE, 1, 180, True),  # times pi
    "rad": (ANGLE, 1, 1, False),
}


def format_si(value: Any, dim: object) -> str:
    """An SI value (or vector) as people read it: mm for lengths, degrees for angles.

    ``dim`` is a ``Dim`` or its name ("length", "angle", ...), so the checker, the runtime's
    errors and the command line all print values the same way."""
    name = str(dim)
    parts = []
    for v in np.atleast_1d(np.asarray(value, dtype=float)):
        if name == "length":
            parts.append(f"{v * 1000:g}mm")
        elif name == "angle":
            parts.append(f"{np.degrees(v):g}deg")
        else:
            parts.append(f"{v:g}")
    return parts[0] if len(parts) == 1 else "(" + ", ".join(parts) + ")"


def param_type(name: str, unit: str | None) -> Type | None:
    """The type a ``param`` declaration names, or None when the name is unknown."""
    if name in SCALAR_TYPES and unit is None:
        return SCALAR_TYPES[name]
    if name in VECTOR_TYPES and (unit is None or unit in UNIT_DIMS):
        return vec(VECTOR_TYPES[name], UNIT_DIMS[unit or "scalar"])
    return None


TYPE_NAMES = [*SCALAR_TYPES, *VECTOR_TYPES, "choice"]
