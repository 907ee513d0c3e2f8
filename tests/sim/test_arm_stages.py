"""Staged arm actions: a plan that stops short of the task's end is executed to there, the
hand lets go, and the next stage is planned from the measured state (same base)."""

from __future__ import annotations

import numpy as np
import pytest

from grace_dsl.robot.placement import plan_placed
from grace_dsl.sim import arm_episode
from grace_dsl.sim.arm_episode import (
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
def test_a_close_cut_short_is_taken_further_by_a_second_stage(lib, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A door 1.2 rad open and a first plan that closes it only to 0.6 rad: the second stage,
    planned from the measured joint value with the arm where it backed off, closes it further
    (two stages here, so that the test does not wait for a third plan)."""
    monkeypatch.setattr(arm_episode, "STAGES", 2)
    concept = lib["HingedCabinet"]
    inst = concept.instantiate(pose=Z_UP, joints={"hinge": 1.2})
    task = task_action(concept, "close")
    robot = panda()
    base = robot_base(robot, inst, "close")
    first = plan_placed(robot, inst, "close", 0.6, base=base, seed=0).plan
    assert first.to == pytest.approx(0.6)
    staged = execute_stages(inst, task, first, 20.0, seed=0)
    assert staged.outcome.arrived and not staged.outcome.slipped
    assert len(staged.options) == 2  # the second stage was planned and executed
    assert staged.outcome.q_final < 0.6 - 0.05  # past where the first plan ended


@pytest.mark.slow
def test_a_later_stage_places_the_base_for_the_rest_of_the_path(lib) -> None:  # type: ignore[no-untyped-def]
    """A refrigerator door closed from wide open to 0.63 rad by a first stage: from the base
    placed for the whole close, IK tracks under half of the rest of the path (the workspace's
    edge); the base placed for the rest (what ``next_stage`` plans from when the old base
    cannot) stands elsewhere and IK tracks all of it."""
    from grace_dsl.robot.placement import hand_paths, path_bases, reach_score

    robot = panda()
    inst = lib["Refrigerator"].instantiate(pose=Z_UP)
    wide = inst.with_joints({"hinge": inst.joint_limits()["hinge"][1]})
    first = path_bases(robot, wide, "close", 0.0, robot_base(robot, wide, "close"))[0]
    rest = inst.with_joints({"hinge": 0.63})
    paths = hand_paths(rest, "close", 0.0)
    chosen = path_bases(robot, rest, "close", 0.0, robot_base(robot, rest, "close"))[0]
    assert float(np.linalg.norm(chosen[:2, 3] - first[:2, 3])) > 0.3
    assert max(reach_score(robot, p, first) for p in paths) < 0.5
    assert max(reach_score(robot, p, chosen) for p in paths) == 1.0


def test_a_short_stage_that_finishes_the_task_is_worth_planning() -> None:
    """A stage shorter than ``MIN_STAGE`` is refused unless it ends where the task is done:
    Laptop close seed 1 (0.18 rad left after stage 1, the fingers touching the base in the last
    0.004 rad) planned a stage to 0.013 rad only with this."""
    from grace_dsl.sim.arm_episode import CLOSE_ENOUGH, OPEN_ENOUGH, _finishes
    from grace_dsl.sim.protocol import TaskAction

    close, open_ = TaskAction("close", "hinge", -1.0), TaskAction("open", "hinge", 1.0)
    lo, hi = 0.0, 2.356
    assert _finishes(close, 0.013, lo, hi) and not _finishes(close, 0.2, lo, hi)
    assert _finishes(close, CLOSE_ENOUGH * hi, lo, hi)
    assert _finishes(open_, OPEN_ENOUGH * hi + 1e-9, lo, hi) and not _finishes(open_, 1.0, lo, hi)


@pytest.mark.slow
def test_a_door_brushed_on_the_way_in_is_taken_again_from_where_it_stopped() -> None:
    """DoorLeaf close, seed 14: the arm brushes the wide-open leaf on its way to the grasp and
    closes it from 1.92 to 1.59 rad without arriving; that used to end the episode
    (``collision``). The part moved, so the next stage is planned from where it stands."""
    from grace_dsl.sim import run_episode
    from grace_dsl.sim.records import EpisodeConfig

    record = run_episode(EpisodeConfig("DoorLeaf", "close", agent="arm"), 14)
    assert record.strict, (record.reason, record.detail, record.q_final)
    assert len(record.bases) >= 2  # a second stage ran
