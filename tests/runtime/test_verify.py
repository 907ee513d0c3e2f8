"""`eacc verify`: the gripper's pads, the verifier's checks on deliberately broken concepts, the
report's JSON form, the command line, and the whole standard library (a few draws; the 200-draw
run is `make verify`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.geometry import primitive_sdf
from grace_dsl.runtime.gripper import Gripper, finger_points
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.verify import (
    VerifyReport,
    concept_seed,
    draw_params,
    verify_concept,
    verify_library,
)
from tests.conftest import write

PANDA = Gripper.panda()

# A drawer with a bar handle, 30 mm in front of its front panel. `good` holds the bar properly;
# every other grasp is wrong in one way.
DRAWER = """\
/// A drawer with a bar handle. Frame: the centre of the front panel, +z out of it, +y up.
concept NAME {
    param front : vec3 length in [(300mm, 100mm, 18mm), (600mm, 200mm, 22mm)]
        = (400mm, 150mm, 20mm) "width, height and thickness of the front"
    param radius : length in [5mm, 8mm] = 6mm "radius of the bar"

    shape carcass = Cuboid(size: (front.x + 40mm, front.y + 40mm, 300mm))
        at trans(0, 0, -front.z / 2 - 151mm)
    link drawer {
        shape panel = Cuboid(size: front)
        shape bar = Capsule(radius: radius, length: 200mm)
            at trans(0, 0, front.z / 2 + 30mm) * roty(90deg)
        /// Pinch the bar from the front, the fingers closing vertically across it.
        grasp good(s in [-80mm, 80mm] = 0) =
            trans(s, 0, front.z / 2 + 30mm) * roty(180deg)
            width 2 * radius
BROKEN    }
    joint slide : prismatic(base -> drawer) axis (0, 0, 1) range [0, 250mm]

    /// Pull the drawer out by its handle.
    action open = pull along slide using good
    /// Push it back in.
    action close = push along slide using good
ACTIONS}
"""

BROKEN_GRASPS = """\
        /// 20 mm in front of the bar's surface.
        grasp far = trans(0, 0, front.z / 2 + 30mm + radius + 20mm) * roty(180deg)
            width 2 * radius
        /// Wider than any Panda opens.
        grasp wide = trans(0, 0, front.z / 2 + 30mm) * roty(180deg) width 120mm
        /// Across the whole front, no width given: the material is front.x wide.
        grasp across = roty(180deg) * rotz(90deg)
        /// A press whose +z points out of the panel instead of into it.
        grasp poke = trans(0, 50mm, front.z / 2) width 0 by press
"""
# A press on the carcass's top: a fine grasp, but on the base link, so `slide` cannot move it.
BROKEN_ACTIONS = """\
    grasp fixed = trans(0, front.y / 2 + 20mm, -front.z / 2 - 151mm) * rotx(90deg) width 0 by press
    /// Pull the drawer out by the carcass.
    action open_wrong = pull along slide using fixed
