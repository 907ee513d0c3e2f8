"""The execution and verification loop in MuJoCo: plans written by hand against the contract."""

from __future__ import annotations

import pytest

import grace_dsl as eac
from grace_dsl.agent.errors import ExecutionError
from grace_dsl.agent.execute import Executor, aim, held
from grace_dsl.agent.plan import Condition, Plan, SceneObject, SceneSpec, SubTask, Target

CHEST = SceneObject("chest", "ChestOfDrawers", joints={"slide1": 0.2})
MICROWAVE = SceneObject("microwave", "Microwave", position=(0.0, 1.2, 0.0))
# a board in front of the top drawer's handle, level with the pinch's upper finger and palm:
# the ranker does not know it (it sees one object), the hand meets it on the way in
BOARD = SceneObject("board", "Cuboid", {"size": (0.3, 0.01, 0.12)}, position=(0.56, 0.0, 0.662))


def _sub(obj: str, concept: str, action: str, joint: str, target: Target, lo: float, hi: float):  # type: ignore[no-untyped-def]
    return SubTask(
        action, obj, concept, action, action, joint, target, Condition(obj, joint, lo, hi)
    )


CLOSE_TOP = _sub("chest", "ChestOfDrawers", "close1", "slide1", Target("close"), -1.0, 0.0175)


def test_aim_stays_inside_the_condition() -> None:
    cond = Condition("o", "j", 0.4, 0.6)
    assert aim(Target("fraction", 0.5), cond, 0.0, 0.0, 1.0, 1.0) == pytest.approx(0.5)
    assert aim(Target("fraction", 0.9), cond, 0.0, 0.0, 1.0, 1.0) == pytest.approx(0.57)
    assert aim(Target("delta", 0.3), cond, 0.2, 0.0, 1.0, 1.0) == pytest.approx(0.5)
    assert aim(Target("close"), Condition("o", "j", -1.0, 0.05), 0.5, 0.0, 1.0, -1.0) is None
    assert aim(Target("open"), Condition("o", "j", 0.5, 1.0), 0.0, 0.0, 1.0, 1.0) == 0.9


def test_end_state_counts_the_last_step_on_each_joint() -> None:
    open_, close = (
        _sub("c", "C", "open1", "slide1", Target("open"), 0.1, 1.0),
        _sub("c", "C", "close1", "slide1", Target("close"), -1.0, 0.01),
    )
    assert held((open_, close), {"c": {"slide1": 0.0}}) == (True, True)
    assert held((close, open_), {"c": {"slide1": 0.0}}) == (True, False)


@pytest.mark.slow
def test_a_two_step_plan_executes_and_verifies(lib: eac.Library) -> None:
    executor = Executor(SceneSpec("kitchen", (CHEST, MICROWAVE)), lib)
    half = 0.5 * lib["Microwave"].instantiate().joint_limits()["hinge"][1]
    plan = Plan(
        "close the top drawer, then open the microwave halfway",
        (),
        (
            CLOSE_TOP,
            _sub(
                "microwave",
                "Microwave",
                "open",
                "hinge",
                Target("fraction", 0.5),
                half - 0.17,
                half + 0.17,
            ),  # fmt: skip
        ),
    )
    result = executor.run(plan)
    assert result.success, result.to_json()
    assert [len(s.attempts) for s in result.steps] == [1, 1]
    assert result.joints["chest"]["slide1"] < 0.0175
    assert result.joints["microwave"]["hinge"] == pytest.approx(half, abs=0.05)
    assert result.steps[1].q_before == 0.0 and result.steps[0].q_before == pytest.approx(0.2)
    again = executor.run(Plan("close the top drawer", (), (CLOSE_TOP,)))
    assert again.steps[0].reason == "already_held" and again.success  # the state persisted


@pytest.mark.slow
def test_a_blocked_option_fails_and_the_next_ranked_one_is_tried(lib: eac.Library) -> None:
    result = Executor(SceneSpec("blocked", (CHEST, BOARD)), lib).run(
        Plan("close the top drawer", (), (CLOSE_TOP,))
    )
    first, second = result.steps[0].attempts
    assert first.option == "handle1.pull (pinch)" and not first.verified
    assert first.reason == "collision" and first.q_after == pytest.approx(0.2, abs=0.01)
    assert second.option == "push1 (push)" and second.verified
    assert result.success and result.joints["chest"]["slide1"] < 0.0175
    # without the board the first-ranked option does it alone
    free = Executor(SceneSpec("free", (CHEST,)), lib).run(Plan("close", (), (CLOSE_TOP,)))
    assert [a.option for a in free.steps[0].attempts] == ["handle1.pull (pinch)"]


def test_a_plan_that_does_not_fit_the_scene_raises(lib: eac.Library) -> None:
    executor = Executor(SceneSpec("one", (CHEST,)), lib)
    wrong = [
        (_sub("oven", "Oven", "open", "hinge", Target("open"), 0.5, 2.0), "no object 'oven'"),
        (_sub("chest", "Microwave", "open", "hinge", Target("open"), 0.5, 2.0), "is a ChestOf"),
        (_sub("chest", "ChestOfDrawers", "open9", "slide1", Target("open"), 0.1, 1), "no action"),
        (_sub("chest", "ChestOfDrawers", "open1", "slide2", Target("open"), 0.1, 1), "moves joint"),
    ]
    for sub, message in wrong:
        with pytest.raises(ExecutionError, match=message):
            executor.run(Plan("x", (), (sub,)))
    assert executor.world.joints("chest")["slide1"] == pytest.approx(0.2)  # nothing moved
