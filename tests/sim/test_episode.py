"""Real MuJoCo episodes with the flying Panda hand: one per task kind, and determinism."""

from __future__ import annotations

from dataclasses import replace

import pytest

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.sim.episode import Outcome, _failure, run_episode
from grace_dsl.sim.protocol import Draw
from grace_dsl.sim.records import FAILURE_REASONS, EpisodeConfig


def _same(a: dict, b: dict) -> bool:  # type: ignore[type-arg]
    a, b = dict(a), dict(b)
    a.pop("wall_seconds"), b.pop("wall_seconds")
    return a == b


@pytest.mark.slow
def test_open_a_drawer_from_closed() -> None:
    record = run_episode(EpisodeConfig("CabinetDrawer", "open"), 0)
    assert record.q_initial == 0.0  # this seed draws the closed start
    assert record.strict and record.lenient, record.detail
    lo, hi = record.q_range
    assert record.q_final >= lo + 0.5 * (hi - lo)
    assert record.reason == "" and record.option.endswith("(pinch)")


@pytest.mark.slow
def test_close_a_door_and_replay_it() -> None:
    config = EpisodeConfig("HingedCabinet", "close")
    record = run_episode(config, 1)
    assert record.q_initial > 0.5
    assert record.strict and record.lenient, record.detail
    again = run_episode(config, 1)
    assert _same(record.to_json(), again.to_json())  # a pure function of (config, seed)


@pytest.mark.slow
def test_a_hand_that_cannot_pinch_reports_a_reason_not_an_exception() -> None:
    record = run_episode(EpisodeConfig("CabinetDrawer", "open", hand="pusher"), 2)
    assert record.reason in FAILURE_REASONS
    assert record.strict == (record.reason == "")
    assert "(pinch)" not in record.option


def test_unsupported_configurations_raise_typed_errors() -> None:
    with pytest.raises(ParameterError, match="agent"):
        run_episode(EpisodeConfig("CabinetDrawer", agent="legs"), 0)  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="oracle"):
        run_episode(EpisodeConfig("CabinetDrawer", mode="estimated"), 0)


def test_hands_built_from_their_descriptions() -> None:
    import numpy as np

    import grace_dsl as eac
    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.sim.episode import Z_UP
    from grace_dsl.sim.hand import GRASP_FORCE
    from grace_dsl.sim.world import World

    inst = eac.load_library()["CabinetDrawer"].instantiate(pose=Z_UP)
    away = np.eye(4)
    away[:3, 3] = (1.0, 0.0, 1.0)  # far from the object: the fingers move freely
    panda = World.build(inst, Gripper.panda(), away)
    assert panda.hand.fingers and panda.hand.grasp_force == GRASP_FORCE == 70.0
    assert np.all(panda.model.actuator_forcerange == [[-70.0, 70.0], [-70.0, 70.0]])
    panda.set_fingers(0.08)
    for _ in range(600):  # 1.2 s: 40 mm per finger at 0.1 m/s
        panda.step(away)
    assert panda.opening() == pytest.approx(0.08, abs=1e-3)
    assert np.allclose(panda.hand_pose()[:3, 3], away[:3, 3], atol=1e-3)  # it floats in place
    pusher = World.build(inst, Gripper.load("pusher"), away)
    assert pusher.hand.fingers == () and pusher.model.nu == 0  # a hand that cannot close


