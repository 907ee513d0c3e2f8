"""Typical and valid parameter values: ``instantiate(..., ranges="typical"|"valid")``."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.shapes import ShapeError
from grace_dsl.runtime.verify import draw_params, random_pose


def test_typical_refuses_a_toy_drawer_and_names_the_way_out(lib) -> None:  # type: ignore[no-untyped-def]
    drawer = lib["CabinetDrawer"]
    with pytest.raises(eac.ParameterError, match='ranges="valid"') as err:
        drawer.instantiate(front=(0.2, 0.12, 0.018))
    assert "outside its range" in str(err.value)


def test_valid_accepts_a_toy_drawer_and_places_its_handle(lib) -> None:  # type: ignore[no-untyped-def]
    """A 200 mm front (below the 300 mm typical minimum) instantiates; the handle's pull grasp
    sits where the concept's text puts it: on the front's centre, standoff in front of it."""
    pose = random_pose(np.random.default_rng(5))
    inst = lib["CabinetDrawer"].instantiate(
        pose=pose, ranges="valid", front=(0.2, 0.12, 0.018), depth=0.2, travel=0.15
    )
    assert inst.params["front"] == (0.2, 0.12, 0.018)
    standoff = inst.params["handle.standoff"]
    local = np.linalg.solve(pose, inst.grasp("handle.pull"))
    np.testing.assert_allclose(local[:3, 3], [0.0, 0.0, 0.009 + standoff], atol=1e-12)
    assert inst.joint_limits()["slide"] == (0.0, 0.15)


def test_a_small_knob_from_a_simulator_dataset(lib) -> None:  # type: ignore[no-untyped-def]
    """A 30 mm knob (15 mm radius is typical) and a 6 mm one (5 mm is below every range)."""
    knob = lib["RoundKnob"]
    for radius in (0.015, 0.006):
        inst = knob.instantiate(ranges="valid", radius=radius)
        assert inst.grasp_width("pinch") == pytest.approx(2 * radius, abs=1e-15)
    with pytest.raises(eac.ParameterError, match="outside its range"):
        knob.instantiate(radius=0.006)


def test_the_domain_keeps_signs_and_angles(lib) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(
        eac.ParameterError, match="radius = -10mm is not a valid value: it must be positive"
    ):
        lib["RoundKnob"].instantiate(ranges="valid", radius=-0.01)
    with pytest.raises(eac.ParameterError, match="must be positive"):
        lib["CabinetDrawer"].instantiate(ranges="valid", front=(0.5, 0.0, 0.018))
    # keep_clear's typical range starts at 0: 0 is valid, below is not
    handle = lib["CurveHandle"]
    handle.instantiate(ranges="valid", keep_clear=0.0)
    with pytest.raises(eac.ParameterError, match="must not be negative"):
        handle.instantiate(ranges="valid", keep_clear=-1e-3)
    with pytest.raises(eac.ParameterError, match="one turn"):
        lib["LeverHandle"].instantiate(ranges="valid", throw=7.0)
    # a signed offset may leave its typical range either way: a 2 m fridge, handle 700 mm down
    fridge = lib["Refrigerator"].instantiate(ranges="valid", size=(0.6, 2.0, 0.65), handle_y=-0.7)
    assert fridge.params["handle_y"] == -0.7


def test_requirements_still_hold_under_valid(lib) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(eac.RequirementError, match="the bar needs material"):
        lib["CurveHandle"].instantiate(ranges="valid", r_in=0.05, r_out=0.04)


def test_an_empty_grasp_range_is_refused(lib) -> None:  # type: ignore[no-untyped-def]
    """A 1 m door with its handle at 950 mm leaves no room above the handle to push: the grasp
    push_edge's range is empty, which the typical ranges never reach."""
    with pytest.raises(eac.ParameterError, match="range of grasp push_edge") as err:
        lib["RoomDoor"].instantiate(ranges="valid", size=(0.86, 1.0, 0.04), handle_height=0.95)
    assert not isinstance(err.value, eac.RequirementError)


def test_a_malformed_shape_is_refused(lib) -> None:  # type: ignore[no-untyped-def]
    """A 100 mm casement with 60 mm frames: the frame's opening would be -20 mm wide."""
    with pytest.raises(ShapeError, match="outer"):
        lib["CasementWindow"].instantiate(ranges="valid", size=(0.1, 1.1))


SLIDER = """use primitives.{Cuboid}

/// A plate on a rail whose travel is what is left of the rail after 50 mm.
concept Slider {
    param rail : length in [60mm, 200mm] = 100mm
    shape base_plate = Cuboid(size: (rail, 20mm, 10mm))
    link carriage {
        shape block = Cuboid(size: (20mm, 20mm, 20mm)) at trans(0, 0, 15mm)
        grasp top = trans(0, 0, 25mm) * roty(180deg) width 20mm
    }
    joint slide : prismatic(base -> carriage) axis (1, 0, 0) range [0, rail - 50mm]
    action push_along = push along slide using top
}
"""


def test_an_empty_joint_range_is_refused(tmp_path) -> None:  # type: ignore[no-untyped-def]
    src = tmp_path / "slider.eac"
    src.write_text(SLIDER)
    slider = eac.compile_paths([src])["Slider"]
    assert slider.instantiate(ranges="valid", rail=0.05).joint_limits()["slide"] == (0.0, 0.0)
    with pytest.raises(eac.ParameterError, match="range of joint slide is empty"):
        slider.instantiate(ranges="valid", rail=0.04)


def test_unknown_ranges_mode(lib) -> None:  # type: ignore[no-untyped-def]
    for bad in ("all", None, 1, True):
        with pytest.raises(eac.ParameterError, match='"typical" or "valid"'):
            lib["RoundKnob"].instantiate(ranges=bad)


@pytest.mark.parametrize("name", ["Safe", "SlidingWindow", "Toilet", "RoomDoor", "CabinetDrawer"])
def test_typical_values_give_the_same_instance_either_way(lib, name: str) -> None:  # type: ignore[no-untyped-def]
    """Inside the typical ranges ``valid`` accepts exactly what ``typical`` accepts."""
    concept = lib[name]
    rng = np.random.default_rng(11)
    compared = 0
    for _ in range(100):
        values = draw_params(concept, rng)
        try:
            a = concept.instantiate(params=values)
        except eac.RequirementError:
            with pytest.raises(eac.RequirementError):
                concept.instantiate(params=values, ranges="valid")
            continue
        assert concept.instantiate(params=values, ranges="valid") == a
        compared += 1
    assert compared >= 10


def test_valid_values_are_not_verified_typical_ones_are(lib) -> None:  # type: ignore[no-untyped-def]
    """Sampling stays inside the typical ranges: ``draw_params`` never leaves them."""
    concept = lib["SlidingWindow"]
    rng = np.random.default_rng(0)
    for _ in range(50):
        values = draw_params(concept, rng)
        for p in concept.params:
            if p.kind in ("num", "vec"):
                v, lo, hi = (
                    np.atleast_1d(np.asarray(x, float)) for x in (values[p.name], p.lo, p.hi)
                )
                assert np.all(v >= lo) and np.all(v <= hi)
