"""Type and unit rules of the check pass, and the values it verifies at the defaults."""

from __future__ import annotations

from pathlib import Path

import pytest

from grace_dsl.compiler.build import front_end
from tests.conftest import write


def codes(tmp_path: Path, body: str, header: str = "use primitives.{Cuboid, Ring}\n") -> list[str]:
    path = write(tmp_path, "t.eac", header + "concept T {\n" + body + "\n}\n")
    _, _, diags = front_end([path])
    return [d.code for d in diags]


@pytest.mark.parametrize(
    "body",
    [
        "param r : length = 2mm  param a : angle = 30deg  let arc = r * a  require arc > 0mm",
        "param r : length = 2mm  let area = r * r  let back = sqrt(area)  require back == r",
        "param v : vec3 length = (1mm, 0, 0)  let n = norm(v)  let u = normalize(v)  "
        "let d = dot(v, v)  let c = cross(v, v)",
        "let p = rotz(30deg) * trans(0, 1mm, 0) * rpy(0, 0, pi / 2)  let q = inv(p) * p",
        "param a : angle = 10deg  let s = sin(a) + cos(0.5rad) + tan(a)  let b = atan2(1mm, 2mm)",
        'param side : choice{"l", "r"} = "r"  let k = if side == "l" then 1mm else 0',
        "param n : int in [1, 5] = 3  param f : bool = true  let m = if f and n > 2 then n else 0",
        "let x = (0, 0, 0)  let y = trans(x * 1mm)",
    ],
)
def test_valid_bodies(tmp_path: Path, body: str) -> None:
    assert codes(tmp_path, body) == []


@pytest.mark.parametrize(
    "body, expected",
    [
        ("param r : length = 2mm  let x = r + 30deg", "E203"),
        ("param r : length = 2mm  let x = r + 3", "E204"),
        ("param a : angle = 2deg  let x = a > 1", "E204"),
        ("let x = trans(0, 1, 0)", "E204"),
        ("let x = sqrt(3mm)", "E228"),
        ("let x = (1mm, 2mm) + (1mm, 2mm, 3mm)", "E213"),
        ("let x = if 1 then 2 else 3", "E214"),
        ("let x = if true then 2mm else (1mm, 2mm)", "E215"),
        ('param s : choice{"l", "r"} = "l"  let x = s == "m"', "E216"),
        ('let x = "text"', "E227"),
        ("let a = b  let b = a", "E119"),
        ("let x = rotz(1mm)", "E206"),
        ("let x = atan2(1mm)", "E205"),
        ("let x = cos", "E106"),
        ("let x = frobnicate(1)", "E115"),
        ("param v : vec2 length = (1mm, 1mm)  let x = v.z", "E212"),
        ("param n : int = 2.5", "E226"),
        ("shape s = Ring(r_in: 1mm, r_in: 1mm)", "E118"),
        ("shape s = Ring(radius: 1mm)", "E116"),
        ("shape s = Ring(1mm)", "E117"),
    ],
)
def test_errors(tmp_path: Path, body: str, expected: str) -> None:
    assert expected in codes(tmp_path, body)


def test_bare_zero_adapts_but_not_a_bare_one(tmp_path: Path) -> None:
    assert codes(tmp_path, "param r : length = 2mm  require r > 0") == []
    assert codes(tmp_path, "param r : length = 2mm  require r > 0 * 5") == []
    assert codes(tmp_path, "param r : length = 2mm  require r > 1") == ["E204"]


def test_values_at_defaults(tmp_path: Path) -> None:
    assert codes(tmp_path, "param r : length in [1mm, 2mm] = 3mm") == ["E209"]
    assert codes(tmp_path, "param r : length in [3mm, 2mm]") == ["E208"]
    assert codes(tmp_path, 'param r : length = 2mm  require r > 3mm "too small"') == ["E210"]
    assert codes(tmp_path, "param r : length = 2mm  grasp g(t in [r, 0mm]) = trans(t, 0, 0)") == [
        "E211"
    ]
    assert codes(tmp_path, "param r : length = 0mm  let k = 1 / (r / 1mm)") == ["E225"]


def test_part_parameters_are_readable_and_typed(tmp_path: Path) -> None:
    header = "use primitives.{Cuboid}\nuse handles.{CurveHandle}\n"
    ok = "part h = CurveHandle(r_in: 30mm)  let reach = h.r_out + h.r_in"
    assert codes(tmp_path, ok, header) == []
    assert "E212" in codes(tmp_path, "part h = CurveHandle()  let x = h.radius", header)
    assert "E203" in codes(tmp_path, "part h = CurveHandle(r_in: 30deg)", header)


