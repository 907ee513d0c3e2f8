"""Bad names and values fail early with a GeometryError (a ValueError) that says what to fix."""

from __future__ import annotations

import math
import re
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import grace_dsl
from grace_dsl.geometry import (
    PRIMITIVES,
    GeometryError,
    default_params,
    primitive_mesh,
    primitive_sdf,
    primitive_sdf_casadi,
    sample_surface,
    validate,
    volume,
)

EAC = Path(grace_dsl.__file__).parent / "concepts" / "primitives.eac"


def test_registry_matches_primitives_eac() -> None:
    text = EAC.read_text()
    declared = {
        m.group(1): re.findall(r"param (\w+)", m.group(2))
        for m in re.finditer(r"primitive (\w+) \{(.*?)\n\}", text, re.S)
    }
    assert {k: list(v.param_names) for k, v in PRIMITIVES.items()} == declared


@pytest.mark.parametrize(
    ("name", "params", "message"),
    [
        ("Cube", {}, "unknown primitive 'Cube'; known primitives: Cuboid"),
        ("Sphere", {"r": 1.0}, "Sphere has no parameter 'r'; its parameters are: radius"),
        ("Cuboid", {"size": (1.0, 2.0)}, "Cuboid.size must be 3 numbers"),
        ("Sphere", {"radius": (1.0, 2.0)}, "Sphere.radius must be a number"),
        ("Sphere", {"radius": "big"}, "Sphere.radius must be a number"),
        ("Sphere", {"radius": float("nan")}, "Sphere.radius must be finite"),
        ("Sphere", {"radius": -0.1}, "Sphere.radius must be > 0"),
        ("Cylinder", {"radian": 7.0}, "at most 2*pi"),
        ("Tube", {"r_in": 0.03, "r_out": 0.02}, "r_out > r_in"),
        ("RectRing", {"inner": (0.5, 0.1)}, "inner.x < outer.x"),
        ("Frustum", {"r_bottom": 0.0, "r_top": 0.0}, "one end needs a radius"),
        ("Frustum", {"r_top": -1.0}, "Frustum.r_top must be >= 0"),
        ("TaperedCuboid", {"top": (-0.01, 0.02)}, "TaperedCuboid.top must be >= 0"),
        ("TaperedCuboid", {"offset": (0.0, float("inf"))}, "TaperedCuboid.offset must be finite"),
        ("SphericalCap", {"height": 0.05}, "height <= 2 * radius"),
        ("Torus", {"r_minor": 0.04}, "r_minor < r_major"),
        ("Torus", {"radian": 0.0}, "Torus.radian must be > 0"),
        ("Prism", {"sides": 2.5}, "Prism.sides must be a whole number"),
        ("Prism", {"sides": True}, "Prism.sides must be a whole number"),
        ("Prism", {"sides": 2}, "sides >= 3"),
    ],
)
def test_bad_parameters_are_reported(name: str, params: dict[str, object], message: str) -> None:
    with pytest.raises(GeometryError, match=re.escape(message)):
        validate(name, params)
    with pytest.raises(ValueError):
        volume(name, params)


def test_missing_parameters_take_the_eac_defaults() -> None:
    assert validate("Ring", {"radian": math.pi}) == {**default_params("Ring"), "radian": math.pi}
    assert math.isclose(default_params("Ring")["radian"], math.radians(120))  # type: ignore[arg-type]


def test_shifts_may_be_negative_and_whole_floats_are_ints() -> None:
    """The runtime passes every argument as a float: 6.0 sides is the int 6."""
    got = validate("TaperedCuboid", {"offset": (-0.02, 0.01)})
    assert got["offset"] == (-0.02, 0.01)
    sides = validate("Prism", {"sides": 6.0})["sides"]
    assert sides == 6 and isinstance(sides, int)


def test_bad_points_and_counts() -> None:
    with pytest.raises(GeometryError, match=r"shape \(N, 3\)"):
        primitive_sdf("Sphere", {}, np.zeros((4, 2)))
    with pytest.raises(GeometryError, match="finite"):
        primitive_sdf("Sphere", {}, [[np.nan, 0, 0]])
    with pytest.raises(GeometryError, match="non-negative integer"):
        sample_surface("Sphere", {}, -1, seed=0)
    with pytest.raises(GeometryError, match="resolution"):
        primitive_mesh("Sphere", {}, resolution=2)
    with pytest.raises(GeometryError, match="no parameter"):
        primitive_sdf_casadi("Sphere", {"radius": ca.SX.sym("r"), "x": 1.0}, ca.SX.sym("p", 3))


def test_single_point_and_numeric_casadi() -> None:
    assert primitive_sdf("Sphere", {"radius": 1.0}, [2.0, 0.0, 0.0]).tolist() == [1.0]
    expr = primitive_sdf_casadi("Sphere", {"radius": 1.0}, ca.DM([0.0, 3.0, 0.0]))
    assert float(expr) == 2.0
