"""What task parsing produces: an object graph and an ordered list of verifiable sub-tasks.

The paper's top layer turns an instruction into sub-tasks (l_i, c_i): l_i says which object part
to act on and how, c_i says how to check that it happened. Here l_i is a ``SubTask`` (a scene
object, a part of its concept, an action of that concept and a target) and c_i its
``Condition`` (a predicate on one joint of that object, checkable in simulation).

This module is the contract between the parsers (offline and VLM), scene grounding and the
execution loop; it holds plain values only. Names:

- an object is named as in the scene file (``"chest"``, ``"microwave"``);
- a part is the concept's link or part path (``"drawer[0]"``, ``"door"``), an action the
  concept's action name (``"drawer[0].open"``), a joint the concept's joint name
  (``"drawer[0].slide"``); values are SI (metres, radians).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np

TargetKind = Literal["open", "close", "fraction", "delta"]


@dataclass(frozen=True)
class Target:
    """Where the joint should end up.

    ``open``: fully open (the range's upper end); ``close``: closed (its lower end);
    ``fraction``: ``value`` in [0, 1] of the range ("halfway" is 0.5); ``delta``: move by
    ``value`` (m or rad; "by 30 degrees" is 0.5236) in the action's direction."""

    kind: TargetKind
    value: float = 0.0


@dataclass(frozen=True)
class Condition:
    """A sub-task's verification: ``lo <= q_joint <= hi`` on one object's joint."""

    object: str
    joint: str
    lo: float
    hi: float

    def holds(self, q: float) -> bool:
        return self.lo <= q <= self.hi


@dataclass(frozen=True)
class SubTask:
    """One step: act on a part of a scene object with one of its concept's actions."""

    text: str  # the instruction's words this step came from
    object: str
    concept: str
    part: str
    action: str
    joint: str
    target: Target
    condition: Condition


@dataclass(frozen=True)
class ObjectNode:
    """A scene object in the plan's graph, with the parts the instruction mentions."""

    name: str
    concept: str
    parts: tuple[str, ...] = ()
    relations: tuple[tuple[str, str], ...] = ()  # (relation, other), e.g. ("left_of", "fridge")


@dataclass(frozen=True)
class Plan:
    """An instruction's object graph and its ordered sub-tasks."""

    instruction: str
    objects: tuple[ObjectNode, ...]
    subtasks: tuple[SubTask, ...]
    notes: tuple[str, ...] = ()  # what the parser assumed, for a person to read

    def to_json(self) -> dict[str, Any]:
        from dataclasses import asdict

        return asdict(self)


@dataclass(frozen=True)
class SceneObject:
    """One object of a scene file: a concept instance at a world pose with joint values."""

    name: str
    concept: str
    params: dict[str, Any] = field(default_factory=dict)
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)  # m, world, z up
    yaw: float = 0.0  # rad about world z; 0: the object's front faces world +x
    joints: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class SceneSpec:
    """A scene file's content (``grace_dsl.agent.scene_file`` reads and writes it)."""

    name: str
    objects: tuple[SceneObject, ...]
    description: str = ""


class TaskParser(Protocol):
    """An instruction (and optionally an RGB image) in a scene -> a grounded ``Plan``.

    Raises ``grace_dsl.agent.errors.ParseError`` (a ``GraceError``) with a message a person can
    act on when it cannot parse or the instruction is ambiguous; it never guesses silently."""

    def parse(
        self, instruction: str, scene: SceneSpec, *, image: np.ndarray | None = None
    ) -> Plan: ...
