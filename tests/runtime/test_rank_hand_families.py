"""The bar hook's tilt out of the panel (``StraightHandle.hook``), for the hand that cannot
close (issue 13's other hands): the default pose is the old one, a tilt turns the hand about the
bar's axis and slides it on to just off the post, ``rank``'s search finds the tilt where the
pusher's flange clears a front the bar stands close to, the independent sweep of
``bench/bench_rank_agreement.py`` agrees, and ``eacc verify``'s checks hold over the range."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.verify import verify_concept
from grace_dsl.sim.episode import Z_UP

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_rank_agreement.py"


def agreement() -> ModuleType:
    """The independent check (shares nothing with rank's geometry)."""
    spec = importlib.util.spec_from_file_location("bench_rank_agreement", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def option(inst: eac.Instance, action: str, hand: str, grasp: str):  # type: ignore[no-untyped-def]
    return next(o for o in inst.rank(action, Gripper.load(hand)) if o.grasp == grasp)


def rot(axis: int, degrees: float) -> np.ndarray:
    """The right-handed rotation about x, y or z (axis 0, 1, 2)."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = (axis + 1) % 3, (axis + 2) % 3
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def shift(x: float, y: float, z: float) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def test_the_hook_at_tilt_zero_is_the_old_hook(lib: eac.Library) -> None:
    """The default pose is today's (the Panda's episodes do not change), and a tilt turns the
    hand about the bar's axis: every point keeps its distance to that axis."""
    inst = lib["StraightHandle"].instantiate()
    length, radius = inst.params["length"], inst.params["radius"]
    old = (
        shift(length / 2, 0, -radius - 0.00975)
        @ rot(2, -45)
        @ shift(-radius - 0.001, 0, 0)
        @ rot(1, 90)
        @ rot(2, 180)
    )
    np.testing.assert_allclose(inst.grasp("hook"), old, atol=1e-9)
    for degrees in (10.0, 20.0, 30.0):
        tilted = inst.grasp("hook", tilt=math.radians(degrees))
        turned = rot(0, degrees) @ old
        # turned about the bar's axis, then slid on along its own approach only
        np.testing.assert_allclose(tilted[:3, :3], turned[:3, :3], atol=1e-9)
        slide = tilted[:3, 3] - turned[:3, 3]
        assert 0 < slide @ turned[:3, 2] < 0.012
        np.testing.assert_allclose(slide, (slide @ turned[:3, 2]) * turned[:3, 2], atol=1e-9)
        # the fingers' side stays 1 mm behind the bar: the plane through the fingertips
        # normal to the grasp's +x is radius + 1 mm from the bar's axis
        side = -(tilted[:3, 3] - (tilted[:3, 3] @ [1, 0, 0]) * np.array([1, 0, 0])) @ tilted[:3, 0]
        assert side - 0.00875 == pytest.approx(radius + 0.001, abs=1e-6)
        # and the fingertips are off the right post again, by 1 mm + 6 mm sin(tilt)
        tip = tilted[:3, 3]
        gap = math.hypot(tip[0] - length / 2, tip[1]) - radius
        assert gap == pytest.approx(0.001 + 0.006 * math.sin(math.radians(degrees)), abs=3e-4)


def test_the_tilted_hook_passes_eacc_verify(lib: eac.Library) -> None:
    """near, penetration, power and follow over the tilt's range, for the hand that uses it."""
    report = verify_concept(lib["StraightHandle"], draws=4, seed=2, gripper=Gripper.load("pusher"))
    failed = [(f.check, f.member, f.message) for f in report.failures]
    assert report.ok, failed


def test_the_pusher_hooks_a_bar_close_to_the_front_by_tilting(lib: eac.Library) -> None:
    """A 32 mm stand-off: at tilt 0 the pusher's 60 mm flange meets the front (it needs about
    46 mm); rank's search finds a tilt where it clears, and the independent sweep agrees."""
    inst = lib["CabinetDrawer"].instantiate(pose=Z_UP, params={"handle.standoff": 0.032})
    hook = option(inst, "open", "pusher", "handle.hook")
    assert hook.feasible and hook.free["tilt"] > math.radians(10)
    hand = Gripper.load("pusher")
    assert agreement().check(inst, "open", hook, hand)[0] is None
    # the top-down hand still cannot: the hook comes in 45 deg off the vertical at any tilt
    assert not option(inst, "open", "topdown", "handle.hook").feasible
