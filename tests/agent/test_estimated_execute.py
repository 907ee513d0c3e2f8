"""Estimated mode's execution on a model that is an estimate: the path follows the measured
joint's motion from the grasp (not the estimate's zero) and goes on past the estimated range
while the joint still moves (a closed drawer's travel is in no view)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from grace_dsl.agent.estimated import with_joints_clipped
from grace_dsl.agent.estimated_episode import PARKED, beyond
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.episode import execute, start_episode
from grace_dsl.sim.protocol import strict_success
from grace_dsl.sim.records import EpisodeConfig
from grace_dsl.sim.world import World


def _run(task: str, seed: int, believed_of: object, fixed: bool) -> tuple[bool, float, float]:
    """The CabinetDrawer episode ``seed`` of ``task`` with the hand acting on
    ``believed_of(true)`` in the true world; ``fixed``: with the estimated-mode execution."""
    config = EpisodeConfig("CabinetDrawer", task)  # type: ignore[arg-type]
    start = start_episode(config, seed, time.perf_counter())
    assert not isinstance(start, type(None)) and hasattr(start, "inst")
    true, act = start.inst, start.task  # type: ignore[union-attr]
    believed: Instance = believed_of(true)  # type: ignore[operator]
    gripper = Gripper.load(config.hand)
    option = next(o for o in believed.rank(act.action, gripper=gripper) if o.feasible)
    parked = np.eye(4)
    parked[:3, 3] = PARKED
    world = World.build(true, gripper, parked, driven=act.joint)
    extra = {"relative": True, "beyond": beyond(believed, act.joint, act.sign)} if fixed else {}
    out = execute(believed, act, option, gripper, config.max_seconds, world=world, **extra)
    lo, hi = true.joint_limits()[act.joint]
    return strict_success(task, out.q_final, lo, hi), out.q_final, hi  # type: ignore[arg-type]


def _short_travel(true: Instance) -> Instance:
    """The true drawer with its travel estimated at the concept's least (what no view of a
    closed drawer can correct)."""
    params = dict(true.params) | {"travel": 0.2}
    inst = true.concept.instantiate(params=params, pose=true.pose)
    return with_joints_clipped(inst, dict(true.joints))


@pytest.mark.slow  # two physical episodes (about 10 s)
def test_a_drawers_open_goes_on_past_the_estimated_travel() -> None:
    """CabinetDrawer open seed 3: its travel (538 mm) estimated at 200 mm. The old path
    stopped at 85 % of the estimate (under half the real travel); now it follows the drawer
    until it stops."""
    ok, q, hi = _run("open", 3, _short_travel, fixed=True)
    assert ok and q > 0.5 * hi, q
    old, q_old, _ = _run("open", 3, _short_travel, fixed=False)
    assert not old and q_old < q, (q_old, q)


def _shifted(true: Instance, by: float = 0.04) -> Instance:
    """The drawer estimated ``by`` m less open, its body ``by`` m further out: the seen front
    and handle are where they are, only the joint's zero is off (CabinetDrawer close seed 3)."""
    joint = next(iter(true.joints))
    pose = np.array(true.pose, float)
    pose[:3, 3] += pose[:3, 2] * by  # the concept's +z is its front's outward normal
    joints = {joint: float(true.joints[joint]) - by}
    return true.concept.instantiate(params=dict(true.params), pose=pose, joints=joints)


@pytest.mark.slow  # two physical episodes (about 10 s)
def test_a_close_follows_the_joints_motion_not_the_estimates_zero() -> None:
    ok, q, _ = _run("close", 3, _shifted, fixed=True)
    assert ok, q
    old, q_old, _ = _run("close", 3, _shifted, fixed=False)
    assert not old and q_old > q, (q_old, q)
