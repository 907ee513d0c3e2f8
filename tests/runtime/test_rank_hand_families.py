"""Grasp families for the hands that cannot pinch or cannot turn (issue 13's other hands): the
bar hook's tilt out of the panel, the hooks over a drawer's top edge and behind a mirror door's
overhang, the push up under a lid. Each is judged by ``rank`` per draw; the checks here are the
physical cases the concepts' comments argue (where the hand fits and where it cannot), and the
independent sweep of ``bench/bench_rank_agreement.py`` agrees with rank's verdict."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.gripper import Gripper
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
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [k for k in range(3) if k != axis]
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
    tilted = inst.grasp("hook", tilt=math.radians(25))
    np.testing.assert_allclose(tilted, rot(0, 25) @ old, atol=1e-9)
    off_axis = np.linalg.norm(tilted[1:3, 3]), np.linalg.norm(old[1:3, 3])
    assert off_axis[0] == pytest.approx(off_axis[1])


@pytest.mark.slow
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


@pytest.mark.slow
@pytest.mark.parametrize("hand", ["pusher", "topdown"])
def test_a_drawer_ajar_is_hooked_over_its_top_edge_a_shut_one_is_not(
    lib: eac.Library, hand: str
) -> None:
    shut = lib["CabinetDrawer"].instantiate(pose=Z_UP, joints={"slide": 0.0})
    why = option(shut, "open", hand, "hook_top").reasons
    assert why and "enters the part" in why[0]  # behind the front is the carcass
    ajar = lib["CabinetDrawer"].instantiate(pose=Z_UP, joints={"slide": 0.12})
    hook = option(ajar, "open", hand, "hook_top")
    assert hook.feasible
    assert agreement().check(ajar, "open", hook, Gripper.load(hand))[0] is None


@pytest.mark.slow
def test_a_mirror_door_is_hooked_behind_its_overhang(lib: eac.Library) -> None:
    """No handle and nothing to pinch for the pusher: its fingers go behind the overhang."""
    inst = lib["MirrorCabinet"].instantiate(pose=Z_UP)
    options = [o for o in inst.rank("open", Gripper.load("pusher")) if o.feasible]
    assert options and options[0].grasp in ("hook_top", "hook_side")
    shut = lib["MirrorCabinet"].instantiate(pose=Z_UP, params={"hinge_side": "right"})
    assert option(shut, "open", "topdown", "hook_top").feasible  # the other side too


@pytest.mark.slow
def test_a_lid_is_pushed_up_under_its_overhang_a_shut_laptop_is_not(lib: eac.Library) -> None:
    box = lib["LidBox"].instantiate(pose=Z_UP, params={"lip": 0.02})
    lift = option(box, "open", "pusher", "lift_under")
    assert lift.feasible
    assert agreement().check(box, "open", lift, Gripper.load("pusher"))[0] is None
    # the top-down hand pushes only down: lifting a lid is beyond it
    assert not option(box, "open", "topdown", "lift_under").feasible
    shut = lib["Laptop"].instantiate(pose=Z_UP)  # a 2 mm lip: no room under it
    assert not option(shut, "open", "pusher", "lift_under").feasible
    ajar = lib["Laptop"].instantiate(pose=Z_UP, joints={"hinge": math.radians(30)})
    assert option(ajar, "open", "pusher", "lift_under").feasible
