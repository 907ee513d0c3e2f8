"""Whole actions: the planned trajectory does what the concept says, within limits, continuously."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.act import (
    CLOSED_CLEAR,
    FINGER_ALLOWANCE,
    FINGERS,
    FINGERTIP_REACH,
    ActionPlanningError,
    plan_action,
)
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.model import Robot
from grace_dsl.robot.placement import default_instance
from grace_dsl.robot.plan import DEFAULT_ACCELERATION
from tests.robot.test_grasp_ik import facing
from tests.robot.test_model import urdf_chain_fk
from tests.robot.test_timing import differenced

RECHECK = 0.004  # radians between re-checked configurations: finer than the planner's 0.01


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
    recheck(panda, door, plan)


def recheck(panda: Robot, inst, plan) -> None:  # type: ignore[no-untyped-def]
    """Re-checked densely with fresh scenes: the arm (fingers aside) touches nothing at all, the
    object posed at its joint value; the fingers press into the held link by no more than the
    allowance, and touch nothing else; on the way in (the approach), nothing touches at all."""
    arm = collision_scene(panda, inst, ignore=FINGERS)
    link = inst.concept.grasps[plan.choice.option.grasp].link
    fingers = collision_scene(
        panda, inst, touching=[(f, link) for f in FINGERS], allowance=FINGER_ALLOWANCE
    )
    strict = collision_scene(panda, inst)
    approach_end = plan.phases[0][2]
    for k in range(len(plan.q) - 1):
        a, b = plan.q[k], plan.q[k + 1]
        va, vb = plan.joint_values[k], plan.joint_values[k + 1]
        n = max(1, int(np.ceil(max(np.max(np.abs(b - a)), abs(vb - va)) / RECHECK)))
        for w in np.linspace(0.0, 1.0, n + 1):
            q, posed = a + w * (b - a), inst.with_joints({plan.joint: va + w * (vb - va)})
            for scene in (arm, fingers, strict):
                scene.place(posed)
            assert not arm.collides(q), (k, w)
            if k + 1 < approach_end:
                assert not strict.collides(q), (k, w)
            else:
                assert not fingers.collides(q), (k, w)


@pytest.fixture(scope="module")
def lid_plan(panda: Robot, lib):  # type: ignore[no-untyped-def]
    """A lid lifted by its front edge: the lower finger goes under a 15 mm overhang, which the
    finger pads reach past unless the hand stops short (the standoff)."""
    lid = default_instance(panda, lib["LidBox"], "open")
    return lid, plan_action(panda, lid, "open", to=0.6)


@pytest.mark.slow
def test_a_lid_is_lifted_to_its_target_on_its_arc(panda: Robot, lid_plan) -> None:  # type: ignore[no-untyped-def]
    lid, plan = lid_plan
    # the pads' ends on the lip, or just beyond them where the closed lower finger would touch
    # the body under the lip (act._standoff)
    assert 0.0 <= plan.standoff <= FINGERTIP_REACH + 2 * CLOSED_CLEAR
    start, stop = plan.span("interact")
    values = plan.joint_values[(plan.t >= start) & (plan.t <= stop)]
    assert values[-1] == pytest.approx(0.6) and np.all(np.diff(values) >= 0)
    # The hand (independent FK) follows the lid's analytic path, short by the standoff.
    path = lid.follow("open", grasp=plan.choice.ik.grasp_pose, to=0.6, steps=200)
    back = np.eye(4)
    back[2, 3] = -plan.standoff
    path = path @ back
    hand = np.array([urdf_chain_fk(q)[:3, 3] for q in plan.phase("interact")])
    gaps = np.min(np.linalg.norm(hand[:, None] - path[None, :, :3, 3], axis=2), axis=1)
    assert gaps.max() <= 2e-3
    assert np.linalg.norm(hand[-1] - path[-1][:3, 3]) <= 1e-3
    assert np.all(plan.q >= panda.lower) and np.all(plan.q <= panda.upper)
    recheck(panda, lid, plan)


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
