"""Affordance cues (``bar.principal_axis``): types, errors, and agreement with the geometry's own
affordance hints under a placement."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.compiler.build import front_end
from grace_dsl.geometry import affordances
from tests.conftest import write

HEADER = "use primitives\n"


def diagnostics(tmp_path: Path, body: str) -> list[tuple[str, str]]:
    path = write(tmp_path, "t.eac", HEADER + "concept T {\n" + body + "\n}\n")
    _, _, diags = front_end([path])
    return [(d.code, d.message) for d in diags]


@pytest.mark.parametrize(
    "body, code, words",
    [
        ("shape a = Cuboid(size: (10mm, 20mm, 30mm))  let w = a.width", "E212", "no cue `width`"),
        (
            "shape a = Cuboid()  shape b = Cuboid() at trans(0, 0, 9mm)\n"
            "shape u = union(a, b)  let k = u.principal_axis",
            "E212",
            "no cue `principal_axis`",
        ),
        ("shape a = Cuboid(size: (a.graspable_width, 1mm, 1mm))", "E119", "its own cues"),
        (
            "let w = a.graspable_width  shape a = Cuboid(size: (w, 1mm, 1mm))",
            "E119",
            "its own cues",
        ),
        ("shape a = Cuboid()  let x = a.graspable_width + 1deg", "E203", ""),
    ],
)
def test_cue_errors(tmp_path: Path, body: str, code: str, words: str) -> None:
    found = diagnostics(tmp_path, body)
    assert code in [c for c, _ in found], found
    assert any(words in m for c, m in found if c == code)


def test_cues_of_unions_and_their_types_check(tmp_path: Path) -> None:
    body = (
        "shape a = Cuboid()  shape b = Cuboid() at trans(0, 0, 90mm)  shape u = union(a, b)\n"
        "let c = u.center  let n = u.front_normal  let p = u.pose * trans(0, 0, 1mm)\n"
        "grasp g = trans(b.center) * trans(b.front_normal * 5mm) width b.graspable_width"
    )
    assert diagnostics(tmp_path, body) == []


# Primitive -> (arguments in .eac, the same in SI for grace_dsl.geometry)
CASES = {
    "Cuboid": ("size: (40mm, 120mm, 30mm)", {"size": (0.04, 0.12, 0.03)}),
    "Cylinder": ("radius: 15mm, height: 80mm", {"radius": 0.015, "height": 0.08}),
    "Tube": (
        "r_in: 10mm, r_out: 14mm, height: 60mm",
        {"r_in": 0.01, "r_out": 0.014, "height": 0.06},
    ),
    "Sphere": ("radius: 25mm", {"radius": 0.025}),
    "Capsule": ("radius: 8mm, length: 150mm", {"radius": 0.008, "length": 0.15}),
    "Ring": (
        "r_in: 40mm, r_out: 48mm, height: 12mm, radian: 120deg",
        {"r_in": 0.04, "r_out": 0.048, "height": 0.012, "radian": np.radians(120)},
    ),
    "Torus": (
        "r_major: 40mm, r_minor: 6mm, radian: 200deg",
        {"r_major": 0.04, "r_minor": 0.006, "radian": np.radians(200)},
    ),
    "SphericalCap": ("radius: 20mm, height: 8mm", {"radius": 0.02, "height": 0.008}),
    "TallCap": ("radius: 20mm, height: 30mm", {"radius": 0.02, "height": 0.03}),
    "RectRing": (
        "outer: (400mm, 600mm), inner: (360mm, 560mm), depth: 15mm",
        {"outer": (0.4, 0.6), "inner": (0.36, 0.56), "depth": 0.015},
    ),
}


PRIMITIVE = {"TallCap": "SphericalCap"}


@pytest.fixture(scope="module")
def cued(tmp_path_factory: pytest.TempPathFactory) -> eac.Library:
    """One concept per primitive, placed by a rotation and a translation given as parameters,
    with grasps that expose every cue: origin = center, axes = (principal_axis, front_normal)."""
    root = tmp_path_factory.mktemp("cues")
    text = HEADER
    for case, (args, _) in CASES.items():
        prim = PRIMITIVE.get(case, case)
        text += (
            f"concept {case}Cued {{\n"
            "    param r : vec3 in [(-4, -4, -4), (4, 4, 4)] = (0.3, 0.2, 0.1)\n"
            "    param t : vec3 length in [(-1m, -1m, -1m), (1m, 1m, 1m)] = (0, 0, 0)\n"
            f"    shape s = {prim}({args}) at trans(t) * rpy(r.x * 1rad, r.y * 1rad, r.z * 1rad)\n"
            "    grasp axis = trans(s.center + s.principal_axis * 1m)\n"
            "    grasp front = trans(s.center + s.front_normal * 1m) width s.graspable_width\n"
            "    grasp pose = s.pose\n"
            "}\n"
        )
    return eac.compile_paths([write(root, "cued.eac", text)])


@pytest.mark.parametrize("prim", sorted(CASES))
@settings(max_examples=15, deadline=None)
@given(
    r=st.tuples(*[st.floats(-3, 3)] * 3),
    t=st.tuples(*[st.floats(-0.5, 0.5)] * 3),
)
def test_cues_agree_with_geometry_affordances(
    cued: eac.Library, prim: str, r: tuple[float, ...], t: tuple[float, ...]
) -> None:
    inst = cued[f"{prim}Cued"].instantiate(r=r, t=t)
    pose = inst.grasp("pose")
    hint = affordances(PRIMITIVE.get(prim, prim), CASES[prim][1])
    rot, center = pose[:3, :3], pose[:3, 3]
    np.testing.assert_allclose(
        inst.grasp("axis")[:3, 3] - center, rot @ hint["principal_axis"], atol=1e-9
    )
    np.testing.assert_allclose(
        inst.grasp("front")[:3, 3] - center, rot @ hint["front_normal"], atol=1e-9
    )
    np.testing.assert_allclose(inst.grasp_width("front"), hint["graspable_width"], atol=1e-12)
    np.testing.assert_allclose(center, t, atol=1e-12)
