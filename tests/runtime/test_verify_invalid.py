"""Draws inside the declared ranges whose shapes or formulas cannot be evaluated: `eacc verify`
reports them as failures naming what broke, its `file:line` and the values, instead of crashing
(it raised `GeometryError: RectRing.inner must be > 0` and `points must be finite` before)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.runtime.verify import ENDS, draw_params, verify_concept
from tests.conftest import write

# the opening of the ring closes up once border > size / 2: inner = size - 2 border <= 0
FRAME = """\
use primitives.{RectRing}

/// A picture frame whose opening can close up.
concept Frame {
    param size : length in [100mm, 300mm] = 200mm "outer width and height"
    param border : length in [10mm, 150mm] = 20mm "width of the border"

    shape ring = RectRing(outer: (size, size), inner: (size - 2 * border, size - 2 * border),
        depth: 20mm)
    /// Pinch the top border.
    grasp top = trans(0, size / 2 - border / 2, 0) * roty(180deg) width border
}
"""

# the grasp's offset 1mm * 1mm / r is infinite at r = 0, the lower end of r's range
RECIP = """\
use primitives.{Cylinder}

/// A knob whose grasp offset divides by a parameter that may be 0.
concept Recip {
    param r : length in [0, 50mm] = 20mm "a length the offset divides by"

    shape body = Cylinder(radius: 10mm, height: 20mm)
    /// Pinch it.
    grasp pinch = trans(0, 0, 1mm * 1mm / r) * roty(180deg) width 20mm
}
"""


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> eac.Library:
    d = tmp_path_factory.mktemp("invalid")
    return eac.compile_paths([write(d, "frame.eac", FRAME), write(d, "recip.eac", RECIP)])


def test_a_shape_that_cannot_be_built_is_a_failure(lib: eac.Library) -> None:
    report = verify_concept(lib["Frame"], draws=20, seed=0)
    shape = [f for f in report.failures if f.check == "shape"]
    assert shape, report.failures
    f = shape[0]
    assert f.member == "ring (frame.eac:8)"
    assert "RectRing.inner must be > 0" in f.message and "frame.eac:8" in f.message
    size, border = f.si["params"]["size"], f.si["params"]["border"]
    assert size - 2 * border <= 0  # the reported values do close the opening
    assert f"border = {border * 1e3:g}mm" in f.message
    # draws whose opening stays open are checked as usual, and none of them fails `shape`
    assert report.evaluated["near"] > 0


def test_a_formula_infinite_at_a_range_end_is_a_failure(lib: eac.Library) -> None:
    report = verify_concept(lib["Recip"], draws=40, seed=0)
    finite = [f for f in report.failures if f.check == "finite"]
    assert finite, report.failures
    for f in finite:
        assert f.member == "pinch (recip.eac:9)"
        assert f.si["params"]["r"] == 0.0
        assert "r = 0mm" in f.message and "not finite" in f.message
    assert all(f.check != "finite" for f in report.failures if f.si["params"]["r"] > 0)


def test_range_ends_are_drawn(lib: eac.Library) -> None:
    import numpy as np

    rng = np.random.default_rng(1)
    rs = [draw_params(lib["Recip"], rng)["r"] for _ in range(40 * ENDS)]
    assert 0.0 in rs and 0.05 in rs
    assert 0.6 < sum(0.0 < r < 0.05 for r in rs) / len(rs) < 1.0


def test_eacc_verify_reports_instead_of_crashing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "frame.eac", FRAME)
    assert main(["verify", str(path), "--draws", "10", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    checks = {f["check"] for c in out["concepts"] for f in c["failures"]}
    assert "shape" in checks
