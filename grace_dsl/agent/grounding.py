"""Scene grounding: the words of a clause -> one moving part of one scene object, and a target.

Each scene object's moving joints that have actions become *units* (a drawer, a door, a lid):
the object, the part, the joint, its opening and closing actions, the joint's range and the world
position of the handle the opening action grasps. A unit answers to a bag of nouns: its part's
words (``drawer1`` -> "drawer", a ``leaf`` is a "door"), its grasps' parts ("handle"), the scene
object's name and its concept's nouns (``lexicon.concept_phrases``).

A clause picks the units whose bag holds all its nouns and whose actions fit its verb, then
filters them by its selectors, geometrically:

- top/bottom: the highest/lowest handle in the world (z); handles within ``TIE`` (3 cm) of each
  other are level;
- left/right: as seen by someone standing in front of the object and facing it (the robot's
  view), so an object's left door is the one on the viewer's left; candidates on objects that
  face different ways cannot be told left from right, which is an error;
- middle: the median of an odd number of rows (or, if all are level, of columns);
- first/second/third/last: counted top to bottom if the candidates differ in height, else left
  to right.

What is left must be one unit; otherwise ``ParseError`` says which parts match and how to tell
them apart. A clause with no nouns ("then the bottom one") reuses the previous clause's nouns;
"it" is the previous clause's unit; a plain "the drawer" that matches several, one of which an
earlier clause named, is that one (the plan notes it).

Targets and their conditions (the verification a simulator checks), with r the joint's range:
open: q >= lo + 0.5 r (the simulation benchmark's strict criterion); close: q <= lo + 0.05 r;
``fraction`` f ("halfway" is 0.5): |q - (lo + f r)| <= 0.1 r; ``delta`` v ("by 30 degrees",
"a bit" = 0.2 r) from the value the joint has after the earlier steps: within max(0.25 v, 0.05 r)
of it. Ranges clip every interval.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.agent.errors import ParseError
from grace_dsl.agent.grammar import Amount, Clause
from grace_dsl.agent.lexicon import SYNONYMS, Lexicon, concept_phrases, part_words, words_of
from grace_dsl.agent.plan import Condition, ObjectNode, Plan, SceneSpec, SubTask, Target
from grace_dsl.agent.scene_file import world_instances

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Concept, Library

TIE = 0.03  # m: handles closer than this in height (or sideways) are level
OPEN_GOAL = 0.5  # open: at least this fraction of the range (the simulator's strict criterion)
CLOSE_GOAL = 0.05  # close: at most this fraction of the range
FRACTION_TOL = 0.1  # of the range, either side of a fraction target
BIT = 0.2  # "a bit": this fraction of the range
DELTA_TOL = (0.25, 0.05)  # a delta's tolerance: max(0.25 |v|, 0.05 r)


@dataclass(frozen=True)
class Unit:
    """One moving part of a scene object that a clause can name."""

    object: str
    concept: str
    part: str
    joint: str
    kind: str  # "prismatic", "revolute" or "continuous"
    open_action: str | None
    close_action: str | None
    actions: Mapping[str, str]  # every action on this joint -> its sense
    lo: float
    hi: float
    q0: float  # the joint's value in the scene
    position: tuple[float, float, float]  # the handle (or the part), world
    front: tuple[float, float, float]  # the object's front direction, world
    nouns: frozenset[str] = field(default_factory=frozenset)

    @property
    def label(self) -> str:
        return f"{self.object}: {self.part}"

    @property
    def openable(self) -> bool:
        """Whether "open"/"close" apply (its actions are an open and a close, not a press)."""
        return self.open_action is not None and self.close_action is not None

    def left_coordinate(self) -> float:
        """How far to the left the handle is, seen from in front of the object facing it."""
        f = np.asarray(self.front)
        left = np.cross([0.0, 0.0, 1.0], -f)  # the viewer faces -front; up x forward = left
        return float(np.dot(self.position, left))


@dataclass(frozen=True)
class GroundedScene:
    """A scene's units and the words that name them."""

    scene: SceneSpec
    units: tuple[Unit, ...]
    concepts: Mapping[str, str]  # object -> concept

    @property
    def nouns(self) -> frozenset[str]:
        return frozenset().union(*(u.nouns for u in self.units))

    def describe(self) -> str:
        return ", ".join(f"{o.name} ({o.concept})" for o in self.scene.objects)


