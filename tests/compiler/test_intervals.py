"""The interval pass: sound intervals (a hypothesis property), and warnings only with witnesses."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from grace_dsl.compiler.backends import NUMPY
from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.interval_backend import INTERVALS, Interval
from grace_dsl.compiler.resolve import stdlib_dir
from grace_dsl.compiler.values import evaluator_at
from grace_dsl.lang import ast
from tests.conftest import write

# ---- soundness: the interval of every sub-expression holds its sampled values ------------------

LEAVES = st.sampled_from(["x", "y", "0.5", "2", "-1.5", "pi"])
UNARY = ["sqrt", "sin", "cos", "tan", "abs", "atan"]


def _combine(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    binary = st.tuples(st.sampled_from(["+", "-", "*", "/"]), children, children).map(
        lambda t: f"({t[1]} {t[0]} {t[2]})"
    )
    power = st.tuples(children, st.sampled_from(["2", "3", "-1", "0.5", "y"])).map(
        lambda t: f"({t[0]} ^ {t[1]})"
    )
    call1 = st.tuples(st.sampled_from(UNARY), children).map(
        lambda t: f"atan2({t[1]}, 1.5)" if t[0] == "atan" else f"{t[0]}({t[1]})"
    )
    call2 = st.tuples(st.sampled_from(["min", "max", "atan2"]), children, children).map(
        lambda t: f"{t[0]}({t[1]}, {t[2]})"
    )
    clamp = st.tuples(children, children).map(lambda t: f"clamp({t[0]}, -1, {t[1]})")
    branch = st.tuples(st.sampled_from(["<", ">="]), children, children, children).map(
        lambda t: f"(if {t[1]} {t[0]} 0.3 then {t[2]} else {t[3]})"
    )
    return st.one_of(binary, power, call1, call2, clamp, branch)


EXPRS = st.recursive(LEAVES, _combine, max_leaves=6)
RANGES = st.tuples(st.floats(-3, 3, allow_nan=False), st.floats(0, 4, allow_nan=False)).map(
    lambda t: (round(t[0], 3), round(t[0] + t[1], 3))
)


def _values(concept: Any, checked: Any, backend: Any, env: dict[str, Any]) -> dict[int, Any]:
    seen: dict[int, Any] = {}
    ev = evaluator_at(
        concept.decl,
        env,
        checked.concepts,
        checked.types,
        backend,
        lambda e, v: seen.__setitem__(id(e), v),
    )
    assert ev is not None
    ev.lookup("e")
    return seen


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(expr=EXPRS, rx=RANGES, ry=RANGES)
@example(expr="(sqrt(pi) * (x + pi))", rx=(0.0, 1.0), ry=(0.0, 1.0))  # rejected: not evaluated
def test_intervals_hold_the_sampled_values(
    expr: str, rx: tuple[float, float], ry: tuple[float, float]
) -> None:
    text = (
        f"concept P {{\n    param x : scalar in [{rx[0]}, {rx[1]}] = {rx[0]}\n"
        f"    param y : scalar in [{ry[0]}, {ry[1]}] = {ry[0]}\n    let e = {expr}\n}}\n"
    )
    with tempfile.TemporaryDirectory() as tmp:
        _, checked, diags = front_end([write(Path(tmp), "p.eac", text)])
    # a program the checker rejects (``sqrt(pi)``: a root of an angle, E203) is not evaluated
    assume(not any(d.severity == "error" for d in diags))
    concept = checked.concepts["P"]
    boxes = _values(concept, checked, INTERVALS, {"x": Interval(*rx), "y": Interval(*ry)})
    rng = np.random.default_rng(0)
    xs = np.concatenate([[rx[0], rx[1]], rng.uniform(*rx, 64)])
    ys = np.concatenate([[ry[0], ry[1]], rng.uniform(*ry, 64)])
    with np.errstate(all="ignore"):
        points = _values(concept, checked, NUMPY, {"x": xs, "y": ys})
    # Intervals bound the values where the program is defined: a point at which any
    # sub-expression is undefined (sqrt below 0, 0/0: the E233-E235 warnings) is left out, since
    # NumPy carries on with NaN there (``sqrt(-1.5) < 0.3`` is false) while intervals clip.
    defined = np.ones(xs.shape, dtype=bool)
    for value in points.values():
        with np.errstate(all="ignore"):
            arr = np.asarray(value, dtype=float) if not isinstance(value, tuple) else None
        if arr is not None and arr.dtype.kind == "f":
            defined &= np.broadcast_to(np.isfinite(arr), xs.shape)
    for key, box in boxes.items():
        if not isinstance(box, Interval) or key not in points:
            continue
        v = np.broadcast_to(np.asarray(points[key], dtype=float), xs.shape)[defined]
        tol = 1e-9 * (1 + np.abs(v))
        assert np.all(v >= box.lo - tol) and np.all(v <= box.hi + tol), (expr, box, v)


def test_interval_arithmetic_by_hand() -> None:
    x = Interval(-1.0, 2.0)
    assert x * x == Interval(0.0, 4.0)  # a square, not [-2, 4]
    assert x * Interval(-1.0, 2.0) == Interval(-2.0, 4.0)
    assert (Interval(1.0, 2.0) / x) == Interval(-math.inf, math.inf)
    assert INTERVALS.sin(Interval(0.0, math.pi)) == Interval(0.0, 1.0)
    assert INTERVALS.cos(Interval(0.1, 0.2)).hi == pytest.approx(math.cos(0.1))
    assert INTERVALS.pow(Interval(10.0, 10.0), Interval(0.0, 400.0)).hi == math.inf
    assert INTERVALS.pow(Interval(-2.0, 3.0), Interval(2.0, 2.0)) == Interval(0.0, 9.0)
    assert INTERVALS.tan(Interval(1.0, 2.0)) == Interval(-math.inf, math.inf)  # over pi/2
    assert Interval(math.nan, 1.0) == Interval(-math.inf, math.inf)


# ---- warnings -----------------------------------------------------------------------------------


def diags(tmp_path: Path, body: str, header: str = "use primitives.{RectRing}\n") -> list[Any]:
    path = write(tmp_path, "t.eac", header + "concept T {\n" + body + "\n}\n")
    return front_end([path])[2]


def test_the_issue_examples_warn_at_the_sub_expression(tmp_path: Path) -> None:
    found = diags(
        tmp_path,
        "param r : length in [0mm, 10mm] = 5mm\n"
        "param x : scalar in [-1, 1] = 0.5\n"
        "param n : scalar in [0, 400] = 2\n"
        "let a = 1mm * 1mm / r\n"
        "let s = sqrt(x)\n"
        "let big = 10 ^ n\n"
        "grasp g = trans(0mm, 0mm, a) width 10mm\n",
    )
    assert [(d.code, d.severity, d.span.line) for d in found] == [
        ("E233", "warning", 6),
        ("E234", "warning", 7),
        ("E235", "warning", 8),
    ]
    assert "r = 0mm" in found[0].hint and "x = -1" in found[1].hint
    assert "n = 400" in found[2].hint
    assert found[0].span.col == 9  # `1mm * 1mm / r`, not the whole let


@pytest.mark.parametrize(
    "body",
    [
        # guarded by an `if` that excludes the zero
        "param r : length in [0mm, 10mm] = 5mm\nlet a = if r > 0mm then 1mm * 1mm / r else 0mm",
        # excluded by a requirement
        "param r : length in [0mm, 10mm] = 5mm  require r > 1mm\nlet a = 1mm * 1mm / r",
        # x - x is 0 but its interval is not: no witness, no warning
        "param x : scalar in [-1, 1] = 0.5\nlet s = sqrt(x - x)",
        "param x : scalar in [-1, 1] = 0.5\nlet s = sqrt(x * x + 1)",
        # the divisor's interval holds 0 but no value reaches it
        "param x : scalar in [-1, 1] = 0.5\nlet d = 1 / (x * x + 0.5)",
        # a frame that a requirement keeps open
        "param size : vec2 length in [(100mm, 100mm), (1m, 1m)] = (400mm, 600mm)\n"
        "param rim : length in [10mm, 80mm] = 30mm\n"
        "require 2 * rim + 1mm < size.x and 2 * rim + 1mm < size.y\n"
        "shape f = RectRing(outer: size, inner: (size.x - 2 * rim, size.y - 2 * rim), "
        "depth: 20mm)",
    ],
)
def test_no_warning_without_a_witness(tmp_path: Path, body: str) -> None:
    assert diags(tmp_path, body) == []


def test_an_argument_leaving_its_primitives_range(tmp_path: Path) -> None:
    found = diags(
        tmp_path,
        "param size : vec2 length in [(100mm, 100mm), (1m, 1m)] = (400mm, 600mm)\n"
        "param rim : length in [10mm, 80mm] = 30mm\n"
        "shape f = RectRing(outer: size, inner: (size.x - 2 * rim, size.y - 2 * rim), "
        "depth: 20mm)",
    )
    assert [(d.code, d.severity) for d in found] == [("E236", "warning")]
    assert "`inner` of RectRing" in found[0].message and "rim = 80mm" in found[0].hint


def test_a_part_argument_leaving_the_parts_range(tmp_path: Path) -> None:
    found = diags(
        tmp_path,
        "param w : length in [10mm, 100mm] = 50mm\npart k = K(r: w / 2)",
        header="concept K { param r : length in [10mm, 40mm] = 20mm }\n",
    )
    assert [d.code for d in found] == ["E236"]


def test_a_nested_part_argument_leaving_the_nested_range(tmp_path: Path) -> None:
    """``D(k.r: ...)`` binds ``r`` of D's part ``k``: it is judged against K's range."""
    header = (
        "concept K { param r : length in [10mm, 40mm] = 20mm }\n"
        "concept D {\nparam s : length in [1mm, 2mm] = 1mm\npart k = K()\n}\n"
    )
    found = diags(
        tmp_path, "param w : length in [10mm, 100mm] = 50mm\npart d = D(k.r: w / 2)", header
    )
    assert [d.code for d in found] == ["E236"]
    assert "`k.r` of D" in found[0].message and "[10mm, 40mm]" in found[0].message
    assert "it is 5mm at w = 10mm" in (found[0].hint or "")
    safe = diags(
        tmp_path, "param w : length in [20mm, 80mm] = 50mm\npart d = D(k.r: w / 2)", header
    )
    assert safe == []


def test_a_non_finite_range_bound_or_default_is_an_error(tmp_path: Path) -> None:
    """Regression: a NaN bound disabled range checking (instantiate(r=-5.0) was accepted)."""
    found = diags(
        tmp_path,
        "param r : length in [0mm, sqrt(-1) * 1mm] = 1mm\n"
        "param s : length in [0mm, 1e300mm * 1e300] = 1mm\n"
        "param d : scalar = 0 / 0",
    )
    assert [(d.code, d.severity, d.span.line) for d in found] == [
        ("E225", "error", 3),
        ("E225", "error", 4),
        ("E225", "error", 5),
    ]


def test_the_standard_library_has_no_interval_warnings() -> None:
    _, _, found = front_end([stdlib_dir()])
    assert found == []


def test_every_node_kind_is_walked() -> None:
    """The pass walks the same children as the AST helpers (no sub-expression is skipped)."""
    e = ast.Binary(ast.Name("x"), "+", ast.Name("y"))
    assert len(ast._children(e)) == 2
