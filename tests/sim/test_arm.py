"""The full Panda in MuJoCo: the same kinematics as the planner's, still under gravity
compensation, and one real arm episode on a drawer."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from grace_dsl.robot.model import Robot
from grace_dsl.runtime.errors import ParameterError
from grace_dsl.sim.arm import ArmWorld
from grace_dsl.sim.episode import Z_UP, run_episode
from grace_dsl.sim.records import EpisodeConfig


@pytest.fixture(scope="module")
def panda() -> Robot:
    return Robot.panda()


def _world(lib, panda: Robot) -> ArmWorld:  # type: ignore[no-untyped-def]
    inst = lib["CabinetDrawer"].instantiate(pose=Z_UP)
    base = np.eye(4)
    base[:3, :3] = np.diag([-1.0, -1.0, 1.0])  # facing the drawer's front (world +x)
    base[:3, 3] = (1.0, 0.0, 0.2)
    return ArmWorld.build(inst, base, panda.home)


def test_the_simulated_arm_has_the_planners_kinematics(lib, panda: Robot) -> None:  # type: ignore[no-untyped-def]
    world = _world(lib, panda)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = panda.random_q(rng)
        world.data.qpos[world.arm_qpos] = q
        mujoco.mj_forward(world.model, world.data)
        expected = world.base @ panda.fk(q)
        assert np.allclose(world.hand_pose(), expected, atol=1e-6)
    assert len(world.hand.fingers) == 2 and world.hand.grasp_force == 70.0


def test_the_arm_holds_still_under_gravity_compensation(lib, panda: Robot) -> None:  # type: ignore[no-untyped-def]
    world = _world(lib, panda)
    q0 = world.arm_q()
    for _ in range(500):  # 1 s with the motors off
        world.step(np.zeros(7))
    assert np.abs(world.arm_q() - q0).max() < 1e-4
    assert not world.unstable()
    sagging = _world(lib, panda)
    sagging.model.body_gravcomp[:] = 0.0  # without compensation the same arm falls
    for _ in range(500):
        sagging.step(np.zeros(7))
    assert np.abs(sagging.arm_q() - q0).max() > 0.05


def test_an_arm_link_in_the_object_is_a_contact(lib, panda: Robot) -> None:  # type: ignore[no-untyped-def]
    world = _world(lib, panda)
    assert not world.arm_contact()  # 1 m in front of the drawer, at home
    inst = lib["CabinetDrawer"].instantiate(pose=Z_UP)
    base = np.eye(4)
    base[:3, :3] = np.diag([-1.0, -1.0, 1.0])
    base[:3, 3] = (0.0, 0.0, 0.0)  # standing in the carcass, the upper arm through its top
    inside = ArmWorld.build(inst, base, panda.home)
    inside.step(np.zeros(7))
    assert inside.arm_contact()


def test_the_arm_takes_only_the_panda_hand() -> None:
    with pytest.raises(ParameterError, match="hand"):
        run_episode(EpisodeConfig("CabinetDrawer", agent="arm", hand="pusher"), 0)


@pytest.mark.slow
def test_the_arm_opens_a_drawer() -> None:
    record = run_episode(EpisodeConfig("CabinetDrawer", "open", agent="arm"), 1)
    lo, hi = record.q_range
    assert record.strict, record.detail
    assert record.q_final - lo >= 0.5 * (hi - lo)
    assert record.option.endswith("(pinch)")
    assert record.sim_seconds > 1.0
