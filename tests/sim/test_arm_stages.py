"""Staged arm actions: a plan that stops short of the task's end is executed to there, the
hand lets go, and the next stage is planned from the measured state (same base)."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.robot.placement import plan_placed
from grace_dsl.sim.arm_episode import (
    CLOSE_ENOUGH,
    _interleave,
    execute_stages,
    panda,
    robot_base,
)
from grace_dsl.sim.episode import Z_UP
from grace_dsl.sim.protocol import task_action


def test_interleave_alternates_scored_and_fixed_bases_without_repeats() -> None:
    poses = [np.eye(4) for _ in range(4)]
    for k, pose in enumerate(poses):
        pose[0, 3] = k
    scored, fixed = [poses[2], poses[0]], [poses[0], poses[1], poses[3]]
    out = _interleave(scored, fixed, 4)
    assert [float(p[0, 3]) for p in out] == [2.0, 0.0, 1.0, 3.0]
    assert len(_interleave(scored, fixed, 2)) == 2


@pytest.mark.slow
def test_a_close_cut_short_is_finished_by_a_second_stage(lib) -> None:  # type: ignore[no-untyped-def]
    """A door 1.2 rad open and a first plan that closes it only to 0.6 rad: a second plan,
    from where the arm backed off, closes it."""
    concept = lib["HingedCabinet"]
    inst = concept.instantiate(pose=Z_UP, joints={"hinge": 1.2})
    task = task_action(concept, "close")
    robot = panda()
    base = robot_base(robot, inst, "close")
    first = plan_placed(robot, inst, "close", 0.6, base=base, seed=0).plan
    assert first.to == pytest.approx(0.6)
    staged = execute_stages(inst, task, first, 20.0, seed=0)
    lo, hi = inst.joint_limits()["hinge"]
    assert not staged.unplanned and len(staged.options) == 2
    assert staged.outcome.q_final <= lo + max(CLOSE_ENOUGH, 0.05) * (hi - lo)