_CACHE: dict[tuple[str, int], GroundedScene] = {}


def ground_scene(scene: SceneSpec, lib: Library) -> GroundedScene:
    """The scene's units (cached per scene content and library: placing objects meshes them)."""
    from grace_dsl.agent.scene_file import scene_to_data

    key = (json.dumps(scene_to_data(scene), sort_keys=True), id(lib))
    if key not in _CACHE:
        instances = world_instances(scene, lib)
        units = []
        for obj in scene.objects:
            units += _units(obj.name, lib[obj.concept], instances[obj.name], obj.params)
        _CACHE[key] = GroundedScene(scene, tuple(units), {o.name: o.concept for o in scene.objects})
    return _CACHE[key]


def _object_nouns(name: str, concept: Concept) -> set[str]:
    c = {"name": concept.name, "doc": concept.doc}
    phrases = concept_phrases(c) | {words_of(name)} | set(words_of(name).split())
    for word, targets in SYNONYMS.items():
        if any(t in phrases for t in targets):
            phrases.add(word)
    return {p for p in phrases if p}


def _units(name: str, concept: Concept, inst: Instance, params: Mapping[str, Any]) -> list[Unit]:
    object_nouns = _object_nouns(name, concept)
    limits = inst.joint_limits()
    front = inst.pose[:3, :3] @ np.array([0.0, 0.0, 1.0])
    out = []
    for jname in inst.joints:
        acts = {a["name"]: a["sense"] for a in concept.actions.values() if a["joint"] == jname}
        if not acts:
            continue
        spec = concept.joints[jname]
        part = jname.rsplit(".", 1)[0] if "." in jname else spec["child"]
        opening = _main([a for a, s in acts.items() if s == "opening"], ("open",), part)
        closing = _main([a for a, s in acts.items() if s == "closing"], ("close",), part)
        grasp = concept.actions[opening or next(iter(acts))]["using"]
        nouns = part_words(part) | part_words(spec["child"]) | object_nouns
        for g in grasp:
            if "." in g:
                nouns |= part_words(g.rsplit(".", 1)[0])
        lo, hi = limits[jname]
        out.append(
            Unit(
                object=name,
                concept=concept.name,
                part=part,
                joint=jname,
                kind=spec["kind"],
                open_action=opening if _named(opening, "open") else None,
                close_action=closing if _named(closing, "close") else None,
                actions=acts,
                lo=float(lo),
                hi=float(hi),
                q0=float(inst.joints[jname]),
                position=_handle(inst, grasp, spec["child"]),
                front=(float(front[0]), float(front[1]), float(front[2])),
                nouns=frozenset(nouns),
            )
        )
    return out


def _main(names: list[str], prefixes: tuple[str, ...], part: str) -> str | None:
    """The action a plain "open"/"close" means: one whose last name starts so, the part's own
    (``drawer1.open`` before ``open1``) and then the shortest."""
    named = [n for n in names if n.rsplit(".", 1)[-1].startswith(prefixes)]
    pool = named or names
    key = lambda n: (not n.startswith(part + "."), len(n), n)  # noqa: E731
    return min(pool, key=key) if pool else None


def _named(action: str | None, word: str) -> bool:
    return action is not None and word in action.rsplit(".", 1)[-1]


def _handle(inst: Instance, grasps: Sequence[str], link: str) -> tuple[float, float, float]:
    """Where the opening action grasps (its first grasp at its default free values), or the
    moving link's origin for an action without a grasp."""
    for g in grasps:
        try:
            p = inst.grasp(g)[:3, 3]
        except Exception:  # a grasp that needs free values it has no default for
            continue
        return (float(p[0]), float(p[1]), float(p[2]))
    p = inst.link_pose(link)[:3, 3]
    return (float(p[0]), float(p[1]), float(p[2]))


# ---- clauses -> sub-tasks ----------------------------------------------------------------------


@dataclass
class _State:
    """What the earlier clauses fixed: the last unit, the units named, the joints' values."""

    last: Unit | None = None
    named: list[Unit] = field(default_factory=list)
    nouns: tuple[str, ...] = ()
    q: dict[tuple[str, str], float] = field(default_factory=dict)
    verb: tuple[str | None, str | None] = (None, None)


