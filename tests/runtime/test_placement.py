"""Placement parameters of the library: where a handle sits and which way a part moves are
parameters whose defaults keep the earlier geometry (expected values derived by hand from the
concepts' text)."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac


def test_sliding_window_default_is_the_left_opening_sash(lib) -> None:  # type: ignore[no-untyped-def]
    """Default (1200 x 1000 mm, 60 mm frame, 30 mm sash): the sash is w = 550 mm wide, centred at
    cx = 265 mm; its pull 40 mm in from the right edge is at x = 500 mm, its hook 5.25 mm left of
    the pull's centre (the 30 mm pocket's right wall after the 180deg turn), 1 mm off the 10 mm
    pocket's back: z = 30 + 2 - 10 + 1 = 23 mm. Opening slides it left over 510 mm."""
    inst = lib["SlidingWindow"].instantiate()
    g = inst.grasp("handle.pull")
    np.testing.assert_allclose(g[:3, 3], [0.49475, 0.0, 0.023], atol=1e-12)
    np.testing.assert_allclose(inst.force("open", grasp=g), [-1.0, 0.0, 0.0], atol=1e-12)
    assert inst.joint_limits()["track"] == pytest.approx((0.0, 0.51))


def test_sliding_window_opening_right_is_the_mirror_image(lib) -> None:  # type: ignore[no-untyped-def]
    window = lib["SlidingWindow"]
    left, right = window.instantiate(), window.instantiate(opens_to="right")
    mirror = np.diag([-1.0, 1.0, 1.0])
    for grasp in ("handle.pull", "handle.pull_back"):
        np.testing.assert_allclose(
            right.grasp(grasp)[:3, 3], mirror @ left.grasp(grasp)[:3, 3], atol=1e-12
        )
    g = right.grasp("handle.pull")
    np.testing.assert_allclose(right.force("open", grasp=g), [1.0, 0.0, 0.0], atol=1e-12)
    path = right.follow("open", grasp=g, to=0.3, steps=4)
    np.testing.assert_allclose(path[-1][:3, 3] - g[:3, 3], [0.3, 0.0, 0.0], atol=1e-12)
    # the shapes are mirrored too: the sash's glass is where the left sash's is, mirrored
    probe = np.array([[0.3, 0.0, 0.017], [-0.3, 0.0, 0.017]])
    np.testing.assert_allclose(right.sdf(probe), left.sdf(probe[::-1]), atol=1e-9)


def test_sliding_window_pull_placement(lib) -> None:  # type: ignore[no-untyped-def]
    base = lib["SlidingWindow"].instantiate().grasp("handle.pull")[:3, 3]
    moved = lib["SlidingWindow"].instantiate(pull_at=0.1, pull_y=0.2)
    np.testing.assert_allclose(
        moved.grasp("handle.pull")[:3, 3], base + [-0.06, 0.2, 0.0], atol=1e-12
    )
    assert moved.joint_limits()["track"] == pytest.approx((0.0, 0.45))
    with pytest.raises(eac.RequirementError, match="the pull fits on the sash"):
        lib["SlidingWindow"].instantiate(size=(1.2, 0.5), pull_y=0.2)


def test_safe_lever_hub_and_side(lib) -> None:  # type: ignore[no-untyped-def]
    """Default safe (420 x 380 x 380 mm, 50 mm door): the lever's hub on the centre line, a
    sixth of the height below the middle; `hold` 30 mm short of the 130 mm lever's tip, at the
    lever's 60 mm reach in front of the door: (0.1, -0.38 / 6, 0.19 + 0.05 + 0.06)."""
    safe = lib["Safe"]
    hold = safe.instantiate().grasp("handle.hold")[:3, 3]
    np.testing.assert_allclose(hold, [0.1, -0.38 / 6, 0.3], atol=1e-12)
    shifted = safe.instantiate(handle_x=0.05).grasp("handle.hold")[:3, 3]
    np.testing.assert_allclose(shifted, hold + [0.05, 0.0, 0.0], atol=1e-12)
    left = safe.instantiate(**{"handle.hand": "left"}).grasp("handle.hold")[:3, 3]
    np.testing.assert_allclose(left, [-0.1, -0.38 / 6, 0.3], atol=1e-12)
    with pytest.raises(eac.RequirementError, match="the lever stays on the door"):
        safe.instantiate(handle_x=0.1)


@pytest.mark.parametrize(
    ("name", "param", "default", "grasp", "axis", "sign"),
    [
        ("Microwave", "handle_inset", 0.035, "handle.pull", 0, -1.0),
        ("HingedCabinet", "handle_inset", 0.040, "handle.pull", 0, -1.0),
        ("Refrigerator", "handle_inset", 0.045, "handle.pull", 0, 1.0),  # hinged on the right
        ("CasementWindow", "handle_inset", 0.030, "handle.hold", 0, -1.0),
        ("Oven", "handle_drop", 0.050, "handle.pull", 1, -1.0),
        ("CabinetDrawer", "handle_y", 0.0, "handle.pull", 1, 1.0),
    ],
)
def test_handle_placements_move_the_grasp(lib, name, param, default, grasp, axis, sign) -> None:  # type: ignore[no-untyped-def]
    """Moving the handle 10 mm further from its edge (or up) moves its grasp by 10 mm along x
    (or y), towards the door's inside, and leaves the default where it was."""
    concept = lib[name]
    assert concept.defaults()[param] == pytest.approx(default)
    before = concept.instantiate().grasp(grasp)
    after = concept.instantiate(**{param: default + 0.01}).grasp(grasp)
    step = np.zeros(3)
    step[axis] = sign * 0.01
    np.testing.assert_allclose(after[:3, 3] - before[:3, 3], step, atol=1e-12)
    np.testing.assert_allclose(after[:3, :3], before[:3, :3], atol=1e-12)
