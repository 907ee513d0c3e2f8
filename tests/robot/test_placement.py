"""The base placement search: seeded, deterministic, facing the object; and the self-motion that
keeps a tracked arm away from its joint limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.robot.act import RELAX_STEP, ActionPlanningError, _relax
from grace_dsl.robot.collision import collision_scene
from grace_dsl.robot.ik import IKOptions
from grace_dsl.robot.model import Robot
from grace_dsl.robot.placement import (
    PATH_SAMPLES,
    SHIFTS,
    _grasp_centre,
    base_pose,
    default_instance,
    hand_paths,
    path_bases,
    placements,
    plan_placed,
    reach_score,
)
from tests.robot.test_grasp_ik import facing


def test_placements_are_seeded_deterministic_and_face_the_grasps(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = default_instance(panda, lib["Oven"], "open")
    start = base_pose(0.02, -0.01, 0.1)
    a = placements(inst, "open", start, seed=3)
    b = placements(inst, "open", start, seed=3)
    c = placements(inst, "open", start, seed=4)
    assert len(a) == 1 + len(SHIFTS)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.allclose(x, y) for x, y in zip(a[1:], c[1:]))
    np.testing.assert_array_equal(a[0], start)  # the given base comes first, unchanged
    centre = np.append(_grasp_centre(inst, "open"), 1.0)
    for pose in a[1:]:  # every other one is a rigid floor pose turned toward the grasps
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-12)
        assert pose[2, 3] == pytest.approx(0.0) and pose[2, 2] == pytest.approx(1.0)
        seen = np.linalg.inv(pose) @ centre
        assert seen[0] > 0.3 and abs(math.atan2(seen[1], seen[0])) < 1e-9
    moved = [np.linalg.norm(p[:2, 3] - start[:2, 3]) for p in a[1:]]
    assert min(moved) > 0.05 and max(moved) < 0.3
    assert len(placements(inst, "open", None, seed=0, count=2)) == 2


def test_no_placement_that_works_is_a_typed_error(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    far = lib["SunkenDoor"].instantiate(pose=facing(2.5, 0.0, 0.45))
    with pytest.raises(eac.GraceError, match="no usable grasp|out of reach"):
        plan_placed(panda, far, "open", 0.3, count=2)


def test_self_motion_leaves_the_hand_and_moves_away_from_the_limits(panda: Robot) -> None:
    """From a posture with joints near their limits, one relaxation step keeps the gripper on its
    pose (IK tolerance, independent FK) and brings the joints toward the middle of their ranges."""
    rng = np.random.default_rng(5)
    middle, half = (panda.upper + panda.lower) / 2, (panda.upper - panda.lower) / 2
    improved = 0
    for _ in range(10):
        q = np.clip(
            middle + half * rng.uniform(0.75, 0.95, 7) * rng.choice([-1, 1], 7),
            panda.lower,
            panda.upper,
        )
        pose = panda.fk(q)
        out = _relax(panda, pose, q, q, IKOptions(max_restarts=0))
        hand = panda.fk(out)
        assert np.linalg.norm(hand[:3, 3] - pose[:3, 3]) <= 1e-3
        assert np.max(np.abs(out - q)) <= RELAX_STEP + 0.05  # a small move, no jump
        before = np.sum(((q - middle) / half) ** 2)
        after = np.sum(((out - middle) / half) ** 2)
        assert after <= before + 1e-6
        improved += after < before - 1e-3
    assert improved >= 7


def _wide_open_door(lib):  # type: ignore[no-untyped-def]
    from grace_dsl.sim.episode import Z_UP

    inst = lib["DoorLeaf"].instantiate(pose=Z_UP)
    return inst.with_joints({"hinge": inst.joint_limits()["hinge"][1]})


def test_reach_score_is_the_tracked_fraction_of_the_path(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = _wide_open_door(lib)
    path = hand_paths(inst, "close", 0.0)[0]
    assert path.shape == (PATH_SAMPLES, 4, 4)
    far = base_pose(5.0, 0.0, math.pi)
    assert reach_score(panda, path, far) == 0.0
    # a base at the path's start, facing it, reaches the start but not the whole swing
    start = path[0, :3, 3]
    near = base_pose(float(start[0]) + 0.55, float(start[1]), math.pi)
    near[2, 3] = float(start[2]) - 0.5
    score = reach_score(panda, path, near)
    assert 0.0 < score <= 1.0
    assert score in {k / PATH_SAMPLES for k in range(1, PATH_SAMPLES + 1)}


@pytest.mark.slow
def test_path_bases_put_the_best_reach_first(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    from grace_dsl.sim.arm_episode import robot_base

    inst = _wide_open_door(lib)
    first = robot_base(panda, inst, "close")
    bases = path_bases(panda, inst, "close", 0.0, first)
    again = path_bases(panda, inst, "close", 0.0, first)
    assert len(bases) > 1 and all(np.array_equal(a, b) for a, b in zip(bases, again))
    paths = hand_paths(inst, "close", 0.0)
    scores = [max(reach_score(panda, p, b) for p in paths) for b in bases]
    assert scores[0] == max(scores)
    assert scores[0] > max(reach_score(panda, p, first) for p in paths)
    for b in bases:  # the arm at home stands clear of the open door
        assert not collision_scene(panda, inst, base=b).collides(panda.home)


@pytest.mark.slow
def test_plan_placed_names_the_base_that_got_furthest(panda: Robot, lib) -> None:  # type: ignore[no-untyped-def]
    inst = _wide_open_door(lib)
    from grace_dsl.sim.arm_episode import robot_base

    first = robot_base(panda, inst, "close")
    with pytest.raises(ActionPlanningError) as caught:
        plan_placed(panda, inst, "close", 0.0, poses=[first], count=1)
    assert caught.value.base is not None
    np.testing.assert_array_equal(caught.value.base, first)
    assert caught.value.value is None or caught.value.value < inst.joints["hinge"]