def build_plan(
    instruction: str, clauses: Sequence[Clause], grounded: GroundedScene, lexicon: Lexicon
) -> Plan:
    """The plan of ``clauses`` in ``grounded``; raises ``ParseError`` rather than guess."""
    if not clauses:
        raise ParseError(f"{instruction!r}: there is nothing to do in it")
    state = _State(q={(u.object, u.joint): u.q0 for u in grounded.units})
    subtasks: list[SubTask] = []
    notes: list[str] = []
    for k, clause in enumerate(clauses):
        _refuse_unknown(clause, grounded, lexicon)
        if clause.verb is None:
            if state.verb[0] is None:
                raise ParseError(
                    f"{clause.text!r}: no action in it; say what to do (open, close, ...)"
                )
            clause = replace(clause, verb=state.verb[0], intent=state.verb[1])
        if not clause.nouns and not clause.pronoun and not state.nouns:
            # "open the top and bottom drawers": the noun comes in a later clause
            later = next((c.nouns for c in clauses[k + 1 :] if c.nouns), ())
            clause = replace(clause, nouns=later)
        units, why = resolve_all(clause, grounded, state, lexicon)
        notes += list(clause.notes) + ([why] if why else [])
        for unit in units:
            step = subtask(clause, unit, state.q[(unit.object, unit.joint)])
            subtasks.append(step)
            key = (unit.object, unit.joint)
            state.q[key] = nominal(step.target, unit, state.q[key], step.action, unit.actions)
            state.named.append(unit)
        state.last, state.verb = units[-1], (clause.verb, clause.intent)
        state.nouns = clause.nouns or state.nouns
    return assemble(instruction, subtasks, grounded, notes)


def resolve_all(
    clause: Clause, grounded: GroundedScene, state: _State, lexicon: Lexicon
) -> tuple[list[Unit], str]:
    """The units ``clause`` names: one, or with "all"/"every"/"both" each that matches (in
    order along the direction they spread), and a note when context decided."""
    if not clause.every:
        unit, why = resolve(clause, grounded, state, lexicon)
        return [unit], why
    if not clause.nouns:
        raise ParseError(f"{clause.text!r}: all of what? name them (all the drawers)")
    found = [u for u in grounded.units if all(n in u.nouns for n in clause.nouns)]
    if not found:
        raise ParseError(_missing(clause, clause.nouns, grounded, lexicon))
    found = _by_verb(clause, found, clause.nouns)
    if clause.selectors or clause.ordinal is not None:
        found = select(found, clause.selectors, clause.ordinal, " ".join(clause.nouns))
    ordered = [u for group in _rows(found) for u in group]
    return ordered, f"{clause.text!r}: {len(ordered)} parts, " + ", ".join(u.label for u in ordered)


def assemble(
    instruction: str,
    subtasks: Sequence[SubTask],
    grounded: GroundedScene,
    notes: Sequence[str] = (),
    relations: Mapping[str, Sequence[tuple[str, str]]] | None = None,
) -> Plan:
    """The plan of ``subtasks``: its object graph (with ``relations`` by object when given,
    else left/right computed from the scene) and its notes."""
    objects = _graph(subtasks, grounded)
    if relations is not None:
        objects = tuple(replace(o, relations=tuple(relations.get(o.name, ()))) for o in objects)
    return Plan(
        instruction=instruction,
        objects=objects,
        subtasks=tuple(subtasks),
        notes=tuple(dict.fromkeys(notes)),
    )


def _refuse_unknown(clause: Clause, grounded: GroundedScene, lexicon: Lexicon) -> None:
    for word, close in clause.ambiguous:
        raise ParseError(
            f"{clause.text!r}: I do not know {word!r}; did you mean "
            + " or ".join(repr(c) for c in close)
            + "?"
        )
    if not clause.unknown:
        return
    word = clause.unknown[0]
    if not clause.nouns and not clause.pronoun:
        raise ParseError(
            f"{clause.text!r}: no concept in the library matches {word!r}"
            f"; this scene has {grounded.describe()}"
        )
    raise ParseError(
        f"{clause.text!r}: I do not know the word {word!r}; rephrase without it "
        "(selectors I know: top, bottom, left, right, middle, first, second, third, last)"
    )


