"""Estimated mode: the looks fitted together from the second on, and a frameless leaf's joint
from the protocol's upright base."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.estimated import (
    EstimateRefused,
    Perceived,
    Sight,
    View,
    frameless_joint,
    look_around,
)


def _perceived(view: View, source: str = "fit", confidence: float = 0.9) -> Perceived:
    sight = Sight(view, (0.0, 0.0, 0.0), handle=30)
    return Perceived("X", {}, np.eye(4), {}, 0.003, confidence, source, view, 100, 0.1,
                     sight=sight)  # fmt: skip


def test_look_around_fits_the_looks_together_from_the_second_on() -> None:
    calls: list[tuple[int, int]] = []

    def see(view: View) -> Perceived:
        if view.azimuth == 0.0:  # the first look is refused, with its fit as a guess
            guess = _perceived(view, confidence=0.3)
            raise EstimateRefused("low confidence", guess, guess.sight)
        return _perceived(view)

    def fused(sights: list[Sight], guesses: list[Perceived]) -> Perceived:
        calls.append((len(sights), len(guesses)))
        return _perceived(sights[-1].view, "fused", 0.95)

    got, account = look_around([View(0.0, 40.0), View(90.0, 40.0)], see, fused=fused)
    assert got is not None and got.source == "fused" and calls == [(2, 2)]
    assert [("refused" in a, a.get("fused")) for a in account] == [(True, None), (False, None),
                                                                    (False, 2)]  # fmt: skip

    def refuse(sights: list[Sight], guesses: list[Perceived]) -> Perceived:
        raise EstimateRefused("fused: confidence 0.20")

    got, account = look_around([View(0.0, 40.0), View(90.0, 40.0)], see, fused=refuse)
    assert got is not None and got.source == "fit"  # the second look's own, accepted
    assert account[-1]["fused"] == 2 and "refused" in account[-1]
    calls.clear()
    got, _ = look_around([View(90.0, 40.0), View(0.0, 40.0)], see, fused=fused)
    assert got is not None and got.source == "fit" and calls == []  # the first look stands


@pytest.mark.slow
def test_a_frameless_leafs_joint_comes_from_the_upright_base(lib: eac.Library) -> None:
    """A door leaf fitted with its base turned 0.5 rad about the hinge and the joint turned
    back: the leaf is where it is, the pair is taken apart again from the upright base."""
    concept = lib["DoorLeaf"]
    q = 0.9
    truth = concept.instantiate(joints={"hinge": q})
    leaf = truth.link_pose("leaf")
    wrong_q = q - 0.5
    rel = concept.instantiate(joints={"hinge": wrong_q}).link_pose("leaf")
    turned = leaf @ np.linalg.inv(rel)  # the base that puts the leaf in place at wrong_q
    assert math.degrees(math.acos((np.trace(turned[:3, :3]) - 1) / 2)) > 25
    got = Perceived("DoorLeaf", dict(truth.params), turned, {"hinge": wrong_q}, 0.002, 1.0,
                    "fit", View(0.0, 40.0), 1000, 0.1)  # fmt: skip
    fixed = frameless_joint(concept, got, "hinge", np.eye(3))
    assert fixed is not None
    assert abs(fixed.joints["hinge"] - q) < math.radians(0.5)
    assert np.allclose(fixed.pose[:3, :3], np.eye(3), atol=0.01)
    np.testing.assert_allclose(fixed.instance(concept).link_pose("leaf"), leaf, atol=1e-6)
    # a cabinet's carcass shows its door's angle: left alone
    cab = lib["HingedCabinet"].instantiate()
    on = Perceived("HingedCabinet", dict(cab.params), np.eye(4), {}, 0.002, 1.0, "fit",
                   View(0.0, 40.0), 1000, 0.1)  # fmt: skip
    joint = next(iter(cab.joint_limits()))
    assert frameless_joint(lib["HingedCabinet"], on, joint, np.eye(3)) is None
