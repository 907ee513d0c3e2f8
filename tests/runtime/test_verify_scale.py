"""``eacc verify --scale``: every length range multiplied by a factor, instances made with
``ranges="valid"``; a requirement that forbids the scaled defaults is reported, not failed."""

from __future__ import annotations

import json

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.cli.eacc import main
from grace_dsl.runtime.verify import (
    ConceptReport,
    VerifyReport,
    check_scale,
    draw_params,
    forbidding_requirement,
    scaled_defaults,
    scaled_specs,
    verify_concept,
    verify_library,
)
from tests.test_library import LOW_YIELD  # concepts few of whose draws are valid (a defect)


def test_scaled_specs_multiply_lengths_only(lib) -> None:  # type: ignore[no-untyped-def]
    concept = lib["LeverHandle"]
    by_name = {p.name: p for p in scaled_specs(concept, 0.5)}
    for p in concept.params:
        q = by_name[p.name]
        if p.dim == "length":
            assert (q.lo, q.hi, q.default) == pytest.approx((p.lo / 2, p.hi / 2, p.default / 2))
        else:
            assert q == p  # the throw (an angle) and the hand (a choice) keep theirs
    values = scaled_defaults(concept, 2.0)
    assert values["length"] == pytest.approx(0.26) and values["hand"] == "right"
    rng = np.random.default_rng(0)
    for _ in range(20):
        drawn = draw_params(concept, rng, scaled_specs(concept, 2.0))
        assert 0.18 <= drawn["length"] <= 0.34


def test_a_requirement_forbids_a_scale(lib) -> None:  # type: ignore[no-untyped-def]
    """A 0.3x bar handle leaves 7.8 mm behind the bar: a Panda finger needs 19 mm."""
    why = forbidding_requirement(lib["StraightHandle"], 0.3)
    assert "a finger fits between the bar and the panel" in why
    report = verify_concept(lib["StraightHandle"], draws=3, seed=0, scale=0.3)
    assert report.ok and report.draws == 0 and report.forbidden == why
    assert "not drawn at 0.3x" in report.note
    assert forbidding_requirement(lib["StraightHandle"], 2.0) == ""


def test_scaled_defaults_keep_bools(lib) -> None:  # type: ignore[no-untyped-def]
    """A bool parameter stays a bool, so a concept with one is forbidden by name, not drawn."""
    assert scaled_defaults(lib["DoorLeaf"], 0.3)["handle_vertical"] is True
    why = forbidding_requirement(lib["DoorLeaf"], 0.3)
    assert "the handle leaves the free edge to push on" in why
    assert forbidding_requirement(lib["DoorLeaf"], 2.0) == ""


def test_a_scaled_run_round_trips_through_json(lib) -> None:  # type: ignore[no-untyped-def]
    report = verify_library(lib, ["RoundKnob", "StraightHandle"], draws=2, seed=1, scale=0.3)
    assert report.scale == 0.3
    again = VerifyReport.from_json(json.loads(json.dumps(report.to_json())))
    assert again == report
    old = report.concepts[0].to_json()
    del old["scale"], old["forbidden"]  # reports written before scales read as scale 1
    assert ConceptReport.from_json(old).scale == 1.0


def test_a_pinch_wider_than_the_hand_is_its_limit_at_a_scale(lib) -> None:  # type: ignore[no-untyped-def]
    """At 3x a round knob is 96 mm across, wider than a Panda opens: noted, not failed; at 1x
    the same width is a failure (a knob of the typical family must fit the hand)."""
    report = verify_concept(lib["RoundKnob"], draws=3, seed=0, scale=3.0)
    assert report.ok and "wider than panda opens" in report.note and "pinch" in report.note


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "2", True])
def test_bad_scales(bad) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(eac.ParameterError, match="scale"):
        check_scale(bad)


def test_command_line_scales(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["verify", "--concept", "RoundKnob", "--concept", "StraightHandle",
                 "--draws", "2", "--scale", "0.3,2", "--json"])  # fmt: skip
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["ok"]
    assert [r["scale"] for r in out["runs"]] == [0.3, 2.0]
    forbidden = {c["concept"]: c["forbidden"] for c in out["runs"][0]["concepts"]}
    assert forbidden["RoundKnob"] == "" and "finger fits" in forbidden["StraightHandle"]
    with pytest.raises(SystemExit):
        main(["verify", "--scale", "0.3,-2"])
    assert "a scale is a finite number > 0" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("scale", [0.3, 2.0])
def test_the_library_verifies_at_a_scale(lib, scale: float) -> None:  # type: ignore[no-untyped-def]
    """Every concept instantiates and verifies at 0.3x and 2x its size, or names the requirement
    that forbids it (docs/library.md, "Verifying at other sizes")."""
    report = verify_library(lib, draws=10, seed=0, scale=scale)
    bad = [(f.concept, f.check, f.member, f.message) for f in report.failures]
    assert report.ok, bad[:10]
    drawn = [c for c in report.concepts if not c.forbidden]
    short = [c.concept for c in drawn if c.draws < 10 and c.concept not in LOW_YIELD]
    assert not short, short
    assert len(drawn) >= (18 if scale == 0.3 else len(report.concepts))