def resolve(
    clause: Clause, grounded: GroundedScene, state: _State, lexicon: Lexicon
) -> tuple[Unit, str]:
    """The one unit ``clause`` names, and a note when context decided it."""
    nouns = clause.nouns
    if clause.pronoun and not nouns:
        if state.last is None:
            raise ParseError(f"{clause.text!r}: 'it' refers to nothing named before it")
        last = state.last
        if _fits(clause, last):
            return last, ""
        # "unlatch the door, then open it": the same object's part that can do it
        same = [u for u in grounded.units if u.object == last.object and _fits(clause, u)]
        if len(same) == 1:
            return same[0], f"'it' in {clause.text!r} taken as {same[0].label}"
        raise ParseError(
            f"{clause.text!r}: 'it' is {last.label}, which cannot be '{clause.verb}'-ed; "
            "name the part"
        )
    if not nouns:
        if not state.nouns:
            raise ParseError(f"{clause.text!r}: which object? name it (the drawer, the door)")
        nouns = state.nouns
    found = [u for u in grounded.units if all(n in u.nouns for n in nouns)]
    if not found:
        raise ParseError(_missing(clause, nouns, grounded, lexicon))
    found = _by_verb(clause, found, nouns)
    what = " ".join(nouns)
    if clause.selectors or clause.ordinal is not None:
        found = select(found, clause.selectors, clause.ordinal, what)
    if len(found) > 1:
        named = {u.label for u in state.named}
        earlier = [u for u in found if u.label in named]
        if len(earlier) == 1:
            return earlier[
                0
            ], f"'{what}' in {clause.text!r} taken as {earlier[0].label}, named before"
        raise ParseError(_ambiguous(what, found, clause))
    return found[0], ""


def _fits(clause: Clause, unit: Unit) -> bool:
    """Whether ``unit`` can do the clause's verb."""
    if clause.intent == "action":
        return any(_phrase(a) == clause.verb for a in unit.actions)
    return unit.openable


def _by_verb(clause: Clause, units: list[Unit], nouns: Sequence[str]) -> list[Unit]:
    fit = [u for u in units if _fits(clause, u)]
    if fit:
        return fit
    can = sorted({_phrase(a) for u in units for a in u.actions})
    raise ParseError(
        f"{clause.text!r}: the {' '.join(nouns)} cannot be '{clause.verb}'-ed; "
        f"its actions: {', '.join(can)}"
    )


def _phrase(action: str) -> str:
    return words_of(action.rsplit(".", 1)[-1])


def _missing(clause: Clause, nouns: Sequence[str], grounded: GroundedScene, lex: Lexicon) -> str:
    have = grounded.nouns
    for n in nouns:
        if n in have:
            continue
        if n in lex.concept_nouns:
            return (
                f"{clause.text!r}: there is no {n} in scene {grounded.scene.name!r}; "
                f"it has {grounded.describe()}"
            )
        if n in lex.part_nouns:
            return f"{clause.text!r}: nothing in scene {grounded.scene.name!r} has a {n}"
        return f"{clause.text!r}: no concept in the library matches {n!r}"
    return (
        f"{clause.text!r}: nothing in scene {grounded.scene.name!r} is "
        + " and ".join(f"a {n!r}" for n in nouns)
        + f" at once; it has {grounded.describe()}"
    )


def _ambiguous(what: str, units: Sequence[Unit], clause: Clause) -> str:
    said = " ".join(clause.selectors) + (f" #{clause.ordinal}" if clause.ordinal else "")
    lead = (
        f"{len(units)} parts are '{said.strip()} {what}'"
        if said
        else f"{len(units)} parts match '{what}'"
    )
    hints = _hints(units)
    return f"{clause.text!r}: {lead}: {'; '.join(u.label for u in units)}. Which one? " + (
        f"say {hints}"
        if hints
        else "name the object (" + ", ".join(sorted({u.object for u in units})) + ")"
    )


def _hints(units: Sequence[Unit]) -> str:
    """The selectors that pick exactly one of ``units`` (each tried alone), and the objects."""
    words = []
    for s in ("top", "middle", "bottom", "left", "right"):
        try:
            if len(select(units, (s,), None, "")) == 1:
                words.append(s)
        except ParseError:
            continue
    out = [" or ".join(f"'{w}'" for w in words)] if words else []
    objects = sorted({u.object for u in units})
    if len(objects) > 1:
        out.append("the object (" + ", ".join(objects) + ")")
    return ", or ".join(out)


def _same_facing(units: Sequence[Unit]) -> bool:
    f0 = np.asarray(units[0].front)
    return all(float(np.dot(f0, u.front)) > 0.999 for u in units)


