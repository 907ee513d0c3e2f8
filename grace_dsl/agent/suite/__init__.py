"""The long-horizon task suite: instructions over the shipped scenes with their expected plans.

``tasks.json`` lists each instruction's scene, its expected steps (object, part, action, joint,
target) and the nominal value of every joint it moves at the end. ``parse_accuracy`` runs a
parser over the suite: a plan is right when its steps equal the expected ones (same object,
part, action, joint, target kind and value within ``VALUE_TOL``); a ``ParseError`` counts as
wrong. Execution (task success) checks each plan's ``grounding.final_conditions`` in simulation.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from typing import Any

from grace_dsl.agent.errors import ParseError
from grace_dsl.agent.plan import Plan, SceneSpec, Target

VALUE_TOL = 1e-4  # a target's value: equal within this (m, rad or fraction)


@dataclass(frozen=True)
class Step:
    """An expected sub-task, without its text and condition (which follow from it)."""

    object: str
    part: str
    action: str
    joint: str
    target: Target

    @classmethod
    def parse(cls, text: str) -> Step:
        """``"chest drawer1 open1 slide1 fraction 0.5"`` -> a ``Step``."""
        words = text.split()
        if len(words) not in (5, 6) or words[4] not in ("open", "close", "fraction", "delta"):
            raise ValueError(f"a step is 'object part action joint kind [value]', not {text!r}")
        value = float(words[5]) if len(words) == 6 else 0.0
        return cls(words[0], words[1], words[2], words[3], Target(words[4], value))  # type: ignore[arg-type]

    def matches(self, other: Step) -> bool:
        return (self.object, self.part, self.action, self.joint, self.target.kind) == (
            other.object,
            other.part,
            other.action,
            other.joint,
            other.target.kind,
        ) and abs(self.target.value - other.target.value) <= VALUE_TOL

    def __str__(self) -> str:
        value = f" {self.target.value:g}" if self.target.kind in ("fraction", "delta") else ""
        return f"{self.object} {self.part} {self.action} {self.joint} {self.target.kind}{value}"


@dataclass(frozen=True)
class SuiteTask:
    id: str
    scene: str
    instruction: str
    steps: tuple[Step, ...]
    final: Mapping[str, float]  # "object/joint" -> its nominal value at the end


def plan_steps(plan: Plan) -> tuple[Step, ...]:
    return tuple(Step(s.object, s.part, s.action, s.joint, s.target) for s in plan.subtasks)


def load_suite() -> tuple[SuiteTask, ...]:
    """The shipped suite's tasks, in file order."""
    text = (resources.files("grace_dsl.agent.suite") / "tasks.json").read_text(encoding="utf-8")
    data = json.loads(text)
    return tuple(
        SuiteTask(
            id=t["id"],
            scene=t["scene"],
            instruction=t["instruction"],
            steps=tuple(Step.parse(s) for s in t["steps"]),
            final={k: float(v) for k, v in t["final"].items()},
        )
        for t in data["tasks"]
    )


@dataclass(frozen=True)
class TaskOutcome:
    task: SuiteTask
    plan: Plan | None
    correct: bool
    problem: str  # "" when correct: the first differing step or the parser's error


@dataclass(frozen=True)
class SuiteResult:
    outcomes: tuple[TaskOutcome, ...]

    @property
    def accuracy(self) -> float:
        return sum(o.correct for o in self.outcomes) / max(len(self.outcomes), 1)

    def table(self) -> str:
        lines = [
            f"parse accuracy: {self.accuracy:.3f} ({sum(o.correct for o in self.outcomes)}"
            f"/{len(self.outcomes)})"
        ]
        lines += [f"  {o.task.id}: {o.problem}" for o in self.outcomes if not o.correct]
        return "\n".join(lines)


def compare(task: SuiteTask, plan: Plan) -> str:
    """ "" when ``plan`` is the expected plan, else what differs first."""
    got = plan_steps(plan)
    if len(got) != len(task.steps):
        return f"{len(got)} steps instead of {len(task.steps)}: " + "; ".join(map(str, got))
    for k, (want, have) in enumerate(zip(task.steps, got, strict=True)):
        if not want.matches(have):
            return f"step {k + 1}: {have} instead of {want}"
    return ""


def parse_accuracy(
    parse: Callable[[str, SceneSpec], Plan],
    scenes: Mapping[str, SceneSpec],
    tasks: Sequence[SuiteTask] | None = None,
) -> SuiteResult:
    """Run ``parse(instruction, scene)`` over the suite (``scenes`` by name)."""
    outcomes = []
    for task in tasks if tasks is not None else load_suite():
        try:
            plan: Plan | None = parse(task.instruction, scenes[task.scene])
        except ParseError as exc:
            outcomes.append(TaskOutcome(task, None, False, f"refused: {exc}"))
            continue
        assert plan is not None
        problem = compare(task, plan)
        outcomes.append(TaskOutcome(task, plan, not problem, problem))
    return SuiteResult(tuple(outcomes))


def shipped_scene_specs(lib: Any) -> dict[str, SceneSpec]:
    """The shipped scenes by name, checked against ``lib``."""
    from grace_dsl.agent.scene_file import load_scene, shipped_scenes

    return {name: load_scene(path, lib) for name, path in shipped_scenes().items()}
