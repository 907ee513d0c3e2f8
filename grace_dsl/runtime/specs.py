"""Typed specs of a concept's members, built once from its manifest entry.

Why: the runtime, the ranker and the verifier all need the *meaning* of a grasp or an action
(its contact mode, whether it turns the hand, its sense), not the verb strings of the manifest.
Each spec compiles that meaning in once; ``spec["key"]`` still reads the raw manifest entry, so
code written against the old ``{name: dict}`` tables keeps working.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

# Verbs of actions that turn the hand: along a joint, a grasp on its axis is twisted; with an
# explicit direction (`turn toward (0, 0, 1)`), the direction is the axis of the twist.
TWIST_VERBS = ("turn", "rotate")
MODES = ("pinch", "hook", "push", "press")


@dataclass(frozen=True, eq=False)
class _Entry(Mapping[str, Any]):
    """Read access to the manifest entry a spec was built from (the old dict interface)."""

    def __getitem__(self, key: str) -> Any:
        return self.entry[key]  # type: ignore[attr-defined]

    def __iter__(self) -> Iterator[str]:
        return iter(self.entry)  # type: ignore[attr-defined]

    def __len__(self) -> int:
        return len(self.entry)  # type: ignore[attr-defined]

    def __eq__(self, other: object) -> bool:
        return type(other) is type(self) and self.entry == other.entry  # type: ignore[attr-defined]

    def __hash__(self) -> int:
        return hash((type(self).__name__, self.where))  # type: ignore[attr-defined]


def where_of(entry: Mapping[str, Any], concept: Mapping[str, Any], what: str) -> str:
    """Where a member is written: its ``file:line`` when the manifest records one, else the
    concept's file and the member's name (so an error still says which formula to look at)."""
    for key in ("where", "location"):
        if entry.get(key):
            return str(entry[key])
    file = concept.get("file") or "?"
    return f"{file}, {what} of {concept.get('name', '?')}"


@dataclass(frozen=True, eq=False)
class FreeSpec:
    """A free parameter of a grasp family (its range is evaluated per instance)."""

    name: str
    dim: str | None


@dataclass(frozen=True, eq=False)
class GraspSpec(_Entry):
    """A grasp family: the link it rides on, its free parameters and how it touches."""

    name: str
    link: str
    doc: str
    free: tuple[FreeSpec, ...]
    has_width: bool
    mode: str  # pinch | hook | push | press
    symmetric: bool
    approach_symmetric: bool  # symmetric about its approach: spinning never changes it
    needs_close: bool  # the fingers must close on it (a pinch)
    where: str
    entry: Mapping[str, Any] = field(repr=False)
    when: str | None = None  # the ``when`` condition as written (None: it always applies)
    when_joints: tuple[str, ...] = ()  # the joints that condition reads
    when_where: str = ""  # its ``file:line``

    @property
    def free_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.free)

    @staticmethod
    def of(e: Mapping[str, Any], concept: Mapping[str, Any]) -> GraspSpec:
        mode = e.get("mode") or "pinch"
        demands = e.get("demands") or {}
        when = e.get("when") or {}
        return GraspSpec(
            e["name"],
            e["link"],
            e.get("doc", ""),
            tuple(FreeSpec(f["name"], f.get("dim")) for f in e["free"]),
            bool(e["has_width"]),
            mode,
            bool(e.get("symmetric")),
            demands.get("orientation") == "approach",
            mode == "pinch",
            where_of(e, concept, f"grasp {e['name']}"),
            e,
            when.get("condition"),
            tuple(when.get("joints", ())),
            when.get("where", ""),
        )


@dataclass(frozen=True, eq=False)
class ActionSpec(_Entry):
    """An action: its joint (None: a fixed direction), its sense, and whether it turns the hand.

    ``turns`` is true for the verbs turn/rotate; ``fixed_twist`` when such an action has an
    explicit direction, which is then the axis of a twist and gives no linear force."""

    name: str
    verb: str
    joint: str | None
    opening: bool
    sign: float  # +1 opening, -1 closing
    turns: bool
    fixed_twist: bool
    using: tuple[str, ...]
    doc: str
    where: str
    entry: Mapping[str, Any] = field(repr=False)

    @property
    def sense(self) -> str:
        return "opening" if self.opening else "closing"

    @staticmethod
    def of(e: Mapping[str, Any], concept: Mapping[str, Any]) -> ActionSpec:
        opening = e["sense"] == "opening"
        turns = e["verb"] in TWIST_VERBS
        return ActionSpec(
            e["name"],
            e["verb"],
            e["joint"],
            opening,
            1.0 if opening else -1.0,
            turns,
            turns and e["joint"] is None,
            tuple(e.get("using") or ()),
            e.get("doc", ""),
            where_of(e, concept, f"action {e['name']}"),
            e,
        )


@dataclass(frozen=True, eq=False)
class JointSpec(_Entry):
    """A joint of the flattened tree; ``index`` is its place in q (None: fixed)."""

    name: str
    kind: str  # revolute | prismatic | continuous | fixed
    parent: str
    child: str
    doc: str
    index: int | None
    where: str
    entry: Mapping[str, Any] = field(repr=False)

    @property
    def moving(self) -> bool:
        return self.index is not None

    @property
    def turns(self) -> bool:
        """A revolute or continuous joint: something a hand can twist."""
        return self.kind in ("revolute", "continuous")

    @staticmethod
    def of(e: Mapping[str, Any], concept: Mapping[str, Any]) -> JointSpec:
        return JointSpec(
            e["name"],
            e["kind"],
            e["parent"],
            e["child"],
            e.get("doc", ""),
            e["index"],
            where_of(e, concept, f"joint {e['name']}"),
            e,
        )


@dataclass(frozen=True)
class LinkSpec:
    """A rigid link of the flattened tree."""

    name: str
    doc: str


@dataclass(frozen=True)
class PartSpec:
    """A part the concept contains: its qualified name and the concept it instantiates."""

    name: str
    concept: str