def select(
    units: Sequence[Unit], selectors: Iterable[str], ordinal: int | None, what: str
) -> list[Unit]:
    """``units`` filtered by selectors (in the order given) and then an ordinal."""
    out = list(units)
    for s in selectors:
        if s in ("left", "right") and not _same_facing(out):
            raise ParseError(
                f"'{s} {what}': the {what} candidates ({', '.join(u.label for u in out)}) face "
                "different ways, so left and right differ between them; name the object"
            )
        if s == "top":
            out = _extreme(out, lambda u: u.position[2])
        elif s == "bottom":
            out = _extreme(out, lambda u: -u.position[2])
        elif s == "left":
            out = _extreme(out, lambda u: u.left_coordinate())
        elif s == "right":
            out = _extreme(out, lambda u: -u.left_coordinate())
        elif s == "middle":
            out = _middle(out, what)
    if ordinal is not None:
        groups = _rows(out)
        k = ordinal - 1 if ordinal > 0 else len(groups) - 1
        if not 0 <= k < len(groups):
            raise ParseError(
                f"there is no {_ordinal_word(ordinal)} {what}: only {len(groups)} "
                f"({', '.join(u.label for u in out)})"
            )
        out = groups[k]
    return out


def _extreme(units: list[Unit], key: Any) -> list[Unit]:
    best = max(key(u) for u in units)
    return [u for u in units if key(u) >= best - TIE]


def _rows(units: Sequence[Unit]) -> list[list[Unit]]:
    """Groups of level units along the direction they spread most: top to bottom (a chest's
    drawers) or left to right (doors side by side, when all face the same way)."""
    z = [u.position[2] for u in units]
    x = [u.left_coordinate() for u in units] if _same_facing(units) else [0.0]
    vertical = max(z) - min(z) > TIE and max(z) - min(z) >= max(x) - min(x)

    def key(u: Unit) -> float:
        return -u.position[2] if vertical else -u.left_coordinate()

    groups: list[list[Unit]] = []
    for u in sorted(units, key=key):
        if groups and abs(key(u) - key(groups[-1][0])) <= TIE:
            groups[-1].append(u)
        else:
            groups.append([u])
    return groups


