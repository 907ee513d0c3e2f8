"""``grace run --agent arm``: the full Panda carries plans out in a room of several objects."""

from __future__ import annotations

import argparse
import json

import pytest

import grace_dsl as eac
from grace_dsl.agent import arm_execute
from grace_dsl.agent.arm_execute import ArmExecutor, arm_aim
from grace_dsl.agent.plan import Condition, Plan, SceneObject, SceneSpec, SubTask, Target
from grace_dsl.cli.run_cmd import add_run_arguments, run_run

CHEST = SceneObject("chest", "ChestOfDrawers", joints={"slide1": 0.0})
CABINET = SceneObject("cabinet", "Cuboid", {"size": (0.4, 0.8, 0.4)}, position=(0.0, 1.4, 0.0))


def _sub(action: str, target: Target, lo: float, hi: float) -> SubTask:
    cond = Condition("chest", "slide1", lo, hi)
    return SubTask(action, "chest", "ChestOfDrawers", "drawer1", action, "slide1", target, cond)


OPEN_HALF = _sub("open1", Target("fraction", 0.5), 0.14, 0.21)  # travel 0.35 by default
CLOSE = _sub("close1", Target("close"), -1.0, 0.0175)


def _args(*argv: str) -> argparse.Namespace:
    p = argparse.ArgumentParser()
    add_run_arguments(p)
    return p.parse_args(list(argv))


def test_the_arm_aims_an_open_at_seven_tenths() -> None:
    cond = Condition("o", "j", 0.5, 1.0)
    assert arm_aim(Target("open"), cond, 0.0, 0.0, 1.0, 1.0) == pytest.approx(0.7)
    assert arm_aim(Target("fraction", 0.3), Condition("o", "j", 0.2, 0.4), 0, 0, 1, 1) == 0.3


def test_the_arm_is_the_panda_with_its_own_hand(capsys: pytest.CaptureFixture[str]) -> None:
    code = run_run(_args("open the microwave", "--scene", "kitchen", "--agent", "arm", "--hand",
                         "pusher"))  # fmt: skip
    assert code == 1 and "Panda with its own hand" in capsys.readouterr().err


@pytest.mark.slow
def test_a_one_step_instruction_on_a_shipped_scene(
    lib: eac.Library, capsys: pytest.CaptureFixture[str]
) -> None:
    assert "ChestOfDrawers" in lib  # the session's library is built: the command loads its cache
    code = run_run(_args("open the top drawer", "--scene", "kitchen", "--agent", "arm", "--json"))
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["success"], out
    (step,) = out["steps"]
    (attempt,) = step["attempts"]
    assert attempt["verified"] and attempt["option"].startswith("handle1")
    assert step["q_after"] >= 0.175  # strict open: half the travel
    x, y, _, _ = attempt["base"]
    assert x > 0.3 and abs(y - (-2.1)) < 0.5  # in front of the chest, not of another object
    assert attempt["arm_before"] != attempt["arm_after"]


@pytest.mark.slow
def test_a_two_step_plan_carries_the_state_over(lib: eac.Library) -> None:
    executor = ArmExecutor(SceneSpec("room", (CHEST, CABINET)), lib)
    result = executor.run(
        Plan("open the top drawer halfway, then close it", (), (OPEN_HALF, CLOSE))
    )
    assert result.success, result.to_json()
    first, second = result.steps
    assert second.q_before == pytest.approx(first.q_after)  # the drawer stayed where it was left
    assert second.attempts[0].arm_before == first.attempts[-1].arm_after
    assert result.joints["chest"]["slide1"] < 0.0175


@pytest.mark.slow
def test_a_base_out_of_reach_is_a_step_reason(
    lib: eac.Library, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(arm_execute, "PLACE_REACH", 3.0)  # the base 3 m from the drawer
    result = ArmExecutor(SceneSpec("room", (CHEST,)), lib).run(Plan("open", (), (OPEN_HALF,)))
    (step,) = result.steps
    assert not result.success and not step.verified
    assert step.reason == "ik_failure" and "reach" in step.attempts[0].detail
    assert len(step.attempts) == 1 and step.q_after == step.q_before == 0.0