def test_joint_rules(tmp_path: Path) -> None:
    link = "link l { shape s = Cuboid() }\n"
    assert codes(tmp_path, link + "joint j : revolute(base -> l) range [0, 1deg]") == ["E217"]
    assert codes(
        tmp_path, link + "joint j : revolute(base -> l) axis (0, 1, 0) range [0, 1mm]"
    ) == ["E229"]
    assert codes(
        tmp_path, link + "joint j : continuous(base -> l) axis (0, 0, 1) range [0, 1deg]"
    ) == ["E219"]
    assert codes(tmp_path, link + "joint j : hinge(base -> l)") == ["E218"]
    assert codes(
        tmp_path, link + "joint j : prismatic(base -> l) axis (0, 0, 0) range [0, 1mm]"
    ) == ["E221"]
    assert codes(tmp_path, link + "joint j : fixed(base -> l)  action a = pull along j") == ["E219"]


def test_part_and_primitive_arguments_are_checked_at_the_defaults(tmp_path: Path) -> None:
    header = "use primitives.{Sphere}\nuse handles.{CurveHandle}\n"
    assert codes(tmp_path, "part h = CurveHandle(r_in: 1m)", header) == ["E209", "E210"]
    assert codes(tmp_path, "part h = CurveHandle(r_in: 48mm)", header) == ["E210"]
    assert codes(tmp_path, "shape s = Sphere(radius: 5m)", header) == ["E209"]
    assert codes(tmp_path, "part h = Sphere(radius: 1mm)", header) == ["E114"]


def test_part_arguments_may_read_part_parameters(tmp_path: Path) -> None:
    header = "use handles.{CurveHandle}\n"
    ok = (
        "let extra = 8mm  part h = CurveHandle(r_out: h.r_in + extra)\n"
        "part k = CurveHandle(r_in: h.r_in, r_out: h.r_out)  let reach = k.r_out"
    )
    assert codes(tmp_path, ok, header) == []
    assert codes(tmp_path, "part h = CurveHandle(r_out: h.r_out)", header) == ["E119"]


def test_more_values_at_the_defaults(tmp_path: Path) -> None:
    link = "link l {}\n"
    assert codes(
        tmp_path, link + "joint k : revolute(base -> l) axis (0, 1, 0) range [10deg, 90deg]"
    ) == ["E209"]
    assert codes(
        tmp_path, link + "joint k : revolute(base -> l) axis (0, 1, 0) range [90deg, 0deg]"
    ) == ["E208"]
    assert codes(tmp_path, "grasp g(s in [0mm, 10mm] = 20mm) = trans(s, 0, 0)") == ["E209"]
    assert codes(tmp_path, "action p = press toward (0, 0, 0)") == ["E221"]
    assert codes(tmp_path, link + "joint j : fixed(base -> l) at (1mm, 0, 0)") == ["E219"]
    assert codes(tmp_path, "param b : bool") == ["E222"]
    assert codes(tmp_path, "param if : scalar = 1") == ["E002"]  # a keyword is never a name
    assert codes(tmp_path, "let v = (inv(trans(1mm, 0, 0)) * (0, 0, 0)).z + 3mm") == []


def test_part_choices_bound_to_options(tmp_path: Path) -> None:
    header = "use handles.{LeverHandle}\n"
    assert codes(tmp_path, 'part h = LeverHandle(hand: "right")', header) == []
    computed = (
        'param s : choice{"l", "r"} = "l"  part h = LeverHandle(hand: if s == "l" '
        'then "left" else "right")'
    )
    assert codes(tmp_path, computed, header) == ["E227"]


def test_a_bare_number_as_an_angle_warns(tmp_path: Path) -> None:
    """Regression: `rotx(90)` was silently 90 radians."""
    path = write(
        tmp_path,
        "t.eac",
        "concept T {\n    param k : scalar in [0, 1] = 0.5\n"
        "    let a = rotx(90)\n    let b = rpy(0, 0, 1.5)\n    let c = sin(2)\n"
        "    let fine = rotx(90deg) * roty(0) * rotz(k) * rotx(pi / 2)\n}\n",
    )
    _, checked, diags = front_end([path])
    assert [(d.code, d.severity, d.span.line) for d in diags] == [
        ("E237", "warning", 3),
        ("E237", "warning", 4),
        ("E237", "warning", 5),
    ]
    assert "5156.62 degrees" in diags[0].message and "`90deg`" in (diags[0].hint or "")
    assert checked.concepts["T"].ok  # a warning does not fail the concept
