"""The offline parser: the suite, the grammar's amounts and selectors, geometric grounding, and
adversarial phrasings (typos, unknown objects, ambiguous references)."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

import grace_dsl as eac
from grace_dsl.agent import parse
from grace_dsl.agent.errors import ParseError
from grace_dsl.agent.grounding import final_conditions
from grace_dsl.agent.offline import OfflineParser
from grace_dsl.agent.plan import SceneSpec, Target
from grace_dsl.agent.suite import load_suite, parse_accuracy, plan_steps


def test_suite_parse_accuracy(parser: OfflineParser, scenes: dict[str, SceneSpec]) -> None:
    tasks = load_suite()
    assert len(tasks) >= 30
    assert {len(t.steps) for t in tasks} >= {1, 2, 3, 4, 5}
    result = parse_accuracy(parser.parse, scenes, tasks)
    assert result.accuracy >= 0.95, result.table()


def test_suite_final_values_meet_the_final_conditions(
    parser: OfflineParser, scenes: dict[str, SceneSpec]
) -> None:
    for task in load_suite():
        plan = parser.parse(task.instruction, scenes[task.scene])
        final = final_conditions(plan)
        for key, value in task.final.items():
            obj, joint = key.split("/", 1)
            assert final[(obj, joint)].holds(value), (task.id, key, final[(obj, joint)])
        moved = {f"{o}/{j}" for o, j in final}
        assert set(task.final) <= moved, task.id


def test_worked_example(parser: OfflineParser, scenes: dict[str, SceneSpec]) -> None:
    text = "open the top drawer, then open the left cabinet door halfway, then close the drawer"
    plan = parser.parse(text, scenes["kitchen"])
    first, second, third = plan.subtasks
    assert (first.object, first.joint, first.target) == ("chest", "slide1", Target("open"))
    assert first.condition.lo == pytest.approx(0.175) and first.condition.hi == pytest.approx(0.35)
    assert (second.part, second.target) == ("door[0]", Target("fraction", 0.5))
    half = math.radians(110) / 2
    assert second.condition.lo == pytest.approx(half - math.radians(11), abs=1e-5)
    assert second.condition.hi == pytest.approx(half + math.radians(11), abs=1e-5)
    assert (third.joint, third.target.kind, third.condition.hi) == ("slide1", "close", 0.0175)
    assert any("named before" in n for n in plan.notes)
    assert [o.name for o in plan.objects] == ["chest", "cabinet"]
    assert plan.objects[0].relations == (("left_of", "cabinet"),)


def test_top_is_the_highest_handle(parser: OfflineParser, scenes: dict[str, SceneSpec]) -> None:
    units = [u for u in parser.ground(scenes["kitchen"]).units if u.object == "chest"]
    for word, pick in (("top", max), ("bottom", min)):
        plan = parser.parse(f"open the {word} drawer", scenes["kitchen"])
        want = pick(units, key=lambda u: u.position[2])
        assert plan.subtasks[0].joint == want.joint


def test_left_is_seen_from_the_front(parser: OfflineParser, scenes: dict[str, SceneSpec]) -> None:
    """The left door is on the left of someone facing the cabinet's front, whichever way the
    cabinet faces: at yaw 0 (front to +x) that is towards -y, at yaw pi towards +y."""
    kitchen = scenes["kitchen"]
    for yaw, sign in ((0.0, -1.0), (math.pi, 1.0)):
        objects = tuple(replace(o, yaw=yaw) if o.name == "cabinet" else o for o in kitchen.objects)
        scene = replace(kitchen, objects=objects)
        plan = parser.parse("open the left cabinet door", scene)
        doors = {u.part: u for u in parser.ground(scene).units if u.object == "cabinet"}
        left = doors[plan.subtasks[0].part]
        other = next(u for p, u in doors.items() if p != left.part)
        assert sign * (left.position[1] - other.position[1]) > 0, (yaw, left.part)


@pytest.mark.parametrize(
    ("text", "target"),
    [
        ("open the microwave halfway", Target("fraction", 0.5)),
        ("open the microwave all the way", Target("open")),
        ("open the microwave by 30 degrees", Target("delta", 0.523599)),
        ("open the microwave to 50 degrees", Target("fraction", 0.5)),
        ("open the microwave 40%", Target("fraction", 0.4)),
        ("open the microwave a bit", Target("delta", round(0.2 * math.radians(100), 6))),
        ("shut the microwave", Target("close")),
    ],
)
def test_amounts(
    parser: OfflineParser, scenes: dict[str, SceneSpec], text: str, target: Target
) -> None:
    (step,) = parser.parse(text, scenes["kitchen"]).subtasks
    assert step.target.kind == target.kind
    assert step.target.value == pytest.approx(target.value, abs=1e-5)


def test_delta_condition_follows_earlier_steps(
    parser: OfflineParser, scenes: dict[str, SceneSpec]
) -> None:
    plan = parser.parse("open the top drawer by 10 cm and then by 5 cm", scenes["kitchen"])
    a, b = plan.subtasks
    assert a.condition.holds(0.1) and not a.condition.holds(0.15)
    assert b.condition.holds(0.15) and not b.condition.holds(0.1)


def test_typos_are_corrected_only_when_unique(
    parser: OfflineParser, scenes: dict[str, SceneSpec]
) -> None:
    plan = parser.parse("opne the midle drwaer", scenes["kitchen"])
    assert plan.subtasks[0].joint == "slide2"
    assert "read 'drwaer' as 'drawer'" in plan.notes and "read 'opne' as 'open'" in plan.notes
    with pytest.raises(ParseError, match="no concept in the library matches 'dor'"):
        parser.parse("open the dor", scenes["kitchen"])  # too short to correct
    with pytest.raises(ParseError, match="I do not know 'lide'; did you mean 'lid' or .*'slide'"):
        parser.parse("open the lide", scenes["kitchen"])  # several words are as near


@pytest.mark.parametrize(
    ("scene", "text", "words"),
    [
        ("kitchen", "open the toaster", ["there is no toaster in scene 'kitchen'", "chest"]),
        ("kitchen", "open the teleporter", ["no concept in the library matches 'teleporter'"]),
        ("kitchen", "open the drawer", ["3 parts match 'drawer'", "Which one?", "top"]),
        ("kitchen", "open the door", ["4 parts match 'door'", "cabinet", "fridge"]),
        ("kitchen", "open the middle door of the cabinet", ["no middle one"]),
        ("kitchen", "open the blue drawer", ["I do not know the word 'blue'"]),
        ("kitchen", "open the top drawer by 30 degrees", ["slides", "cm or mm"]),
        ("kitchen", "close it", ["'it' refers to nothing"]),
        ("kitchen", "the top drawer", ["no action in it"]),
        ("kitchen", "open the fourth drawer of the chest", ["no fourth drawer", "only 3"]),
        ("hall", "open the door", ["3 parts match 'door'"]),
        ("bathroom", "flush the washing machine", ["cannot be 'flush'-ed", "open"]),
    ],
)
def test_refusals_say_why(
    parser: OfflineParser,
    scenes: dict[str, SceneSpec],
    scene: str,
    text: str,
    words: list[str],
) -> None:
    with pytest.raises(ParseError) as info:
        parser.parse(text, scenes[scene])
    for w in words:
        assert w in str(info.value), str(info.value)


def test_left_right_refused_across_facings(
    parser: OfflineParser, scenes: dict[str, SceneSpec]
) -> None:
    hall = scenes["hall"]
    objects = tuple(
        replace(o, yaw=math.pi / 2) if o.name == "wardrobe" else o for o in hall.objects
    )
    with pytest.raises(ParseError, match="face different ways"):
        parser.parse("open the left door", replace(hall, objects=objects))


def test_public_parse_takes_a_scene_name(lib: eac.Library) -> None:
    plan = parse("open the fridge, then close it", scene="kitchen", lib=lib)
    assert [s.action for s in plan.subtasks] == ["open", "close"]
    assert plan_steps(plan)[1].target == Target("close")
    assert plan.to_json()["subtasks"][0]["condition"]["object"] == "fridge"


def test_quantifiers_and_ordinals_follow_the_spread(
    parser: OfflineParser, scenes: dict[str, SceneSpec]
) -> None:
    """Drawers stacked are counted top to bottom; doors side by side, left to right."""
    plan = parser.parse("close all the drawers", scenes["kitchen"])
    assert [s.joint for s in plan.subtasks] == ["slide1", "slide2", "slide3"]
    for word, obj in (("first", "hall_door"), ("second", "bedroom_door"), ("last", "wardrobe")):
        (step,) = parser.parse(f"open the {word} door", scenes["hall"]).subtasks
        assert step.object == obj, word
    plan = parser.parse("open the top and bottom drawers", scenes["kitchen"])
    assert [s.joint for s in plan.subtasks] == ["slide1", "slide3"]
