"""The variant pass (compiler/variants.py): reads of a variant part's parameters, pass-through
arguments, nested grasp families and options' own mountings, checked, lowered and run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.catalog import build_catalog
from grace_dsl.compiler.build import front_end
from grace_dsl.lang.diagnostics import has_errors

FRONT = """use primitives.{Cuboid}
use handles.{StraightHandle}
use knobs.{RoundKnob}

concept VFront {
    param kind : choice{"bar", "knob"} = "bar"
    param t : length in [12mm, 30mm] = 18mm
    require kind != "bar" or handle.standoff - handle.radius >= 19mm "a finger fits"
    let reach = if kind == "bar" then handle.length / 2 else handle.radius
    let bar_standoff = if kind == "bar" then handle["bar"].standoff else 0mm
    link panel {
        shape board = Cuboid(size: (400mm, 200mm, t)) at trans(0, 0, t / 2)
        part handle = match kind {
            "bar" => StraightHandle() at trans(0, 0, handle.standoff),
            "knob" => RoundKnob() at trans(0, 0, handle.stem + handle.depth / 2)
        } at trans(0, 0, t)
    }
    joint slide : prismatic(base -> panel) axis (0, 0, 1) range [0, 300mm]
    action open = pull along slide using handle.pull, handle.pinch
}

concept Host {
    param hk : choice{"bar", "knob"} = "bar"
    part f = VFront(kind: hk, handle.radius: 12mm, handle["bar"].length: 200mm)
    action open = pull along f.slide using f.handle.pull, f.handle.pinch
}
"""


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> eac.Library:
    path = tmp_path_factory.mktemp("variants") / "front.eac"
    path.write_text(FRONT, encoding="utf-8")
    return eac.compile_paths([str(path)])


def _diags(tmp_path: Path, text: str) -> list[Any]:
    path = tmp_path / "x.eac"
    path.write_text(text, encoding="utf-8")
    _, _, diags = front_end([path])
    return [d for d in diags if d.severity == "error"]


@pytest.mark.slow
def test_the_front_compiles_without_diagnostics(tmp_path: Path) -> None:
    assert not has_errors(_diags(tmp_path, FRONT))


@pytest.mark.parametrize(
    ("change", "code", "where"),
    [
        # an unguarded read of a parameter only the bar has
        ('let reach = if kind == "bar"', "let reach = if 1 == 1", ("E129", "handle.radius")),
        # the else of `kind == "bar"` rules the bar out: the knob's stem is readable there
        ("else handle.radius", "else handle.stem", None),
        # a pass-through no option takes
        ("handle.radius: 12mm", "handle.travel: 12mm", ("E116", "handle.travel")),
        # a nested action whose family leaves the knob without a grasp
        ("f.handle.pull, f.handle.pinch", "f.handle.pull", ("E127", "action open")),
    ],
)
def test_diagnostics_are_located(
    tmp_path: Path, change: str, code: str, where: tuple[str, str] | None
) -> None:
    text = FRONT.replace(change, code)
    assert text != FRONT
    errors = _diags(tmp_path, text)
    if where is None:
        assert errors == []
        return
    assert [d.code for d in errors] == [where[0]], errors
    d = errors[0]
    line = text.splitlines()[d.span.line - 1]
    assert where[1].split()[-1] in line, (line, d)
    assert d.hint


def test_reads_follow_the_chosen_option(lib: eac.Library) -> None:
    bar = lib["VFront"].instantiate(kind="bar")
    knob = lib["VFront"].instantiate(kind="knob")
    # the option's own mounting: the bar's axis 32 mm off the face, the knob's head centre at
    # the stem plus half its depth (12 + 8 mm), both on an 18 mm front
    assert bar.grasp("handle.pull")[2, 3] == pytest.approx(0.018 + 0.032)
    assert knob.grasp("handle.pinch")[2, 3] == pytest.approx(0.018 + 0.020)
    with pytest.raises(eac.UnknownNameError):
        knob.grasp("handle.pull")
    assert [o.grasp for o in bar.rank("open")][:1] == ["handle@bar.pull"]
    assert [o.grasp for o in knob.rank("open")][:1] == ["handle@knob.pinch"]
    # the host's requirement reads the bar's parameters through the guard
    req = next(r for r in lib["VFront"].entry["requires"] if r["message"] == "a finger fits")
    assert req["condition"].startswith('kind != "bar" or handle@bar.standoff')


def test_pass_through_binds_every_option_that_has_the_parameter(lib: eac.Library) -> None:
    host = lib["Host"]
    names = {p.name for p in host.params}
    assert "f.handle@bar.radius" not in names and "f.handle@knob.radius" not in names
    assert "f.handle@bar.length" not in names and "f.handle@knob.depth" in names
    knob = host.instantiate(hk="knob")
    assert knob.grasp_width("f.handle.pinch") == pytest.approx(0.024)  # 2 x the 12 mm bound
    assert knob.grasp("f.handle.pinch")[2, 3] == pytest.approx(0.038)
    bar = host.instantiate(hk="bar")
    lo, hi = bar.grasp_range("f.handle.pull")["s"]
    assert hi - lo == pytest.approx(0.200 - 2 * 0.0175, abs=0.03)  # the 200 mm bar's span
    assert [o.grasp for o in knob.rank("open")][:1] == ["f.handle@knob.pinch"]
    assert np.isfinite(bar.grasp("f.handle.pull")).all()


def test_catalog_and_manifest_list_the_nested_variant(lib: eac.Library) -> None:
    variants = lib["Host"].entry["variants"]
    assert variants["f.handle"]["param"] == "hk"
    assert set(variants["f.handle"]["options"]) == {"bar", "knob"}
    catalog = build_catalog(lib, ["Host"])
    assert "f.handle" in str(catalog)
