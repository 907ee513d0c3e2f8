"""`eacc prompt`: the concept catalog on stdout or in a file, markdown or JSON."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from grace_dsl.cli.eacc import main
from tests.conftest import write

SMALL = """use primitives.{Cuboid}

/// A flap on a hinge, for the catalog.
concept Flap {
    param size : vec3 length in [(100mm, 100mm, 10mm), (500mm, 500mm, 40mm)] = (300mm, 200mm, 20mm)
        "width, height and thickness"
    shape frame = Cuboid(size: size)
    link leaf { shape panel = Cuboid(size: size) at trans(0, 0, size.z) }
    /// The hinge along the top edge.
    joint hinge : revolute(base -> leaf) axis (1, 0, 0) at (0, size.y / 2, size.z) range [0, 90deg]
    /// Pinch the bottom edge.
    grasp edge(s in [-size.x / 2, size.x / 2] = 0) =
        trans(s, -size.y / 2, size.z) * rotx(90deg) width size.z
    /// Lift the flap by its bottom edge.
    action lift = pull along hinge using edge
}
"""


def test_markdown_of_one_library(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "flap.eac", SMALL)
    assert main(["prompt", str(path)]) == 0
    out = capsys.readouterr().out
    assert "## Flap (`flap.eac`)" in out and "### Flap" in out
    assert "| `size` | vec3 length | [(100mm, 100mm, 10mm), (500mm, 500mm, 40mm)] |" in out
    assert (
        "- free `s` (length) in `[-size.x / 2, size.x / 2]` = [-150mm, 150mm] at the defaults"
        in out
    )
    assert "`G = trans(s, -size.y / 2, size.z) * rotx(90deg)`" in out
    assert "gripper opening: `size.z` = 20mm at the defaults" in out
    assert "- `lift`: pull along `hinge` (opening), using `edge`. Lift the flap" in out
    assert "force: `F = normalize(" in out


def test_json_to_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "flap.eac", SMALL)
    out = tmp_path / "deep" / "catalog.json"
    assert main(["prompt", str(path), "--json", "-o", str(out), "--concept", "Flap"]) == 0
    assert capsys.readouterr().out == ""
    data = json.loads(out.read_text())
    (cat,) = data["categories"]
    (flap,) = cat["concepts"]
    assert flap["name"] == "Flap" and flap["params"][0]["default"] == [0.3, 0.2, 0.02]
    (lift,) = flap["actions"]
    # a revolute joint about +x through (0, size.y / 2, size.z): v = (1, 0, 0) x (x - o)
    assert lift["force"]["rest_text"] == "normalize([0, size.z - z_g, -size.y/2 + y_g])"


def test_format_flag_and_unknown_concept(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["prompt", "--format", "json", "--concept", "CurveHandle"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in data["categories"][0]["concepts"]] == ["CurveHandle"]
    assert main(["prompt", "--concept", "CurveHandel"]) == 1
    assert "did you mean 'CurveHandle'" in capsys.readouterr().err


def test_a_broken_source_exits_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write(tmp_path, "bad.eac", "concept A {\n    param r : length = 5\n}\n")
    assert main(["prompt", str(path)]) == 1
    assert "E204" in capsys.readouterr().err