"""


def _source(name: str, broken: bool) -> str:
    text = DRAWER.replace("NAME", name).replace("BROKEN", BROKEN_GRASPS if broken else "")
    return text.replace("ACTIONS", BROKEN_ACTIONS if broken else "")


@pytest.fixture(scope="module")
def drawers(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("verify") / "drawers.eac"
    uses = "use primitives.{Capsule, Cuboid}\n\n"
    path.write_text(uses + _source("GoodDrawer", False) + "\n" + _source("BrokenDrawer", True))
    return path


@pytest.fixture(scope="module")
def lib(drawers: Path) -> eac.Library:
    return eac.compile_paths([drawers])


@pytest.fixture(scope="module")
def broken(lib: eac.Library) -> VerifyReport:
    return verify_library(lib, ["BrokenDrawer"], draws=4, seed=1)


# ---- the gripper ------------------------------------------------------------------------------


def test_panda_pads_are_the_urdf_rubber_tips() -> None:
    assert PANDA.max_width == 0.08
    assert (PANDA.finger_width, PANDA.finger_thickness, PANDA.finger_length) == (
        0.0175,
        0.0152,
        0.0185,
    )


@settings(max_examples=25, deadline=None)
@given(width=st.floats(0.0, 0.08))
def test_pads_close_on_the_width_with_tips_at_the_origin(width: float) -> None:
    boxes = PANDA.finger_boxes(width)
    corners = []
    for box in boxes:
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        local = signs * np.asarray(box.half_extents)
        corners.append(local @ box.pose[:3, :3].T + box.pose[:3, 3])
    lower, upper = corners
    assert upper[:, 1].min() == pytest.approx(width / 2) and lower[:, 1].max() == pytest.approx(
        -width / 2
    )
    for c in corners:
        assert c[:, 2].max() == pytest.approx(0.0) and c[:, 2].min() == pytest.approx(-0.0185)
        assert np.ptp(c[:, 0]) == pytest.approx(0.0175) and np.ptp(c[:, 1]) == pytest.approx(0.0152)


@pytest.mark.parametrize("width", [0.0, 0.013, 0.08])
def test_finger_points_lie_on_the_pad_surfaces(width: float) -> None:
    points = finger_points(PANDA, width, spacing=0.002)
    dist = []
    for box in PANDA.finger_boxes(width):
        local = (points - box.pose[:3, 3]) @ box.pose[:3, :3]
        size = tuple(2 * h for h in box.half_extents)
        dist.append(primitive_sdf("Cuboid", {"size": size}, local))
    np.testing.assert_allclose(np.min(dist, axis=0), 0.0, atol=1e-12)
    # a grid on every face: each face of each pad holds points, at most 2 mm apart
    assert len(points) > 2 * 6 * 9 * 9
    face = points[np.isclose(points[:, 2], 0.0) & (points[:, 1] > 0)]
    assert np.unique(np.round(face[:, 0], 9)).size >= math.ceil(17.5 / 2) + 1


@settings(max_examples=20, deadline=None)
@given(width=st.floats(0.0, 0.08))
def test_opening_moves_each_pad_by_half_the_width(width: float) -> None:
    """The closed grid, its -y pad's points first, shifted by -+width/2: what the verifier
    reuses instead of rebuilding the grid for every width."""
    closed, opened = finger_points(PANDA, 0.0), finger_points(PANDA, width)
    half = len(closed) // 2
    shift = np.zeros_like(closed)
    shift[:half, 1], shift[half:, 1] = -width / 2, width / 2
    np.testing.assert_allclose(opened, closed + shift, atol=1e-15)


@pytest.mark.parametrize(
    "kwargs, text",
    [
        ({"max_width": -0.01}, "max_width"),
        ({"finger_length": 0.0}, "finger_length"),
        ({"finger_width": float("nan")}, "finger_width"),
        ({"approach": (0.0, 0.0, 0.0)}, "approach"),
        ({"approach_tolerance": 4.0}, "approach_tolerance"),
    ],
)
def test_bad_gripper_values_are_typed_errors(kwargs: dict[str, object], text: str) -> None:
    fields = dict(
        name="g", max_width=0.05, finger_width=0.01, finger_thickness=0.01, finger_length=0.02
    )
    with pytest.raises(eac.ParameterError, match=text):
        Gripper(**(fields | kwargs))  # type: ignore[arg-type]


def test_the_hand_cannot_open_past_its_width() -> None:
    with pytest.raises(eac.ParameterError, match="opens 0-80 mm"):
        PANDA.finger_boxes(0.12)


# ---- the checks ---------------------------------------------------------------------------


def test_a_good_concept_passes(lib: eac.Library) -> None:
    report = verify_concept(lib["GoodDrawer"], draws=6, seed=3)
    assert report.ok, report.failures
    assert report.draws == 6 and report.attempts == 6 and report.note == ""
    # 6 draws x 2 joint states x 5 free values, and two actions on the grasp
    for check in ("near", "between", "width", "penetration"):
        assert report.evaluated[check] == 60
    assert report.evaluated["power"] == report.evaluated["follow"] == 120


def _failed(report: VerifyReport) -> set[tuple[str, str]]:
    return {(f.check, f.member) for f in report.failures}


def test_each_broken_grasp_fails_its_check(broken: VerifyReport) -> None:
    assert _failed(broken) == {
        ("near", "far"),
        ("between", "far"),
        ("width", "wide"),
        ("width", "across"),
        ("into", "poke"),
        ("penetration", "poke"),
        ("power", "open_wrong/fixed"),
        ("follow", "open_wrong/fixed"),  # follow moves it with the drawer; its link stays
    }
    # every draw fails each of them once (the worst sample of the draw)
    assert len(broken.failures) == 8 * 4


def test_failures_carry_the_values_that_caused_them(broken: VerifyReport, lib) -> None:  # type: ignore[no-untyped-def]
    by = {(f.check, f.member): f for f in broken.failures}
    far = by["near", "far"]
    assert far.value == pytest.approx(20.0) and far.limit == 5.0 and far.unit == "mm"
    assert set(far.params) == {"front", "radius", "q.slide"}
    assert far.params["radius"].endswith("mm")
    wide = by["width", "wide"]
    assert (wide.value, wide.limit) == pytest.approx((120.0, 80.0))
    # the material across the front is front.x wide
    across = by["width", "across"]
    assert across.value == pytest.approx(across.si["params"]["front"][0] * 1e3, abs=1e-4)
    assert by["into", "poke"].value == pytest.approx(1.0, abs=1e-6)  # sdf grows along +z
    # the pads run 18.5 mm into the panel: their deepest points sit mid-way through its
    # thickness (to the 1.85 mm grid along z)
    poke = by["penetration", "poke"]
    assert poke.value == pytest.approx(poke.si["params"]["front"][2] / 2 * 1e3, abs=1.0)
    assert by["power", "open_wrong/fixed"].value == 0.0
    assert "does not move" in by["power", "open_wrong/fixed"].message
    # the SI values reproduce the failure through the public API
    si = far.si
    inst = lib["BrokenDrawer"].instantiate(pose=si["pose"], joints=si["joints"], **si["params"])
    origin = inst.grasp("far", **si["free"])[:3, 3]
    bar = inst.link_pose("drawer") @ np.array([0, 0, si["params"]["front"][2] / 2 + 0.03, 1])
    r = si["params"]["radius"]
    assert np.linalg.norm(origin - bar[:3]) - r == pytest.approx(far.value / 1e3, abs=1e-9)


def test_a_force_against_the_declared_sense_fails_power(lib: eac.Library) -> None:
    """A concept whose compiled `open` force is the closing one (its manifest entry tampered
    with): the grasp point's own motion, from the link poses, exposes it."""
    good = lib["GoodDrawer"]
    entry = json.loads(json.dumps(good.entry))
    fns = entry["functions"]
    fns["force:open"], fns["force:close"] = fns["force:close"], fns["force:open"]
    swapped = Concept(entry, good._functions)
    report = verify_concept(swapped, draws=3, seed=0)
    assert _failed(report) == {("power", "open/good"), ("power", "close/good")}
    assert all(f.value == pytest.approx(-1.0) for f in report.failures)


