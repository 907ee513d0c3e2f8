"""``rank``'s shortcuts change nothing: the forces of all poses from one batched evaluation judge
each contact as the per-pose ``inst.force`` does (twists on a joint's axis included), and a
scene shared between rank calls on one instance gives the same signed distances as a fresh one."""

from __future__ import annotations

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.runtime.contact import Scene
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.manipulation import _contact, _contacts, _poses

# a pinch and a hook on a hinge, pushes on a slide, a twist on a dial's axis, a lever
CASES = ("HingedCabinet", "CabinetDrawer", "RotaryDial", "KitchenMixer", "SlidingWindow")


@pytest.fixture(scope="module")
def lib() -> eac.Library:
    return eac.load_library()


def _pose() -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = np.column_stack([[0, -1, 0], [0, 0, 1], [-1, 0, 0]])
    m[:3, 3] = (1.0, 0.2, 0.8)
    return m


@pytest.mark.parametrize("name", CASES)
def test_batched_forces_judge_every_pose_as_one_at_a_time(lib: eac.Library, name: str) -> None:
    c = lib[name]
    inst = c.instantiate(pose=_pose())
    limits = inst.joint_limits().items()
    half = inst.with_joints(
        {j: (lo + hi) / 2 if np.isfinite(hi - lo) else 0.3 for j, (lo, hi) in limits}
    )
    for hand in (Gripper.panda(), Gripper.load("topdown"), Gripper.load("pusher")):
        for state in (inst, half):
            for action in c.actions:
                spec = state._action_spec(action)
                for grasp in c.grasps:
                    if not state.grasp_applies(grasp):  # rank judges no pose of it here
                        continue
                    mode = c.grasps[grasp].mode
                    poses = _poses(state, grasp, 6, None).poses
                    ok, first = _contacts(state, spec, mode, poses, hand)
                    one = [_contact(state, spec, mode, p, hand) for p in poses]
                    assert ok.tolist() == [w is None for w in one], (name, action, grasp)
                    assert first == one[0]


def test_a_shared_scene_is_the_instance_s_own(lib: eac.Library) -> None:
    inst = lib["HingedCabinet"].instantiate(pose=_pose(), joints={"hinge": 0.7})
    shared = Scene.of(inst)
    assert Scene.of(inst) is shared
    assert Scene.of(inst.with_joints({"hinge": 0.2})) is not shared
    rng = np.random.default_rng(0)
    pts = inst.pose[:3, 3] + rng.uniform(-0.5, 0.5, (200, 3))
    qs = np.array([inst.q, [0.1], [1.2]])
    got = shared.sdf([pts, pts, pts], qs)
    want = Scene(inst).sdf([pts, pts, pts], qs)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    np.testing.assert_allclose(got[0], inst.sdf(pts), atol=1e-9)