def test_the_object_collides_through_its_convex_pieces_only(lib) -> None:  # type: ignore[no-untyped-def]
    """The export's whole visual pieces (a window frame's ring, whose hull is a solid block)
    touch nothing; the hand meets the object's convex collision pieces. Before, the world made
    every object geom collide and the hand stopped at a sliding window's frame hull."""
    import numpy as np

    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.sim.episode import Z_UP
    from grace_dsl.sim.world import World

    away = np.eye(4)
    away[:3, 3] = (1.0, 0.0, 1.0)
    world = World.build(lib["SlidingWindow"].instantiate(pose=Z_UP), Gripper.panda(), away)
    m = world.model
    hand = {m.body(n).id for n in range(m.nbody) if m.body(n).name.startswith("hand")}
    on_object = np.array([m.geom_bodyid[g] not in hand for g in range(m.ngeom)])
    visual, pieces = on_object & (m.geom_group == 2), on_object & (m.geom_group == 3)
    assert visual.any() and pieces.any()
    assert not (m.geom_contype[visual] | m.geom_conaffinity[visual]).any()
    assert (m.geom_conaffinity[pieces] > 0).all()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("concept", "task", "seed"),
    [
        ("Laptop", "open", 17),  # a pad passed under the 8 mm base and closed on base and lid
        ("LidBox", "close", 4),  # a pad deep under the lid's lip landed on the box's wall
        ("Toilet", "open", 3),  # the weightless seat rose with the lid hinged on it
        ("LeverFaucet", "close", 0),  # a short lever pressed 0.4 mm past its stop, twisted back
    ],
)
def test_episodes_that_failed_before_their_fixes(concept: str, task: str, seed: int) -> None:
    record = run_episode(EpisodeConfig(concept, task), seed)  # type: ignore[arg-type]
    assert record.strict, f"{record.reason}: {record.detail} (q {record.q_final:.3f})"


def test_only_the_driven_part_is_balanced(lib) -> None:  # type: ignore[no-untyped-def]
    """Lifting a toilet lid: the lid is balanced, the seat it hangs on keeps its weight and the
    export's friction; without a driven joint, every part is balanced (the old world)."""
    import numpy as np

    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.sim.episode import Z_UP
    from grace_dsl.sim.world import World

    inst = lib["Toilet"].instantiate(pose=Z_UP)
    far = np.eye(4)
    far[:3, 3] = (2.0, 0.0, 1.0)
    w = World.build(inst, Gripper.load("panda"), far, driven="lid_hinge")
    gravcomp = {w.model.body(b).name: float(w.model.body_gravcomp[b]) for b in range(w.model.nbody)}
    assert [n for n, g in gravcomp.items() if g and not n.startswith(("hand", "finger"))] == [
        n for n in gravcomp if "cover" in n
    ]
    friction = {
        w.model.joint(j).name: float(w.model.dof_frictionloss[w.model.jnt_dofadr[j]])
        for j in range(w.model.njnt)
    }
    lid = next(v for k, v in friction.items() if "lid" in k)
    seat = next(v for k, v in friction.items() if "seat" in k)
    assert lid == pytest.approx(0.1) and seat >= lid
    every = World.build(inst, Gripper.load("panda"), far)
    assert all(every.model.body_gravcomp[2:] == 1.0)  # all but the world and the welded root


def test_a_part_gone_from_the_fingers_is_a_slip_not_a_timeout() -> None:
    """The follower re-anchors on the measured joint, so a hand whose pinch lost the part stays
    on the path and the drift check never fires: the fingers closed on nothing say it."""
    config, draw = EpisodeConfig("Refrigerator", "open"), Draw({}, 1.0, 0.0, True)
    held = Outcome(1.0, 21.0, arrived=True, slipped=False)
    assert _failure(config, draw, held)[0] == "timeout"
    reason, detail = _failure(config, draw, replace(held, emptied=True))
    assert reason == "slip" and "+1.000" in detail


@pytest.mark.slow
def test_a_heavy_door_that_left_the_fingers_slips() -> None:
    """A 2x refrigerator door (eight times the mass) pulled by its handle: the bar leaves the
    pinch at 1.0 rad of 2.1 and the door stops; that is a slip."""
    config = EpisodeConfig("Refrigerator", "open", scale=(0.3, 2.0), ranges="valid")
    record = run_episode(config, 1072501174)
    assert not record.strict and record.lenient
    assert record.reason == "slip", record.detail