def test_the_same_seed_gives_the_same_report(lib: eac.Library) -> None:
    a = verify_concept(lib["BrokenDrawer"], draws=2, seed=5)
    assert a == verify_concept(lib["BrokenDrawer"], draws=2, seed=5)
    assert a != verify_concept(lib["BrokenDrawer"], draws=2, seed=6)
    assert concept_seed(0, "A") != concept_seed(0, "B") and concept_seed(0, "A") == concept_seed(
        0, "A"
    )


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_draws_stay_inside_the_ranges(lib: eac.Library, seed: int) -> None:
    c = lib["BrokenDrawer"]
    values = draw_params(c, np.random.default_rng(seed))
    for p in c.params:
        v = np.atleast_1d(values[p.name])
        assert np.all(v >= np.atleast_1d(p.lo)) and np.all(v <= np.atleast_1d(p.hi))


TIGHT = """\
/// A box whose side must be short.
concept NAME {
    param a : length in [0mm, 100mm] = 50.1mm "a side"
    require a > 50mm and a < 50mm + LIMIT "a is inside a narrow band (no range end is)"

    shape box = Cuboid(size: (a + 10mm, 10mm, 10mm))
    /// Press its front.
    grasp tip = trans(0, 0, 5mm) * roty(180deg) width 0 by press
    /// Press it.
    action poke = press toward (0, 0, -1) using tip
}
"""


