"""A grasp family's ``when``: compiled, recorded, and honoured by grasp, rank and eacc verify."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.verify import verify_concept

# A drawer in a carcass whose front's back face lies on the carcass when shut: closed fingers
# fit behind the front only once it is out by more than their 17.5 mm.
TRAY = """use primitives.{Cuboid}

/// A drawer in a carcass. Frame: the front's centre, +z out of it, +y up.
concept Tray {
    param width : length in [200mm, 600mm] = 400mm
    shape carcass = Cuboid(size: (width + 40mm, 160mm, 300mm)) at trans(0, 0, -159mm)
    link drawer {
        shape front = Cuboid(size: (width, 120mm, 18mm))
        /// Hook the closed fingers behind the front from above, their side 1 mm off it.
        grasp hook_top(s in [-width / 2 + 40mm, width / 2 - 40mm] = 0) =
            trans(s, 40mm, -18.75mm) * rotx(90deg) * rotz(90deg)
            by hook
            WHEN
    }
    joint slide : prismatic(base -> drawer) axis (0, 0, 1) range [0, 300mm]
    action open = pull along slide using hook_top
}
"""


def _tray(tmp_path: Path, when: str, name: str = "tray") -> eac.Concept:
    path = tmp_path / f"{name}.eac"
    path.write_text(TRAY.replace("WHEN", when))
    return eac.compile_paths([path])["Tray"]


@pytest.fixture(scope="module")
def tray(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    return _tray(tmp_path_factory.mktemp("when"), "when slide > 19mm")


def test_the_condition_is_compiled_and_recorded(tray: eac.Concept) -> None:
    entry = tray.grasps["hook_top"]["when"]
    assert entry == {"condition": "slide > 19mm", "joints": ["slide"], "where": "tray.eac:13"}
    spec = tray.grasps["hook_top"]
    assert spec.when == "slide > 19mm" and spec.when_joints == ("slide",)
    fn = tray.function("grasp_when", "hook_top")
    inst = tray.instantiate(joints={"slide": 0.05})
    r, holds = (float(np.asarray(x).reshape(-1)[0]) for x in fn(inst.p, inst.q))
    assert r == pytest.approx(0.019 - 0.05) and holds == 1.0


def test_grasp_raises_where_the_condition_fails(tray: eac.Concept) -> None:
    shut, ajar = tray.instantiate(), tray.instantiate(joints={"slide": 0.05})
    assert not shut.grasp_applies("hook_top") and ajar.grasp_applies("hook_top")
    with pytest.raises(eac.GraspConditionError, match=r"applies only when slide > 19mm") as info:
        shut.grasp("hook_top")
    assert "(tray.eac:13); here slide = 0mm" in str(info.value)
    assert isinstance(info.value, eac.ParameterError)
    # the family's geometry stays available, whatever the state
    rotation = ajar.grasp("hook_top")[:3, :3]
    np.testing.assert_allclose(shut.grasps("hook_top", 1)[0][:3, :3], rotation)
    assert ajar.with_joints(slide=0.01).grasp_inapplicable("hook_top") is not None


@pytest.mark.parametrize("hand", ["panda", "pusher"])
def test_rank_honours_the_condition_shut_and_ajar(tray: eac.Concept, hand: str) -> None:
    gripper = eac.Gripper.load(hand)
    (shut,) = tray.instantiate().rank("open", gripper, samples=4)
    assert not shut.feasible
    assert shut.reasons == ("grasp hook_top applies only when slide > 19mm (tray.eac:13); "
                            "here slide = 0mm",)  # fmt: skip
    (ajar,) = tray.instantiate(joints={"slide": 0.1}).rank("open", gripper, samples=4)
    assert ajar.feasible, ajar.reasons


@pytest.mark.slow
def test_verify_checks_the_family_only_where_it_applies(tmp_path: Path, tray: eac.Concept) -> None:
    """Without `when` the hook enters the carcass at the closed joints; with it, verify checks
    it only at joint values past 19 mm, and a condition that never holds fails `applies`."""
    report = verify_concept(tray, draws=3, seed=0)
    assert report.ok, [f.message for f in report.failures]
    assert report.evaluated["penetration"] > 0 and report.evaluated["applies"] == 1
    always = verify_concept(_tray(tmp_path, "", "always"), draws=3, seed=0)
    failed = {(f.check, f.member) for f in always.failures}
    assert ("penetration", "hook_top") in failed
    never = verify_concept(_tray(tmp_path, "when width > 1m", "never"), draws=3, seed=0)
    assert [(f.check, f.member) for f in never.failures] == [("applies", "hook_top")]
    assert "held in none of 3 draws" in never.failures[0].message
    assert never.evaluated["penetration"] == 0


@pytest.mark.slow
def test_at_a_scale_a_family_that_never_applies_is_noted_not_failed(tmp_path: Path) -> None:
    """The hand does not scale with the object: a contact too small for it there is its limit."""
    report = verify_concept(_tray(tmp_path, "when width > 10m", "huge"), draws=2, seed=0, scale=2.0)
    assert report.ok and "never applies at 2x: hook_top" in report.note


def test_verify_measures_a_hook_from_the_side_it_rests_on(tray: eac.Concept) -> None:
    """The fingertips' centre is 9.75 mm behind the front, their +x side 1 mm: `near` passes for
    every shipped hand (pads 17-17.5 mm thick along x)."""
    for hand in ("panda", "pusher", "topdown"):
        report = verify_concept(tray, draws=2, seed=1, gripper=eac.Gripper.load(hand))
        assert not [f for f in report.failures if f.check == "near"], hand


@pytest.mark.slow
def test_the_pusher_lifts_an_ajar_laptop_lid_from_below_in_mujoco() -> None:
    """A real episode of a conditional family: the hand that cannot close opens a laptop whose
    lid is ajar by pushing it up from below (`lift_under`, whose `when` reads the hinge); on a
    shut lid rank offers no option (the lip is a fingernail's grip)."""
    import math
    import time

    from grace_dsl.sim.episode import Start, run_episode, start_episode
    from grace_dsl.sim.records import EpisodeConfig
    from grace_dsl.sim.runner import episode_seed

    config = EpisodeConfig("Laptop", "open", hand="pusher")
    ajar = None
    for i in range(40):
        seed = episode_seed(0, "Laptop", "open", i)
        start = start_episode(config, seed, time.perf_counter())
        assert isinstance(start, Start)
        q = start.inst.joints["hinge"]
        if math.radians(10) < q < math.radians(40):  # ajar, and far from the strict 50%
            ajar = seed
            break
    assert ajar is not None
    record = run_episode(config, ajar)
    assert record.option == "lift_under (push)", record.detail
    assert record.strict, record.detail
