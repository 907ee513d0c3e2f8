"""Estimated mode's choices: where the next look goes (in the protocol's elevation band,
toward a refused fused fit's front, never steered by a fit at confidence ~0), when a fused
front counts as seen, and a refused fused fit run again from each single fit alone."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.estimated import (
    ELEVATIONS,
    HIGH_ELEVATION,
    EstimateRefused,
    Perceived,
    Sight,
    View,
    camera_for,
    front_in_view,
    fuse,
    next_view,
)
from grace_dsl.perception.looks import Look
from grace_dsl.perception.types import Estimate
from grace_dsl.perception.views import split_params

CENTRE = (0.0, 0.0, 0.4)


def test_every_chosen_view_stays_in_the_protocols_elevation_band() -> None:
    low, high = ELEVATIONS
    for first in (View(10.0, 30.0), View(200.0, 47.0), View(300.0, 60.0)):
        for sights in (
            [Sight(first, CENTRE, handle=0)],  # a hidden handle: as low as the band allows
            [Sight(first, CENTRE, handle_at=(0.5, 0.1, 0.4), handle=40)],
            [Sight(first, CENTRE, front=(0.0, 1.0, 0.0), handle=-1)],
        ):
            got = next_view(first, sights)
            assert low <= got.elevation <= high, (first, got)
    assert next_view(View(10.0, 55.0), [Sight(View(10.0, 55.0), CENTRE, handle=0)]).elevation == low
    seen = Sight(View(300.0, 60.0), CENTRE, handle_at=(0.5, 0.0, 0.4), handle=40)
    assert next_view(View(300.0, 60.0), [seen]).elevation == HIGH_ELEVATION


def test_a_fit_at_confidence_zero_does_not_choose_the_next_view() -> None:
    """A refused look whose fit is noise (confidence 0.00, a LidBox seen from above): its front
    says nothing, so the next look is from the other side, not where that front points."""
    first = View(230.0, 40.0)
    noise = Sight(first, CENTRE, front=(0.0, 1.0, 0.0), handle=-1, confidence=0.0)
    assert next_view(first, [noise]).azimuth == pytest.approx(50.0)
    trusted = Sight(first, CENTRE, front=(0.0, 1.0, 0.0), handle=-1, confidence=0.6)
    assert next_view(first, [trusted]).azimuth == pytest.approx(90.0)


def test_a_refused_fused_fits_front_is_where_the_next_look_goes() -> None:
    """Laptop close seed 2: three looks from its sides and back, fused at confidence 0.96 with
    the front (+x) facing none of them; the next look is taken from the front."""
    first = View(230.0, 31.0)
    sights = [
        Sight(first, CENTRE, front=(0.0, -1.0, 0.0), handle=-1, confidence=0.0),
        Sight(View(276.0, 31.0), CENTRE, front=(0.0, -1.0, 0.0), handle=-1, confidence=0.0),
    ]
    fused = Sight(View(276.0, 31.0), CENTRE, front=(1.0, 0.0, 0.0), confidence=0.96, fused=True)
    assert next_view(first, sights, fused).azimuth == pytest.approx(0.0)
    weak = Sight(View(276.0, 31.0), CENTRE, front=(1.0, 0.0, 0.0), confidence=0.2, fused=True)
    assert next_view(first, sights, weak).azimuth != pytest.approx(0.0)


def _camera(azimuth: float, elevation: float = 31.0) -> np.ndarray:
    return camera_for(View(azimuth, elevation), np.zeros(3), 0.3).pose()


def test_a_front_seen_edge_on_from_two_sides_counts_as_in_view() -> None:
    pose = np.eye(4)
    pose[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]  # +z toward world +x
    sides = [_camera(96.0), _camera(276.0), _camera(230.0)]
    assert front_in_view(pose, sides)  # 95 deg from the nearest camera: edge-on
    assert not front_in_view(pose, sides[:1])  # one camera: it must face it
    assert not front_in_view(pose, [_camera(150.0), _camera(210.0)])  # turned away from both
    assert front_in_view(pose, [_camera(20.0)])


def test_a_refused_fused_fit_is_run_again_from_each_single_fit(lib: eac.Library) -> None:
    """Two single fits that disagree start the joint fit in neither basin (CabinetDrawer
    close seed 2: 0.55 alone, 0.00 fused); run from the better one alone it converges."""
    concept = lib["CabinetDrawer"]
    inst = concept.instantiate()
    floats, _ = split_params(concept, inst.params)

    def est(confidence: float, x: float) -> Estimate:
        pose = np.eye(4)
        pose[0, 3] = x
        return Estimate("CabinetDrawer", dict(floats), pose, {}, 0.002, confidence, 0.1)

    def perceived(view: View, e: Estimate) -> Perceived:
        sight = Sight(view, CENTRE, handle=300, cloud=Look(np.zeros((4, 3)), _camera(0.0)))
        return Perceived("CabinetDrawer", dict(inst.params), e.pose, {}, e.residual,
                         e.confidence, "fit", view, 100, 0.1, e, 300, sight)  # fmt: skip

    guesses = [
        perceived(View(0.0, 40.0), est(0.55, 0.0)),
        perceived(View(40.0, 40.0), est(0.1, 0.3)),
    ]
    runs: list[list[float]] = []

    def fit(clouds: list[Look], starts: list[Estimate]) -> Estimate:
        runs.append([float(s.pose[0, 3]) for s in starts])
        return est(0.9 if len(starts) == 1 and starts[0].pose[0, 3] == 0.0 else 0.0, 0.0)

    sights = [g.sight for g in guesses if g.sight is not None]
    got = fuse(concept, sights, guesses, fit=fit)
    assert got.confidence == 0.9 and runs == [[0.0, 0.3], [0.0]]
    runs.clear()
    with pytest.raises(EstimateRefused) as refused:
        fuse(concept, sights, guesses, fit=lambda c, s: runs.append([]) or est(0.0, 0))
    assert len(runs) == 3 and refused.value.perceived is not None
    assert math.isclose(refused.value.perceived.confidence, 0.0)