def test_tight_requirements_are_redrawn_and_reported(tmp_path: Path) -> None:
    """A narrow band (10% of uniform draws) is reached by repairing each draw (redrawing `a`,
    the parameter the failing requirement reads), so no draw is rejected; a band no value is in
    stops at the attempt cap and says so in the report."""
    text = "use primitives.{Cuboid}\n\n" + TIGHT.replace("NAME", "Tight")
    only_default = 'require a == 50.1mm "only the default (no random draw is)"'
    band = 'require a > 50mm and a < 50mm + LIMIT "a is inside a narrow band (no range end is)"'
    assert band in TIGHT
    text += TIGHT.replace("NAME", "Empty").replace(band, only_default)
    lib = eac.compile_paths([write(tmp_path, "tight.eac", text.replace("LIMIT", "10mm"))])
    report = verify_concept(lib["Tight"], draws=5, seed=0)
    assert report.ok and report.note == ""
    assert report.draws == 5 and report.attempts == 5 and report.rejected == 0
    none = verify_concept(lib["Empty"], draws=2, seed=0)
    assert none.draws == 0 and none.attempts == 50 * 2 and none.rejected == 100
    assert "only 0 of 100 draws satisfy the requirements" in none.note


# ---- the report ---------------------------------------------------------------------------


def test_the_report_round_trips_through_json(broken: VerifyReport) -> None:
    text = json.dumps(broken.to_json())
    back = VerifyReport.from_json(json.loads(text))
    assert back == broken
    data = json.loads(text)
    assert data["ok"] is False and data["concepts"][0]["rejected"] == 0
    assert {"check", "member", "params", "value", "limit", "si"} <= set(
        data["concepts"][0]["failures"][0]
    )


def test_command_line(drawers: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["verify", str(drawers), "--draws", "2", "--seed", "1"]
    assert main([*argv, "--concept", "GoodDrawer"]) == 0
    assert "every check passed" in capsys.readouterr().out
    assert main([*argv, "--concept", "BrokenDrawer", "--json"]) == 1
    report = VerifyReport.from_json(json.loads(capsys.readouterr().out))
    assert ("width", "wide") in _failed(report) and report.draws == 2
    assert main([*argv, "--concept", "BrokenDrawer"]) == 1
    out = capsys.readouterr().out
    assert "near" in out and "open_wrong/fixed" in out and "failing draws in 1 concepts" in out
    assert main([*argv, "--concept", "BrokenDrawr"]) == 2
    assert "did you mean 'BrokenDrawer'" in capsys.readouterr().err


# ---- the standard library -----------------------------------------------------------------


@pytest.mark.slow
def test_the_standard_library_passes(stdlib: eac.Library) -> None:
    """Every concept, 5 draws each (`make verify` runs 200)."""
    report = verify_library(stdlib, draws=5, seed=0)
    failed = [(f.concept, f.check, f.member, f.message) for f in report.failures]
    assert report.ok, failed
    assert all(c.draws == 5 for c in report.concepts)
    # every concept with a grasp had its grasps checked against the part (Plinth and Legs have none)
    assert all(c.evaluated["near"] > 0 for c in report.concepts if stdlib[c.concept].grasps)
