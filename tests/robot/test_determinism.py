"""Budgets are counts, not times: a plan is the same on a quiet and on a loaded machine.

Each test slows the real collision checker down (a wrapper that spins before every check, as a
loaded machine would) and asserts the result is bit-identical to the fast run's: under the
former wall-clock budgets the slowed planner shortcut less, and the slowed IK gave up earlier.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import pytest

from grace_dsl.robot.act import plan_action
from grace_dsl.robot.collision import CollisionScene, collision_scene
from grace_dsl.robot.grasp_ik import solve_grasp_ik
from grace_dsl.robot.ik import IKOptions
from grace_dsl.robot.model import Robot
from grace_dsl.robot.plan import PlanningError, PlanningTimeout, plan_path
from grace_dsl.runtime.errors import ParameterError
from tests.robot.test_grasp_ik import facing


class Slowed:
    """A collision scene whose every check first spins ``delay`` seconds (busy, like a loaded
    core), then asks the real scene."""

    def __init__(self, scene: CollisionScene, delay: float) -> None:
        self.scene, self.delay, self.checks = scene, delay, 0
        self.robot = scene.robot

    def collides(self, q: Any) -> bool:
        self.checks += 1
        end = time.perf_counter() + self.delay
        while time.perf_counter() < end:
            pass
        return self.scene.collides(q)

    def contacts(self, q: Any) -> Any:
        return self.scene.contacts(q)


def _other_plan(panda: Robot, scene: CollisionScene) -> None:
    """A different problem planned in between: it draws from OMPL's generators."""
    start, goal = panda.home.copy(), panda.home.copy()
    start[0], goal[0] = 1.1, -1.0
    plan_path(scene, start, goal, seed=11)


@pytest.mark.slow
def test_a_plan_is_the_same_when_every_check_is_slow(panda: Robot, blocked) -> None:  # type: ignore[no-untyped-def]
    scene, start, goal = blocked
    fast = plan_path(scene, start, goal, seed=3)
    _other_plan(panda, scene)  # the process's history does not change the next plan either
    slow_scene = Slowed(scene, 2e-4)
    began = time.perf_counter()
    slow = plan_path(slow_scene, start, goal, seed=3)  # type: ignore[arg-type]
    assert slow_scene.checks > 500  # a real search: OMPL and the shortcutting ran slowed
    assert time.perf_counter() - began > slow_scene.checks * 2e-4
    assert fast.shape == slow.shape and np.array_equal(fast, slow)  # bit-identical


@pytest.mark.slow
def test_a_plan_depends_on_its_seed(panda: Robot, blocked) -> None:  # type: ignore[no-untyped-def]
    scene, start, goal = blocked
    a = plan_path(scene, start, goal, seed=3)
    b = plan_path(scene, start, goal, seed=4)
    assert a.shape != b.shape or not np.array_equal(a, b)
    again = plan_path(scene, start, goal, seed=4)
    assert np.array_equal(b, again)


def test_the_planners_budget_is_a_count_of_checks(panda: Robot, blocked) -> None:  # type: ignore[no-untyped-def]
    scene, start, goal = blocked
    counted = Slowed(scene, 0.0)
    with pytest.raises(PlanningError, match="no collision-free path found in 40 collision checks"):
        plan_path(counted, start, goal, checks=40, seed=3)  # type: ignore[arg-type]
    # the straight-segment test (start to goal, before OMPL) plus at most one planner iteration
    assert counted.checks < 400
    with pytest.raises(ParameterError, match="at least 1 check"):
        plan_path(scene, start, goal, checks=0)


def test_the_wall_clock_cap_is_a_typed_load_dependent_failure(panda: Robot, blocked) -> None:  # type: ignore[no-untyped-def]
    scene, start, goal = blocked
    with pytest.raises(PlanningTimeout, match="load-dependent"):
        plan_path(Slowed(scene, 1e-3), start, goal, seed=3, time_limit=0.05)  # type: ignore[arg-type]


def test_grasp_ik_is_the_same_when_every_check_is_slow(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    """A cabinet standing on the robot's base: every grasp posture of the drawer in front that
    converges is rejected by a collision check, so the search runs its whole budget of restarts
    however long the checks take (the former 0.5 s cap ended it after two slowed ones)."""
    inst = lib["CabinetDrawer"].instantiate(pose=facing(0.65, 0.0, 0.45))
    on_base = lib["CabinetDrawer"].instantiate(pose=facing(0.0, 0.0, 0.0))
    scene = collision_scene(
        panda, inst, ignore=("panda_leftfinger", "panda_rightfinger"), obstacles=[on_base]
    )
    assert scene.collides(panda.home)
    opts = IKOptions(max_restarts=8)
    fast = solve_grasp_ik(panda, inst, "handle.pull", scene=scene, seed=5, options=opts)
    slowed = Slowed(scene, 0.3)
    slow = solve_grasp_ik(panda, inst, "handle.pull", scene=slowed, seed=5, options=opts)  # type: ignore[arg-type]
    assert fast.reason == slow.reason == "collision"
    assert slowed.checks >= 2 and slow.seconds > 0.6  # longer than the former 0.5 s cap
    assert fast.restarts == slow.restarts == 8 and fast.iterations == slow.iterations
    assert np.array_equal(fast.q, slow.q) and fast.free == slow.free


@pytest.mark.slow
def test_a_whole_action_plan_is_the_same_when_every_check_is_slow(
    panda: Robot, lib, monkeypatch: pytest.MonkeyPatch
) -> None:  # type: ignore[no-untyped-def]
    """``plan_action`` (grasp choice by IK with collision checks, the tracked phases, the
    approach, the timing) twice, the second time with every collision check of every scene
    slowed: the trajectories are bit-identical. (The approach is a free straight segment here;
    the OMPL search under slowed checks is the first test's.)"""
    door = lib["SunkenDoor"].instantiate(pose=facing(0.7, 0.0, 0.45))
    fast = plan_action(panda, door, "open", to=0.6, seed=2)
    real = CollisionScene.collides
    calls = [0]

    def slowed(self: CollisionScene, q: Any) -> bool:
        calls[0] += 1
        end = time.perf_counter() + 1e-4
        while time.perf_counter() < end:
            pass
        return real(self, q)

    monkeypatch.setattr(CollisionScene, "collides", slowed)
    slow = plan_action(panda, door, "open", to=0.6, seed=2)
    assert calls[0] > 1000
    assert fast.phases == slow.phases
    assert np.array_equal(fast.q, slow.q) and np.array_equal(fast.t, slow.t)
    assert np.array_equal(fast.joint_values, slow.joint_values)