def _middle(units: list[Unit], what: str) -> list[Unit]:
    groups = _rows(units)
    if len(groups) % 2 == 0 or len(groups) < 3:
        raise ParseError(
            f"'middle {what}': {len(groups)} rows of {what} ({', '.join(u.label for u in units)}) "
            "have no middle one; say top, bottom, left, right or first/second/third"
        )
    return groups[len(groups) // 2]


def _ordinal_word(k: int) -> str:
    return {1: "first", 2: "second", 3: "third", 4: "fourth", -1: "last"}.get(k, f"#{k}")


# ---- targets and conditions ---------------------------------------------------------------------


def subtask(clause: Clause, unit: Unit, q_now: float) -> SubTask:
    """The sub-task of ``clause`` on ``unit`` with the joint at ``q_now`` before it."""
    if clause.intent == "action":
        action = next(a for a in unit.actions if _phrase(a) == clause.verb)
        opening = unit.actions[action] == "opening"
    else:
        opening = clause.intent == "open"
        chosen = unit.open_action if opening else unit.close_action
        assert chosen is not None  # openable units have both
        action = chosen
    target = _target(clause.amount, opening, unit, clause.text)
    return make_subtask(clause.text, unit, action, target, q_now)


def make_subtask(text: str, unit: Unit, action: str, target: Target, q_now: float) -> SubTask:
    """A sub-task moving ``unit`` by ``action`` to ``target`` from ``q_now``, with its
    condition (any parser that has picked a unit, an action and a target ends here)."""
    opening = unit.actions[action] == "opening"
    return SubTask(
        text=text,
        object=unit.object,
        concept=unit.concept,
        part=unit.part,
        action=action,
        joint=unit.joint,
        target=target,
        condition=condition(target, unit, q_now, opening),
    )


def _target(amount: Amount | None, opening: bool, unit: Unit, text: str) -> Target:
    r = unit.hi - unit.lo
    finite = math.isfinite(r)
    if amount is None or amount.kind == "full":
        if not finite:
            raise ParseError(f"{text!r}: {unit.label} turns without end; say by how much")
        return Target("open" if opening else "close")
    if amount.kind == "half":
        _need_range(finite, unit, text, "halfway")
        return Target("fraction", 0.5)
    if amount.kind == "bit":
        _need_range(finite, unit, text, "a bit")
        return Target("delta", round(BIT * r, 6))
    want = "angle" if unit.kind in ("revolute", "continuous") else "length"
    if amount.dim == "fraction":
        if amount.kind == "by":
            _need_range(finite, unit, text, "a percentage")
            return Target("delta", round(amount.value * r, 6))
        return Target("fraction", _unit_interval(amount.value, text))
    if amount.dim != want:
        turns = "turns" if want == "angle" else "slides"
        raise ParseError(
            f"{text!r}: {unit.label} {turns}; give {'an' if want == 'angle' else 'a'} {want} ("
            + ("degrees" if want == "angle" else "cm or mm")
            + f"), not {'degrees' if amount.dim == 'angle' else 'a length'}"
        )
    if amount.kind == "by":
        return Target("delta", round(amount.value, 6))
    _need_range(finite, unit, text, "an absolute value")
    return Target("fraction", _unit_interval(round((amount.value - unit.lo) / r, 6), text))


def _need_range(finite: bool, unit: Unit, text: str, what: str) -> None:
    if not finite:
        raise ParseError(f"{text!r}: {unit.label} turns without end, so {what} means nothing")


def _unit_interval(f: float, text: str) -> float:
    if not 0.0 <= f <= 1.0:
        raise ParseError(f"{text!r}: that is {f:.0%} of the range; it must be within 0..100 %")
    return f


def nominal(
    target: Target, unit: Unit, q_now: float, action: str, senses: Mapping[str, str]
) -> float:
    """The value the joint is meant to have after ``target`` by ``action``: the ends for
    open/close, the point of a fraction, the start moved by a delta (clipped to the range)."""
    if target.kind == "open":
        return unit.hi
    if target.kind == "close":
        return unit.lo
    if target.kind == "fraction":
        return unit.lo + target.value * (unit.hi - unit.lo)
    sign = 1.0 if senses.get(action) == "opening" else -1.0
    return min(max(q_now + sign * target.value, unit.lo), unit.hi)


def condition(target: Target, unit: Unit, q_now: float, opening: bool) -> Condition:
    lo, hi = unit.lo, unit.hi
    r = hi - lo
    if target.kind == "open":
        a, b = lo + OPEN_GOAL * r, hi
    elif target.kind == "close":
        a, b = lo, lo + CLOSE_GOAL * r
    elif target.kind == "fraction":
        mid = lo + target.value * r
        a, b = mid - FRACTION_TOL * r, mid + FRACTION_TOL * r
    else:
        end = q_now + (target.value if opening else -target.value)
        end = min(max(end, lo), hi)
        tol = max(DELTA_TOL[0] * target.value, DELTA_TOL[1] * r if math.isfinite(r) else 0.0)
        a, b = end - tol, end + tol
    return Condition(unit.object, unit.joint, round(max(a, lo), 6), round(min(b, hi), 6))


def final_conditions(plan: Plan) -> dict[tuple[str, str], Condition]:
    """The last condition on each (object, joint): what must hold when the plan is done (an
    earlier step's condition on a joint that a later step moves again need not)."""
    return {(s.object, s.joint): s.condition for s in plan.subtasks}


def _graph(subtasks: Sequence[SubTask], grounded: GroundedScene) -> tuple[ObjectNode, ...]:
    """The plan's object nodes (in the order first named) with the parts it names and their
    left/right relations (seen from the front) among objects that face the same way."""
    order = list(dict.fromkeys(s.object for s in subtasks))
    parts = {o: tuple(dict.fromkeys(s.part for s in subtasks if s.object == o)) for o in order}
    where = {o.name: o for o in grounded.scene.objects}
    nodes = []
    for name in order:
        rel = []
        me = where[name]
        for other in order:
            you = where[other]
            if other == name or abs(math.remainder(me.yaw - you.yaw, 2 * math.pi)) > 1e-3:
                continue
            left = np.array([math.sin(me.yaw), -math.cos(me.yaw)])  # facing them from the front
            side = float(np.dot(np.subtract(me.position[:2], you.position[:2]), left))
            rel.append(("left_of" if side > 0 else "right_of", other))
        nodes.append(ObjectNode(name, grounded.concepts[name], parts[name], tuple(rel)))
    return tuple(nodes)
