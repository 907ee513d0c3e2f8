"""Whole actions: the planned trajectory does what the concept says, within limits, continuously."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.act import FINGER_ALLOWANCE, FINGERS, ActionPlanningError, plan_action
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.robot.plan import DEFAULT_ACCELERATION
from tests.robot.test_grasp_ik import facing
from tests.robot.test_model import urdf_chain_fk
from tests.robot.test_timing import differenced

RECHECK = 0.004  # radians between re-checked configurations: finer than the planner's 0.01


@pytest.fixture(scope="module")
def panda() -> Robot:
    return eac.Robot.panda()


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


@pytest.fixture(scope="module")
def door_plan(panda: Robot, lib):  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(0.7, 0.0, 0.45))
    return door, plan_action(panda, door, "open", to=0.6)


@pytest.mark.slow
def test_opening_a_door_follows_its_arc(door_plan) -> None:  # type: ignore[no-untyped-def]
    door, plan = door_plan
    assert [name for name, *_ in plan.phases] == ["approach", "insert", "interact", "retreat"]
    # The hand during the interaction is on the door's analytic path (independent FK).
    path = door.follow("open", grasp=plan.choice.ik.grasp_pose, to=0.6, steps=200)
    hand = np.array([urdf_chain_fk(q)[:3, 3] for q in plan.phase("interact")])
    gaps = np.min(np.linalg.norm(hand[:, None] - path[None, :, :3, 3], axis=2), axis=1)
    assert gaps.max() <= 2e-3
    assert np.linalg.norm(hand[-1] - path[-1][:3, 3]) <= 1e-3  # it ends where the door is open
    # ... and the door's hinge turns with it: the hand's angle about the hinge is the hinge's.
    start, stop = plan.span("interact")
    inside = (plan.t >= start) & (plan.t <= stop)
    values = plan.joint_values[inside]
    assert values[0] == 0.0 and values[-1] == pytest.approx(0.6) and np.all(np.diff(values) >= 0)
    # A pinch closes on the handle for the interaction and opens before backing out.
    widths = [w for _, w in plan.gripper]
    assert plan.choice.option.mode != "pinch" or widths == [0.08, 0.0, 0.08]
    assert [t for t, _ in plan.gripper] == sorted(t for t, _ in plan.gripper)


@pytest.mark.slow
def test_the_whole_trajectory_is_free_and_within_limits(panda: Robot, door_plan) -> None:  # type: ignore[no-untyped-def]
    door, plan = door_plan
    assert np.all(plan.q >= panda.lower) and np.all(plan.q <= panda.upper)
    assert plan.t[0] == 0 and np.all(np.diff(plan.t) > 0)
    vel, acc = differenced(plan.q, plan.t)
    assert np.all(np.abs(vel) <= panda.velocity_limit * (1 + 1e-9))
    assert np.all(np.abs(acc) <= DEFAULT_ACCELERATION * (1 + 1e-9))
    # Re-checked densely with fresh scenes: the arm (fingers aside) touches nothing at all, the
    # door posed at its joint value; the fingers press into the held leaf by no more than the
    # allowance, and touch nothing else.
    arm = collision_scene(panda, door, ignore=FINGERS)
    link = door.concept.grasps[plan.choice.option.grasp].link
    fingers = collision_scene(
        panda, door, touching=[(f, link) for f in FINGERS], allowance=FINGER_ALLOWANCE
    )
    strict = collision_scene(panda, door)
    approach_end = plan.phases[0][2]
    for k in range(len(plan.q) - 1):
        a, b = plan.q[k], plan.q[k + 1]
        va, vb = plan.joint_values[k], plan.joint_values[k + 1]
        n = max(1, int(np.ceil(max(np.max(np.abs(b - a)), abs(vb - va)) / RECHECK)))
        for w in np.linspace(0.0, 1.0, n + 1):
            q, opened = a + w * (b - a), door.with_joints(hinge=va + w * (vb - va))
            for scene in (arm, fingers, strict):
                scene.place(opened)
            assert not arm.collides(q), (k, w)
            if k + 1 < approach_end:  # on the way in, nothing may touch the door at all
                assert not strict.collides(q), (k, w)
            else:
                assert not fingers.collides(q), (k, w)


@pytest.mark.slow
def test_a_door_that_swings_into_the_arm_is_a_collision(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(0.45, 0.0, 0.45))
    with pytest.raises(ActionPlanningError, match="touches object/leaf") as info:
        plan_action(panda, door, "open", to=1.2)
    failure = info.value
    assert failure.reason == "collision" and failure.phase == "following the action"
    assert failure.value is not None and 0.0 < failure.value < 1.2
    # A smaller opening, short of where the leaf meets the arm, is planned.
    plan = plan_action(panda, door, "open", to=0.9 * failure.value)
    assert plan.joint_values.max() == pytest.approx(0.9 * failure.value)


def test_a_door_out_of_reach_fails_with_a_reason(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    door = lib["SunkenDoor"].instantiate(pose=facing(2.5, 0.0, 0.45))
    with pytest.raises(eac.GraceError, match="no usable grasp|out of reach"):
        plan_action(panda, door, "open", to=0.6)
    assert issubclass(ActionPlanningError, eac.GraceError)
