"""The prompt catalog: complete, faithful to the sources and the runtime, round-trips as JSON."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import sympy as sp

import grace_dsl as eac
from grace_dsl.agent.catalog import (
    SCHEMA,
    _matrix_rows,
    _readable,
    build_catalog,
    render_json,
    render_markdown,
)
from grace_dsl.compiler.functions import sympy_model
from grace_dsl.compiler.lower import symbol_names
from grace_dsl.compiler.manifest import GRASP_POINT, force_vector

ROOT = Path(__file__).resolve().parent.parent.parent
DOC = ROOT / "docs" / "prompt_catalog.md"


@pytest.fixture(scope="module")
def catalog(lib: eac.Library) -> dict[str, Any]:
    return build_catalog(lib)


@pytest.fixture(scope="module")
def markdown(catalog: dict[str, Any]) -> str:
    return render_markdown(catalog)


def concepts(catalog: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {c["name"]: c for cat in catalog["categories"] for c in cat["concepts"]}


def section(markdown: str, name: str) -> str:
    """The markdown of one concept: from its heading to the next heading."""
    m = re.search(rf"^### {name}\b.*?(?=^##)", markdown + "\n##", re.MULTILINE | re.DOTALL)
    assert m, f"no section for {name}"
    return m.group(0)


def test_every_concept_appears_once_in_its_file_category(
    lib: eac.Library, catalog: dict[str, Any], markdown: str
) -> None:
    assert catalog["schema"] == SCHEMA
    found = concepts(catalog)
    assert sorted(found) == sorted(lib)
    assert sum(len(cat["concepts"]) for cat in catalog["categories"]) == len(lib)
    for cat in catalog["categories"]:
        assert cat["file"] == f"{cat['name']}.eac"
        assert all(c["file"] == cat["file"] for c in cat["concepts"])
    for name in lib:
        assert len(re.findall(rf"^### {name}\b", markdown, re.MULTILINE)) == 1, name
        synopsis = " ".join(lib[name].doc.split()).split(". ")[0].rstrip(".")
        assert f"`{name}`: {synopsis}" in markdown  # the synopsis list a model reads first


def test_every_grasp_and_action_appears_with_its_formula(
    lib: eac.Library, catalog: dict[str, Any], markdown: str
) -> None:
    found = concepts(catalog)
    for name in lib:
        c, entry, text = lib[name], found[name], section(markdown, name)
        assert [g["name"] for g in entry["grasps"]] == list(c.grasps)
        assert [a["name"] for a in entry["actions"]] == list(c.actions)
        for g in entry["grasps"]:
            assert g["pose"]["source"] and g["pose"]["text"].startswith("[[")
            assert f"`G = {g['pose']['source']}`" in text, (name, g["name"])
            assert len(g["free"]) == len(c.grasps[g["name"]]["free"])
        for a in entry["actions"]:
            assert a["force"]["text"] and a["force"]["latex"]
            shown = re.search(
                rf"^- `{re.escape(a['name'])}`:.*\n  - force.*`F = (.*)`$", text, re.M
            )
            assert shown, (name, a["name"])
            assert shown.group(1) in (a["force"]["text"], a["force"]["rest_text"])


def test_json_round_trips(catalog: dict[str, Any]) -> None:
    assert json.loads(render_json(catalog)) == catalog


def test_curve_handle_as_the_paper_states_it(markdown: str, catalog: dict[str, Any]) -> None:
    text = section(markdown, "CurveHandle")
    assert "| `r_out` | length | [7mm, 220mm] | 48mm | outer radius of the bar |" in text
    assert "| `radian` | angle | [20deg, 180deg] | 120deg |" in text
    assert "`G = rotz(theta) * trans(0, -r_out, 0) * rpy(90deg, 0, 90deg) * roty(90deg)`" in text
    # the paper's position of the pull grasp: (R_o sin(theta), -R_o cos(theta), 0)
    assert "translation: `[r_out*sin(theta), -r_out*cos(theta), 0]`" in text
    pull = concepts(catalog)["CurveHandle"]["grasps"][0]
    (theta,) = pull["free"]
    assert theta["at_defaults"] == pytest.approx([-np.radians(60), np.radians(60)])
    assert theta["at_defaults_text"] == "[-60deg, 60deg]"
    assert pull["width"]["text"] == "12mm" and pull["width"]["expression"] == "height"


def test_part_grasps_show_the_part_formula_and_placement(
    markdown: str, catalog: dict[str, Any]
) -> None:
    door = concepts(catalog)["SunkenDoor"]
    pull = next(g for g in door["grasps"] if g["name"] == "handle.pull")
    assert pull["part"] == "handle" and pull["part_concept"] == "CurveHandle"
    assert pull["pose"]["source"].startswith("rotz(theta) * trans(0, -r_out, 0)")
    assert pull["pose"]["placement"]
    text = section(markdown, "SunkenDoor")
    assert "- `handle.pull` (part `handle` (CurveHandle), link `leaf`; by pinch)" in text
    assert "pose in the part's frame: `G = rotz(theta)" in text


def test_joints_show_axes_and_ranges(catalog: dict[str, Any], markdown: str) -> None:
    cabinet = concepts(catalog)["HingedCabinet"]
    (hinge,) = cabinet["joints"]
    assert hinge["axis"] == "(0, -side, 0)" and hinge["axis_value"] == [0.0, -1.0, 0.0]
    assert hinge["range"] == "[0, 110deg]" and hinge["limits"] == pytest.approx([0, 1.919862])
    text = section(markdown, "HingedCabinet")
    assert "axis `(0, -side, 0)` = (0, -1, 0) at the defaults" in text
    drawer = section(markdown, "CabinetDrawer")
    assert (
        "- `slide`: prismatic, `base` → `drawer`, axis `(0, 0, 1)`, range `[0, travel]`" in drawer
    )


def test_choices_are_spelled_out(markdown: str) -> None:
    text = section(markdown, "HingedCabinet")
    assert '(1 if hinge_side == "left" else -1)' in text
    assert "Piecewise" not in text and "Eq(" not in text


def test_readable_rewrites_only_what_it_understands(lib: eac.Library) -> None:
    params = {p.name: p for p in lib["HingedCabinet"].params}
    pw = "Piecewise((1, Eq(hinge_side, 0)), (-1, True))"
    assert _readable(f"x*{pw} + {pw}", params) == (
        'x*(1 if hinge_side == "left" else -1) + (1 if hinge_side == "left" else -1)'
    )
    nested = "Piecewise((a, Eq(hinge_side, 1)), (Piecewise((b, c > 0), (d, True)), True))"
    assert _readable(nested, params) == '(a if hinge_side == "right" else (b if c > 0 else d))'
    odd = "Piecewise((a, c > 0), (b, d > 0))"  # no final True branch: left as SymPy wrote it
    assert _readable(odd, params) == odd
    assert _readable("Eq(other, 2)", params) == "other == 2"


@pytest.mark.parametrize("name", ["CurveHandle", "LeverHandle", "RockerSwitch"])
def test_translation_and_rotation_are_the_sympy_entries(
    stdlib_front_end: Any, lib: eac.Library, catalog: dict[str, Any], name: str
) -> None:
    _, checked = stdlib_front_end
    exact = sympy_model(checked, name)
    params = {p.name: p for p in lib[name].params}
    for g in concepts(catalog)[name]["grasps"]:
        pose = sp.Matrix(exact.grasps[g["name"]].pose)
        rows = _matrix_rows(g["pose"]["text"])
        assert rows is not None
        for i, j in ((0, 3), (2, 1), (1, 0)):
            assert rows[i][j] == _readable(sp.sstr(pose[i, j]), params)
        want = _readable(sp.sstr([pose[i, 3] for i in range(3)]), params)
        assert g["pose"]["translation"] == want


def _values(inst: Any, exact: Any, point: np.ndarray) -> dict[Any, float]:
    """Numbers for every symbol of the SymPy model: parameters, joint values, the grasp point."""
    values: dict[str, float] = {}
    for info in exact.params:
        spec = next(s for s in inst.concept.params if s.name == info.name)
        entries = inst.p[spec.offset : spec.offset + spec.size]
        values.update(zip(symbol_names(info), (float(x) for x in entries)))
    values.update({f"q_{j}": float(q) for j, q in zip(inst.concept.moving_joints, inst.q)})
    values.update({s.name: float(x) for s, x in zip(GRASP_POINT, point)})
    return {s: values[s.name] for s in exact.p + exact.q + list(GRASP_POINT)}


@pytest.mark.parametrize(
    "name, joints",
    [
        ("HingedCabinet", {"hinge": 0.6}),
        ("Safe", {"hinge": 0.3, "dial.spin": 1.1, "handle.turn": 0.2}),
        ("ChestOfDrawers", {"slide2": 0.1}),
        ("RockerSwitch", {}),
    ],
)
def test_force_formulas_agree_with_the_runtime(
    stdlib_front_end: Any, lib: eac.Library, name: str, joints: dict[str, float]
) -> None:
    """SymPy's force formula of every action, evaluated at random grasp points, is the direction
    the runtime (CasADi, native) computes."""
    _, checked = stdlib_front_end
    exact = sympy_model(checked, name)
    rng = np.random.default_rng(0)
    pose = np.eye(4)
    pose[:3, 3] = (0.3, -0.2, 1.0)
    inst = lib[name].instantiate(pose=pose, joints=joints)
    for action in lib[name].actions:
        v, normalize = force_vector(exact, action)
        for _ in range(3):
            point = rng.uniform(-0.3, 0.3, 3)
            subs = _values(inst, exact, point)
            f = np.array([float(sp.sympify(c).subs(subs)) for c in v])
            if normalize:
                f /= np.linalg.norm(f)
            grasp = np.eye(4)
            grasp[:3, 3] = point + pose[:3, 3]
            np.testing.assert_allclose(inst.force(action, grasp=grasp), f, atol=1e-9)


def test_one_concept_and_an_unknown_one(lib: eac.Library) -> None:
    one = build_catalog(lib, ["Safe", "CurveHandle", "Safe"])
    assert [c["name"] for cat in one["categories"] for c in cat["concepts"]] == [
        "Safe",
        "CurveHandle",
    ]
    with pytest.raises(eac.UnknownNameError, match="did you mean 'CurveHandle'"):
        build_catalog(lib, ["CurveHandel"])


def test_an_artifact_without_sources_still_has_formulas(lib: eac.Library, tmp_path: Path) -> None:
    from grace_dsl.compiler.build import export_library

    assert lib.result is not None
    assert export_library(lib.result, tmp_path / "art") == []
    art = eac.load_artifact(tmp_path / "art")
    entry = concepts(build_catalog(art, ["CurveHandle"]))["CurveHandle"]
    pull = next(g for g in entry["grasps"] if g["name"] == "pull")
    assert pull["pose"]["source"].startswith("rotz(theta)")
    assert pull["free"][0]["range"] is None and pull["free"][0]["at_defaults_text"]
    assert "`G = rotz(theta)" in render_markdown(build_catalog(art, ["CurveHandle"]))


def test_docs_prompt_catalog_is_up_to_date(markdown: str) -> None:
    assert DOC.read_text("utf-8") == markdown, (
        "docs/prompt_catalog.md is stale: run `eacc prompt -o docs/prompt_catalog.md`"
    )
