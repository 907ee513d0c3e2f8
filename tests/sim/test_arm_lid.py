"""The full Panda on lids (Laptop, LidBox): the side edges' pinch, rank judged part of the way,
the fingers closed on a lid's lip in the plan, and a real episode."""

from __future__ import annotations

import pytest

from grace_dsl.robot.choose import NoGraspError, grasp_candidates
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.sim.arm_episode import panda, robot_base
from grace_dsl.sim.episode import Z_UP, start_episode
from grace_dsl.sim.records import EpisodeConfig

SIDES = ("left.pinch", "right.pinch")
FRONT = ("edge.pinch", "edge.push_face")


@pytest.mark.parametrize("name", ["Laptop", "LidBox"])
def test_a_wide_open_lid_is_pinched_by_its_side_edges(lib, name: str) -> None:  # type: ignore[no-untyped-def]
    """Wide open, the side edges' pinch (the fingertips 1 mm in, the lower finger beside the
    body below, whose sides the lid's are flush with) is feasible for the Panda all the way
    shut, and as far as half way (rank judging the path to ``to``), when asked for (``also``):
    the actions name only the front edge, which a flying hand, choosing by rank, keeps to."""
    concept = lib[name]
    top = concept.instantiate().joint_limits()["hinge"][1]
    inst = concept.instantiate(pose=Z_UP, joints={"hinge": top})
    plain = inst.rank("close", Gripper.panda(), samples=8)
    assert {o.grasp for o in plain} == set(FRONT)
    whole = {o.grasp: o for o in inst.rank("close", Gripper.panda(), samples=8, also=SIDES)}
    half = {
        o.grasp: o for o in inst.rank("close", Gripper.panda(), samples=8, to=top / 2, also=SIDES)
    }
    for side in SIDES:
        assert whole[side].feasible, whole[side].reasons
        assert half[side].feasible, half[side].reasons
        assert whole[side].mode == "pinch"


def test_rank_refuses_a_joint_value_that_is_not_finite_and_a_bare_name(lib) -> None:  # type: ignore[no-untyped-def]
    from grace_dsl.runtime.errors import ParameterError

    inst = lib["Laptop"].instantiate()
    with pytest.raises(ParameterError, match="finite"):
        inst.rank("close", Gripper.panda(), to=float("nan"))
    with pytest.raises(ParameterError, match="list of grasp names"):
        inst.rank("close", Gripper.panda(), also="left.pinch")


@pytest.mark.slow
def test_the_panda_takes_a_wide_open_laptop_lid_by_its_side_where_its_front_is_out_of_reach() -> (
    None
):
    """Episode 0 of the Laptop's close starts fully open (135 deg): from the base the grasps put
    in front of it, neither the front edge's pinch nor the push on the lid's face is reachable
    (the arm found no grasp before the side edges), and the side edges' pinch is, half way."""
    start = start_episode(EpisodeConfig("Laptop", "close", agent="arm"), 0, 0.0)
    inst, robot = start.inst, panda()  # type: ignore[union-attr]
    assert inst.joints["hinge"] == pytest.approx(inst.joint_limits()["hinge"][1])
    base = robot_base(robot, inst, "close")
    with pytest.raises(NoGraspError, match="no usable grasp"):
        grasp_candidates(robot, inst, "close", base=base, seed=0, grasps=FRONT)
    half = float(inst.joints["hinge"]) / 2
    found, _ = grasp_candidates(robot, inst, "close", base=base, seed=0, to=half, also=SIDES)
    assert found and {c.option.grasp for c in found} <= set(SIDES)


@pytest.mark.slow
def test_the_arm_lifts_a_shut_laptop_lid_by_its_lip() -> None:
    """Seed 2 starts shut (the lid on the base, a 2 mm lip): the arm used to find no plan (the
    open lower finger, under the base, was lifted into it), then closed on base and lid."""
    from grace_dsl.sim.arm_episode import run_arm_episode

    record = run_arm_episode(EpisodeConfig("Laptop", "open", agent="arm"), 2)
    assert record.q_initial == pytest.approx(0.0)
    assert record.strict, f"{record.reason}: {record.detail} (q {record.q_final:.3f})"
