"""Machine-check a concept over random parameter draws (``eacc verify``).

A concept can compile, type-check and still be wrong: a grasp a centimetre off its handle, a width
the hand cannot open to, an action whose force drives the joint backwards. ``verify_concept`` draws
parameters uniformly inside their ranges (repairing draws that break a ``require`` by redrawing
parameters it depends on, ``runtime/draws.py``, and rejecting those still broken), places each
instance at a random world pose, and at its joints closed (q = 0) and at random values checks,
for every grasp family (parts' grasps included) at several free-parameter values:

``near``         the origin lies within 5 mm of the part it grasps (signed distance of the shapes
                 of the grasp's link, only the part's own shapes for a part's grasp); for a hook,
                 the middle of the side its closed fingers rest on (origin + x * half the pads'
                 thickness along x): its wall is on +x, and its fingertips hang free;
``between``      pinch: material lies between the pads, on the segment between their inner faces
                 through the origin;
``width``        pinch: 0 < width <= the gripper's opening (the declared width, else the width of
                 material along +y at the origin);
``penetration``  the pads, closed to the width (pinch) or fully (hook, push, press), enter no shape
                 of the instance by more than 2 mm;
``into``         push and press: +z points into the material (the part's signed distance
                 decreases along +z at the origin);

and for every action, for the grasps it uses (``using``, else the grasps on the link it moves):

``power``        along a joint: the force has positive power on the joint's motion in the action's
                 sense (cosine between the force and the grasp point's velocity per unit dq, times
                 +1 opening / -1 closing, is > 0);
``unit_force``   toward a fixed direction: the force is a unit vector;
``follow``       ``inst.follow`` keeps the grasp attached to its link: G_k = L(q_k) L(q_0)^-1 G_0
                 to 1e-6, with L the link pose computed independently.

A grasp family with a ``when`` condition is checked (with the actions that use it) only at joint
states where the condition holds: the closed joints and the random values when it holds there,
else up to ``WHEN_TRIES`` more random joint states per draw until it does. A family whose
condition held in no draw fails

``applies``      the ``when`` held at none of the joint states tried (a condition that cannot hold
                 in the ranges, or one much narrower than them).

Before those, every draw must be computable, or it fails instead of crashing the run:

``shape``        every shape's arguments describe a solid and its pose is finite (a ``RectRing``
                 whose opening closes up fails here: member ``shape (file:line)``);
``finite``       every grasp pose, width and force is finite (a formula that divides by a
                 parameter whose range reaches 0 fails here: member ``grasp (file:line)``).

Each continuous parameter takes one of its range's ends in ``1 / ENDS`` of the draws (each end
half of those), so formulas that break at a bound are found.

At a ``scale`` other than 1 (``eacc verify --scale 0.3,2``) every length parameter's range is
multiplied by it (angles, counts and choices keep theirs) and the instances are made with
``ranges="valid"``: the concept must stay well-formed and pass every check on objects that size.
The gripper keeps its size (a robot's hand does not grow with the object): a pinch wider than it
opens is its limit, not the concept's, and is noted in the report rather than failed.
When the scaled defaults break a ``require`` the concept is not drawn at that scale; the report
names the requirement that forbids it (``ConceptReport.forbidden``), which is not a failure.

Each failure keeps the values that caused it, in display units (mm, deg) and in SI (to reproduce
it with ``concept.instantiate``). Per draw, the worst sample of each check and member is kept.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.compiler.types import format_si
from grace_dsl.runtime.concept import ParamSpec
from grace_dsl.runtime.draws import draw_valid
from grace_dsl.runtime.errors import (
    EvaluationError,
    GraceError,
    ParameterError,
    RequirementError,
)
from grace_dsl.runtime.gripper import Gripper, finger_points
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.masks import presence
from grace_dsl.runtime.sampling import spread
from grace_dsl.runtime.shapes import ShapeError, ShapeTree, parameter_text
from grace_dsl.runtime.specs import ActionSpec
from grace_dsl.tolerances import RANGE_SLACK

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Concept, Library

NEAR = 0.005  # m: how far a grasp's origin may lie from the part it grasps
PENETRATION = 0.002  # m: how deep a pad may enter a shape (the rubber pads give that much)
ATTACHED = 1e-6  # how far a followed grasp may drift from its link (pose entries, m / unitless)
TOUCH = 1e-6  # m: a surface the segment between the pads touches counts as material
UNIT = 1e-9  # tolerance on |force| = 1
FREE_SAMPLES = 5  # free-parameter values per grasp family (spread over its box)
FOLLOW_STEPS = 8
MAX_ATTEMPTS = 50  # draws attempted per requested draw before giving up on a tight `require`
ENDS = 10  # one continuous parameter value in ENDS sits on an end of its range
WHEN_TRIES = 16  # joint states drawn per draw for a grasp whose `when` held at neither state

CHECKS = (
    "shape",
    "finite",
    "near",
    "between",
    "width",
    "penetration",
    "into",
    "power",
    "unit_force",
    "follow",
    "applies",
)


@dataclass(frozen=True)
class Failure:
    """One check that failed on one draw: the worst sample of that draw."""

    concept: str
    check: str
    member: str  # the grasp, or "action/grasp" for action checks
    params: dict[str, str]  # parameters, joint values (`q.<joint>`) and free grasp parameters
    value: float  # measured, in ``unit``
    limit: float  # in ``unit``
    unit: str  # "mm", "" ...
    message: str
    si: dict[str, Any] = field(default_factory=dict)  # params, joints, free, pose: to reproduce

    def to_json(self) -> dict[str, Any]:
        return {
            "concept": self.concept,
            "check": self.check,
            "member": self.member,
            "params": dict(self.params),
            "value": self.value,
            "limit": self.limit,
            "unit": self.unit,
            "message": self.message,
            "si": self.si,
        }

    @staticmethod
    def from_json(d: Mapping[str, Any]) -> Failure:
        return Failure(
            d["concept"],
            d["check"],
            d["member"],
            dict(d["params"]),
            float(d["value"]),
            float(d["limit"]),
            d["unit"],
            d["message"],
            dict(d.get("si", {})),
        )


@dataclass(frozen=True)
class ConceptReport:
    """The outcome of verifying one concept."""

    concept: str
    draws: int  # accepted draws (each satisfies every `require`)
    attempts: int  # draws made, rejected ones included
    evaluated: dict[str, int]  # check -> samples evaluated
    failures: tuple[Failure, ...]
    note: str = ""  # e.g. why fewer draws than asked were accepted
    scale: float = 1.0  # the factor on every length parameter's range
    forbidden: str = ""  # the requirement the scaled defaults break: not drawn at this scale

    @property
    def rejected(self) -> int:
        return self.attempts - self.draws

    @property
    def ok(self) -> bool:
        return not self.failures

    def to_json(self) -> dict[str, Any]:
        return {
            "concept": self.concept,
            "ok": self.ok,
            "draws": self.draws,
            "attempts": self.attempts,
            "rejected": self.rejected,
            "evaluated": dict(self.evaluated),
            "note": self.note,
            "scale": self.scale,
            "forbidden": self.forbidden,
            "failures": [f.to_json() for f in self.failures],
        }

    @staticmethod
    def from_json(d: Mapping[str, Any]) -> ConceptReport:
        return ConceptReport(
            d["concept"],
            int(d["draws"]),
            int(d["attempts"]),
            {k: int(v) for k, v in d["evaluated"].items()},
            tuple(Failure.from_json(f) for f in d["failures"]),
            d.get("note", ""),
            float(d.get("scale", 1.0)),
            d.get("forbidden", ""),
        )


@dataclass(frozen=True)
class VerifyReport:
    """Every concept verified in one run, with the settings that reproduce it."""

    draws: int
    seed: int
    gripper: str
    concepts: tuple[ConceptReport, ...]
    scale: float = 1.0

    @property
    def ok(self) -> bool:
        return all(c.ok for c in self.concepts)

    @property
    def failures(self) -> tuple[Failure, ...]:
        return tuple(f for c in self.concepts for f in c.failures)

    def to_json(self) -> dict[str, Any]:
        return {
            "ok": self.ok,
            "draws": self.draws,
            "seed": self.seed,
            "gripper": self.gripper,
            "scale": self.scale,
            "concepts": [c.to_json() for c in self.concepts],
        }

    @staticmethod
    def from_json(d: Mapping[str, Any]) -> VerifyReport:
        return VerifyReport(
            int(d["draws"]),
            int(d["seed"]),
            d["gripper"],
            tuple(ConceptReport.from_json(c) for c in d["concepts"]),
            float(d.get("scale", 1.0)),
        )


# ---- entry points ------------------------------------------------------------------------------


def verify_library(
    lib: Library,
    names: Sequence[str] | None = None,
    draws: int = 200,
    seed: int = 0,
    gripper: Gripper | None = None,
    progress: Callable[[str, int, int], None] | None = None,
    scale: float = 1.0,
) -> VerifyReport:
    """Verify ``names`` (default: every concept that is not a primitive) of ``lib``, with every
    length range multiplied by ``scale`` (see the module docstring).

    Each concept gets its own stream of draws derived from ``seed`` and its name, so verifying a
    subset gives the same draws as verifying the whole library. ``progress(name, done, total)``
    is called before each concept.
    """
    scale = check_scale(scale)
    gripper = gripper or Gripper.panda()
    chosen = list(names) if names is not None else verifiable(lib)
    reports = []
    for i, name in enumerate(chosen):
        if progress is not None:
            progress(name, i, len(chosen))
        seed_i = concept_seed(seed, name)
        reports.append(verify_concept(lib[name], draws, seed_i, gripper, scale=scale))
    if progress is not None and chosen:
        progress(chosen[-1], len(chosen), len(chosen))
    return VerifyReport(draws, seed, gripper.name, tuple(reports), scale)


def check_scale(scale: Any) -> float:
    """A size factor: a finite number > 0, or a ``ParameterError``."""
    if isinstance(scale, bool) or not isinstance(scale, (int, float, np.floating, np.integer)):
        raise ParameterError(f"scale must be a number > 0, not {scale!r:.60}")
    value = float(scale)
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"scale must be a finite number > 0, got {value!r}")
    return value


def scaled_specs(concept: Concept, scale: float) -> tuple[ParamSpec, ...]:
    """The parameters with every length range and default multiplied by ``scale``."""
    if scale == 1.0:
        return concept.params
    return tuple(
        replace(p, lo=_times(p.lo, scale), hi=_times(p.hi, scale), default=_times(p.default, scale))
        if p.dim == "length" and p.kind in ("num", "vec")
        else p
        for p in concept.params
    )


def _times(value: Any, scale: float) -> Any:
    if isinstance(value, tuple):
        return tuple(float(v) * scale for v in value)
    return None if value is None else float(value) * scale


def scaled_defaults(concept: Concept, scale: float) -> dict[str, Any]:
    """The defaults with every length multiplied by ``scale`` (choices by name)."""
    out = concept.defaults()
    for q in concept.params:  # defaults() gives a bool as 0.0/1.0, which instantiate refuses
        if q.kind == "bool":
            out[q.name] = bool(out[q.name])
    for p in scaled_specs(concept, scale):
        if p.kind in ("num", "vec") and p.dim == "length":
            out[p.name] = p.default
    return out


def forbidding_requirement(concept: Concept, scale: float) -> str:
    """Why the scaled defaults cannot be instantiated (the violated requirements), or ''."""
    try:
        concept.instantiate(ranges="valid", params=scaled_defaults(concept, scale))
    except RequirementError as exc:
        return str(exc).split(": the parameters violate ", 1)[-1]
    except ParameterError:
        return ""  # a broken shape or range: the draws report it as a failure
    return ""


def verifiable(lib: Library) -> list[str]:
    """The concepts of a library that have something to verify (primitives have not)."""
    return [n for n in lib if lib[n].entry["kind"] != "primitive"]


def concept_seed(seed: int, name: str) -> int:
    """A per-concept seed: stable across runs and independent of which others are verified."""
    return int(np.random.SeedSequence([seed, zlib.crc32(name.encode())]).generate_state(1)[0])


def verify_concept(
    concept: Concept,
    draws: int = 200,
    seed: int = 0,
    gripper: Gripper | None = None,
    scale: float = 1.0,
) -> ConceptReport:
    """Draw ``draws`` valid parameter sets of ``concept`` (every length range times ``scale``)
    and run every check on each (see the module docstring). Draws that break a ``require`` are
    redrawn, up to ``MAX_ATTEMPTS`` times ``draws`` attempts in all; the report says when fewer
    were accepted."""
    if draws < 1:
        raise ParameterError(f"draws must be a positive number, got {draws}")
    scale = check_scale(scale)
    gripper = gripper or Gripper.panda()
    ranges = "typical" if scale == 1.0 else "valid"
    if scale != 1.0:
        forbidden = forbidding_requirement(concept, scale)
        if forbidden:
            note = f"not drawn at {scale:g}x: the scaled defaults violate {forbidden}"
            return ConceptReport(
                concept.name, 0, 0, {c: 0 for c in CHECKS}, (), note, scale, forbidden
            )
    specs = scaled_specs(concept, scale)
    rng = np.random.default_rng(seed)
    run = _Run(concept, gripper, rng, scale != 1.0, np.random.default_rng([seed, 1]))
    accepted = attempts = 0
    cap = MAX_ATTEMPTS * draws
    while accepted < draws and attempts < cap:
        attempts += 1
        values = draw_valid(concept, rng, specs, draw_params, ranges)
        pose = random_pose(rng)
        try:
            inst = concept.instantiate(pose=pose, ranges=ranges, params=values)
        except RequirementError:
            continue
        except ParameterError as exc:  # in range, yet refused: a formula or a shape fails
            accepted += 1
            run.refused(values, pose, exc)
            continue
        accepted += 1
        run.check_draw(inst)
    run.never_applied()
    note = ""
    if accepted < draws:
        note = (
            f"only {accepted} of {attempts} draws satisfy the requirements "
            f"({accepted / attempts:.1%}); stopped after {cap} attempts"
        )
    if run.never:
        never = ", ".join(sorted(run.never))
        note = "; ".join(x for x in (note, f"never applies at {scale:g}x: {never}") if x)
    if run.too_wide:
        wide = ", ".join(sorted(run.too_wide))
        note = "; ".join(
            x for x in (note, f"wider than {gripper.name} opens in some draws: {wide}") if x
        )
    return ConceptReport(
        concept.name, accepted, attempts, dict(run.evaluated), run.failures, note, scale
    )


def draw_params(
    concept: Concept, rng: np.random.Generator, specs: Sequence[ParamSpec] | None = None
) -> dict[str, Any]:
    """A value of every parameter, uniform inside its range (per component for vectors), a
    continuous component on one of its range's ends in ``1 / ENDS`` of the draws; ``specs``
    replaces the concept's parameters (``scaled_specs``)."""
    out: dict[str, Any] = {}
    for p in concept.params if specs is None else specs:
        if p.kind == "choice":
            assert p.choices is not None
            out[p.name] = p.choices[int(rng.integers(len(p.choices)))]
        elif p.kind == "bool":
            out[p.name] = bool(rng.integers(2))
        elif p.kind == "int":
            out[p.name] = int(rng.integers(math.ceil(p.lo), math.floor(p.hi) + 1))
        elif p.kind == "vec":
            out[p.name] = tuple(map(float, _uniform_or_end(p.lo, p.hi, rng)))
        else:
            out[p.name] = float(_uniform_or_end(p.lo, p.hi, rng)[0])
    return out


def _uniform_or_end(lo: Any, hi: Any, rng: np.random.Generator) -> np.ndarray:
    """Uniform in [lo, hi] per component; a component is lo or hi, each in 1 / (2 ENDS)."""
    lo, hi = np.atleast_1d(np.asarray(lo, float)), np.atleast_1d(np.asarray(hi, float))
    x = rng.uniform(lo, hi)
    end = rng.integers(2 * ENDS, size=x.shape)
    return np.where(end == 0, lo, np.where(end == 1, hi, x))


def random_pose(rng: np.random.Generator) -> np.ndarray:
    """A rigid transform: a uniform rotation (unit quaternion) and a translation in a 2 m cube."""
    x, y, z, w = rng.normal(size=4)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    m = np.eye(4)
    m[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    m[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return m


# ---- geometry ----------------------------------------------------------------------------------


class _Geometry:
    """Signed distances of one instance's shapes: all of them, or those a grasp holds."""

    def __init__(self, inst: Instance):
        self.inst = inst
        self.tree = ShapeTree(inst)
        self.tree.check()  # every shape's arguments and pose, before any distance
        # world <- concept frame at q = 0, per link: where each link's shapes are now
        self.motions = {
            link: inst.link_pose(link) @ np.linalg.inv(self.tree.link_pose(link))
            for link in inst.links  # the copies its counts leave out have no geometry
        }
        self._inverse = {k: np.linalg.inv(m) for k, m in self.motions.items()}

    def sdf(self, points: np.ndarray, shapes: Sequence[str] | None = None) -> np.ndarray:
        names = self.tree.outermost() if shapes is None else shapes
        if not names:
            return np.full(len(points), np.inf)
        dists = []
        for name in names:
            inv = self._inverse[self.tree.shapes[name]["link"]]
            local = points @ inv[:3, :3].T + inv[:3, 3]
            dists.append(self.tree.sdf(name, self.tree.placement(name), local))
        return np.min(dists, axis=0)

    def held_shapes(self, grasp: str) -> list[str]:
        """The shapes a grasp holds: those of its link, and of its part for a part's grasp."""
        link = self.inst.concept.grasps[grasp]["link"]
        on_link = self.tree.outermost(link)
        if "." not in grasp:
            return on_link
        prefix = grasp.rsplit(".", 1)[0] + "."
        own = [n for n in on_link if n.startswith(prefix)]
        return own or on_link


# ---- one run -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Sample:
    """A grasp pose and what produced it."""

    grasp: str
    pose: np.ndarray
    free: dict[str, float]


@dataclass(frozen=True)
class _Measure:
    """One check on one sample: whether it passed and by how much it missed."""

    check: str
    ok: bool
    badness: float  # how far from passing, larger is worse (ranks the samples of a draw)
    value: float  # shown in ``unit``
    limit: float
    unit: str
    message: str


def _at_most(check: str, value: float, limit: float, unit: str, message: str) -> _Measure:
    """Passes when value <= limit; lengths come in metres and are shown in mm (unit "mm")."""
    k = 1e3 if unit == "mm" else 1.0
    return _Measure(check, value <= limit, value - limit, value * k, limit * k, unit, message)


class _Run:
    """The checks of one concept, accumulating counts and failures over its draws."""

    def __init__(
        self,
        concept: Concept,
        gripper: Gripper,
        rng: np.random.Generator,
        hand_limits: bool = False,
        when_rng: np.random.Generator | None = None,
    ):
        self.concept, self.gripper, self.rng = concept, gripper, rng
        # at a scale other than 1, a pinch wider than the hand opens is the hand's limit (it
        # does not grow with the object), not the concept's: noted, not failed
        self.hand_limits = hand_limits
        self.too_wide: set[str] = set()
        self.evaluated: dict[str, int] = {c: 0 for c in CHECKS}
        self._failures: list[Failure] = []
        self._worst: dict[tuple[str, str], tuple[float, Failure]] = {}
        self._closed = finger_points(gripper, 0.0)
        self._side = gripper.finger_width / 2  # a hook's bearing side: the pads' +x faces
        # families with a `when`: checked only where it holds; how many draws checked each
        self.conditional = {n for n, g in concept.grasps.items() if g.when is not None}
        self.applied = dict.fromkeys(self.conditional, 0)
        self.present = dict.fromkeys(self.conditional, 0)  # draws that have the family at all
        self.never: set[str] = set()  # at a scale: families whose `when` never held (noted)
        # the joint values drawn for them come from their own stream, so that the draws of
        # parameters and of the two joint states stay those of a concept without a `when`
        self._when_rng = when_rng or np.random.default_rng(0)

    @property
    def failures(self) -> tuple[Failure, ...]:
        return tuple(self._failures)

    def check_draw(self, inst: Instance) -> None:
        """Every check at the closed joints and at random joint values, then each grasp family
        whose ``when`` held at neither at joint values drawn until it holds; per check and
        member, the worst failing sample of the draw is kept. A draw whose shapes or formulas
        cannot be evaluated fails ``shape`` or ``finite`` (with what broke) instead of
        raising."""
        self._worst = {}
        here = presence(inst.concept.entry, inst.params)
        pending = {g for g in self.conditional if here(g)}
        for g in pending:
            self.present[g] += 1
        states = [False, True, *([None] * WHEN_TRIES)]  # None: joints drawn for a `when`
        for moved in states:
            if moved is None and not pending:
                break
            state = inst
            try:
                if moved is None:
                    state = self._random_joints(inst, self._when_rng)
                    only = {g for g in pending if state.grasp_applies(g)}
                    if not only:
                        continue
                    pending -= self._check_state(state, only)
                    continue
                state = self._random_joints(inst) if moved else inst
                pending -= self._check_state(state)
            except ShapeError as exc:
                self._broken(state, "shape", f"{exc.shape} ({exc.where})", str(exc))
                break
            except GraceError as exc:  # a runtime query refused a value the draw produced
                self._broken(state, "finite", self.concept.name, str(exc))
                break
        self._failures += [f for _, f in self._worst.values()]

    def never_applied(self) -> None:
        """An ``applies`` failure for each grasp family whose ``when`` held in none of the
        draws that have it (at the closed joints, random ones, or ``WHEN_TRIES`` more drawn for
        it); a repeated copy or variant option no draw has is not one."""
        for g in sorted(self.conditional):
            if not self.present[g]:
                continue
            self.evaluated["applies"] += 1
            if self.applied[g]:
                continue
            if self.hand_limits:  # at a scale: a contact the hand needs may not exist there
                self.never.add(g)
                continue
            draws = self.present[g]
            spec = self.concept.grasps[g]
            at = f" ({spec.when_where})" if spec.when_where else ""
            message = (
                f"grasp {g} applies only when {spec.when}{at}, which held in none of {draws} "
                f"draws (closed, at random joint values and {WHEN_TRIES} more tries each)"
            )
            failure = Failure(self.concept.name, "applies", g, {}, 0.0, 0.0, "", message)
            self._failures.append(failure)

    def _check_state(self, state: Instance, only: set[str] | None = None) -> set[str]:
        """The checks at one joint state (of the grasps in ``only``, when given, and the
        actions that use them); returns the conditional families checked."""
        geo = _Geometry(state)
        self.evaluated["shape"] += 1
        # the repeated copies and variant options this draw has, where their `when` holds
        here = presence(state.concept.entry, state.params)
        names = [g for g in self.concept.grasps if here(g) and (only is None or g in only)]
        names = [g for g in names if g not in self.conditional or state.grasp_applies(g)]
        checked = {g for g in names if g in self.conditional}
        for g in checked:
            self.applied[g] += 1
        samples = {g: self._grasp_samples(state, g) for g in names}
        for ss in samples.values():
            if ss:
                self._check_grasp(state, geo, ss)
        for action, entry in self.concept.actions.items():
            if not here(action):
                continue
            for g in _action_grasps(self.concept, entry):
                for s in samples.get(g, ()):
                    self._check_action(state, action, entry, s)
        return checked

    def _grasp_samples(self, state: Instance, grasp: str) -> list[_Sample]:
        """The grasp's finite samples; a grasp the runtime refuses as not finite fails
        ``finite`` under its own name and source line."""
        try:
            return self._finite_samples(state, grasp)
        except EvaluationError as exc:
            where = self.concept.grasps[grasp].where
            member = f"{grasp} ({where})" if where else grasp
            message = f"grasp {member} is not finite with {parameter_text(state)}: {exc}"
            self._broken(state, "finite", member, message)
            return []

    def refused(self, values: Mapping[str, Any], pose: np.ndarray, exc: ParameterError) -> None:
        """A draw inside every range that ``instantiate`` refused (not for a ``require``): a
        formula of the concept (a joint limit, a requirement) is not finite there, or (with
        ``ranges="valid"``) a shape or a range is malformed."""
        shape = isinstance(exc, ShapeError)
        check = "shape" if shape else "finite"
        self.evaluated[check] += 1
        params = {k: str(v) for k, v in values.items()}
        si = {"params": {k: list(v) if isinstance(v, tuple) else v for k, v in values.items()}}
        si["pose"] = pose.tolist()
        name = self.concept.name
        member = f"{exc.shape} ({exc.where})" if isinstance(exc, ShapeError) else name
        self._failures.append(Failure(name, check, member, params, 0.0, 0.0, "", str(exc), si))

    def _broken(self, inst: Instance, check: str, member: str, message: str) -> None:
        """Record a draw that cannot be checked (its values are the draw's parameters)."""
        self.evaluated[check] += 1
        failure = Failure(
            self.concept.name,
            check,
            member,
            _display(inst, None, {}),
            0.0,
            0.0,
            "",
            message,
            _si(inst, {}),
        )
        self._worst[(check, member)] = (math.inf, failure)

    def _finite_samples(self, inst: Instance, grasp: str) -> list[_Sample]:
        """The grasp's samples whose poses (and declared width) are finite; one ``finite``
        failure for the family names the grasp's declaration and the first bad value."""
        samples = self._samples(inst, grasp)
        width = inst.grasp_width(grasp)
        good = [s for s in samples if np.all(np.isfinite(s.pose))]
        self.evaluated["finite"] += len(samples)
        bad = next((s for s in samples if not np.all(np.isfinite(s.pose))), None)
        if bad is None and (width is None or math.isfinite(width)):
            return good
        where = self.concept.grasps[grasp].get("where", "")
        member = f"{grasp} ({where})" if where else grasp
        what = (
            "its pose has NaN or infinite entries" if bad is not None else f"its width is {width}"
        )
        at = f" ({where})" if where else ""
        message = f"grasp {grasp}{at} is not finite with {parameter_text(inst)}: {what}"
        s = bad or samples[0]
        self._record(inst, member, s, _Measure("finite", False, math.inf, 0.0, 0.0, "", message))
        return good if width is None or math.isfinite(width) else []

    def _random_joints(self, inst: Instance, rng: np.random.Generator | None = None) -> Instance:
        rng = rng or self.rng
        joints = {}
        for name, (lo, hi) in inst.joint_limits().items():
            lo, hi = (-math.pi, math.pi) if not math.isfinite(hi - lo) else (lo, hi)
            joints[name] = float(rng.uniform(lo, hi))
        return inst.with_joints(joints)  # the parameters were checked once, per draw

    def _samples(self, inst: Instance, grasp: str) -> list[_Sample]:
        ranges = inst.grasp_range(grasp)
        values = spread(list(ranges.values()), FREE_SAMPLES)
        poses = inst.grasps(grasp, FREE_SAMPLES)
        return [
            _Sample(grasp, pose, dict(zip(ranges, map(float, row))))
            for pose, row in zip(poses, values)
        ]

    def _record(self, inst: Instance, member: str, s: _Sample, m: _Measure) -> None:
        self.evaluated[m.check] += 1
        if m.ok:
            return
        key = (m.check, member)
        if key in self._worst and self._worst[key][0] >= m.badness:
            return
        failure = Failure(
            self.concept.name,
            m.check,
            member,
            _display(inst, s.grasp, s.free),
            float(m.value),
            float(m.limit),
            m.unit,
            m.message,
            _si(inst, s.free),
        )
        self._worst[key] = (m.badness, failure)

    # -- grasps (all samples of a family at once: one signed-distance query per check)
    def _check_grasp(self, inst: Instance, geo: _Geometry, samples: list[_Sample]) -> None:
        grasp = samples[0].grasp
        mode = self.concept.grasps[grasp].get("mode", "pinch")
        held = geo.held_shapes(grasp)
        origins = np.array([s.pose[:3, 3] for s in samples])
        what = "the origin is"
        if mode == "hook":  # it rests its side on a wall on +x: measure from that side
            origins = origins + np.array([s.pose[:3, 0] for s in samples]) * self._side
            what = "the side the fingers rest on (+x) is"
        for s, d in zip(samples, geo.sdf(origins, held)):
            message = f"{what} {d * 1e3:.2f} mm from the part it grasps"
            self._record(inst, grasp, s, _at_most("near", float(d), NEAR, "mm", message))
        if mode == "pinch":
            if self.gripper.can_close:  # a hand that cannot close makes no pinch (rank says so)
                self._check_pinch(inst, geo, samples, held)
            return
        self._check_penetration(inst, geo, samples, [0.0] * len(samples))
        if mode in ("push", "press"):
            self._check_into(inst, geo, samples, held, mode)

    def _check_pinch(
        self, inst: Instance, geo: _Geometry, samples: list[_Sample], held: list[str]
    ) -> None:
        declared = inst.grasp_width(samples[0].grasp)
        widths = [
            declared
            if declared is not None
            else _material_width(geo, held, s.pose[:3, 3], s.pose[:3, 1], self.gripper)
            for s in samples
        ]
        what = "declared" if declared is not None else "material"
        top = self.gripper.max_width
        fitting = []
        for s, width in zip(samples, widths):
            fits = 0.0 < width <= top + RANGE_SLACK
            message = (
                f"the {what} width is {width * 1e3:.2f} mm; {self.gripper.name} pinches widths "
                f"in (0, {top * 1e3:g}] mm"
            )
            miss = max(width - top, -width)
            measure = _Measure("width", fits, miss, width * 1e3, top * 1e3, "mm", message)
            if self.hand_limits and width > top:
                self.evaluated["width"] += 1
                self.too_wide.add(s.grasp)
                continue
            self._record(inst, s.grasp, s, measure)
            if fits:
                fitting.append((s, width))
        steps = np.linspace(-0.5, 0.5, 41)
        segments = np.concatenate(
            [
                s.pose[:3, 3] + np.outer(max(w, 0.0) * steps, s.pose[:3, 1])
                for s, w in zip(samples, widths)
            ]
        )
        gaps = geo.sdf(segments, held).reshape(len(samples), -1).min(axis=1)
        for s, gap in zip(samples, gaps):
            message = (
                f"no material between the pads: the part is {gap * 1e3:.2f} mm from the segment "
                "between their inner faces"
            )
            between = _at_most("between", float(gap), 0.0, "mm", message)
            self._record(inst, s.grasp, s, replace(between, ok=bool(gap <= TOUCH)))
        if fitting:
            self._check_penetration(inst, geo, [s for s, _ in fitting], [w for _, w in fitting])

    def _check_into(
        self, inst: Instance, geo: _Geometry, samples: list[_Sample], held: list[str], mode: str
    ) -> None:
        h = 5e-4
        probes = np.concatenate(
            [
                [s.pose[:3, 3] + h * s.pose[:3, 2], s.pose[:3, 3] - h * s.pose[:3, 2]]
                for s in samples
            ]
        )
        d = geo.sdf(probes, held).reshape(len(samples), 2)
        for s, (ahead, behind) in zip(samples, d):
            slope = float((ahead - behind) / (2 * h))
            message = (
                f"+z of a {mode} grasp must point into the material; the part's distance "
                f"changes by {slope:+.3f} per unit step along +z"
            )
            measure = _Measure("into", slope < 0, slope, slope, 0.0, "", message)
            self._record(inst, s.grasp, s, measure)

    def _check_penetration(
        self, inst: Instance, geo: _Geometry, samples: list[_Sample], widths: list[float]
    ) -> None:
        pads = [self._pads(w) for w in widths]
        world = np.concatenate(
            [p @ s.pose[:3, :3].T + s.pose[:3, 3] for s, p in zip(samples, pads)]
        )
        d = geo.sdf(world)
        start = 0
        for s, w, p in zip(samples, widths, pads):
            depth = -float(d[start : start + len(p)].min())
            start += len(p)
            message = f"the pads closed to {w * 1e3:.2f} mm enter the instance {depth * 1e3:.2f} mm"
            self._record(
                inst, s.grasp, s, _at_most("penetration", depth, PENETRATION, "mm", message)
            )

    def _pads(self, width: float) -> np.ndarray:
        """The pads' surface points at opening ``width``: the closed grid, each pad moved out
        along y by half the width (the -y pad's points come first)."""
        out = self._closed.copy()
        half = len(out) // 2
        out[:half, 1] -= width / 2
        out[half:, 1] += width / 2
        return out

    # -- actions
    def _check_action(self, inst: Instance, action: str, entry: ActionSpec, s: _Sample) -> None:
        member = f"{action}/{s.grasp}"
        if entry["joint"] is not None:
            self._check_power(inst, action, entry, s, member)
            self._check_follow(inst, action, entry, s, member)
            return
        twist = entry.turns  # a fixed axis to turn about, not a force
        f = inst.twist(action) if twist else inst.force(action, grasp=s.pose)
        err = abs(float(np.linalg.norm(f)) - 1.0) if np.all(np.isfinite(f)) else math.inf
        what = "twist axis" if twist else "force"
        message = f"the {what} {np.round(f, 6).tolist()} is not a unit vector"
        self._record(inst, member, s, _at_most("unit_force", err, UNIT, "", message))

    def _check_power(
        self, inst: Instance, action: str, entry: ActionSpec, s: _Sample, member: str
    ) -> None:
        joint = entry["joint"]
        try:
            f = inst.force(action, grasp=s.pose)
        except ParameterError as exc:
            if entry.turns:  # on the axis: the hand turns (inst.twist)
                return
            self._record(inst, member, s, _Measure("power", False, 1.0, 0.0, 0.0, "", str(exc)))
            return
        if not np.all(np.isfinite(f)):
            message = f"the force of {action} is not finite: {np.round(f, 6).tolist()}"
            self._record(inst, member, s, _Measure("finite", False, math.inf, 0, 0, "", message))
            return
        v = _grasp_velocity(inst, self.concept.grasps[s.grasp]["link"], joint, s.pose)
        speed = float(np.linalg.norm(v))
        sign = 1.0 if entry["sense"] == "opening" else -1.0
        cos = sign * float(f @ v) / speed if speed > 1e-12 else 0.0
        if speed <= 1e-12:
            message = f"the grasp does not move with joint {joint}"
        else:
            message = (
                f"the force drives joint {joint} against the {entry['sense']} sense "
                f"(cosine with the grasp's motion {cos:+.3f})"
            )
        self._record(inst, member, s, _Measure("power", cos > 0.0, -cos, cos, 0.0, "", message))

    def _check_follow(
        self, inst: Instance, action: str, entry: ActionSpec, s: _Sample, member: str
    ) -> None:
        joint = entry["joint"]
        lo, hi = inst.joint_limits()[joint]
        i = self.concept.moving_joints.index(joint)
        q0 = float(inst.q[i])
        if not math.isfinite(hi - lo):
            lo, hi = q0 - math.pi, q0 + math.pi
        # the joint moves the way the action drives it: up from q0 to open, down to close
        opening = entry["sense"] == "opening"
        to = float(self.rng.uniform(q0, hi) if opening else self.rng.uniform(lo, q0))
        path = inst.follow(action, grasp=s.pose, to=to, steps=FOLLOW_STEPS)
        kin, link = Kinematics.of(inst), self.concept.grasps[s.grasp].link
        qs = np.tile(inst.q, (FOLLOW_STEPS, 1))
        qs[:, i] = np.linspace(q0, to, FOLLOW_STEPS)
        attached = np.linalg.solve(kin.link_pose(link), s.pose)
        want = kin.link_pose(link, qs) @ attached
        drift = float(np.abs(path - want).max())
        message = (
            f"the followed grasp drifts {drift:.2e} from its link as {joint} moves to {to:.4g}"
        )
        self._record(inst, member, s, _at_most("follow", drift, ATTACHED, "", message))


def _action_grasps(concept: Concept, entry: ActionSpec) -> list[str]:
    """The grasps an action is performed with: its ``using``, else those on the link it moves
    (every grasp for an action along a fixed direction)."""
    if entry["using"]:
        return list(entry["using"])
    if entry["joint"] is None:
        return list(concept.grasps)
    child = concept.joints[entry["joint"]]["child"]
    return [n for n, g in concept.grasps.items() if g["link"] == child]


def _grasp_velocity(inst: Instance, link: str, joint: str, grasp: np.ndarray) -> np.ndarray:
    """World velocity of the grasp's origin, carried by ``link``, per unit of ``joint``'s value:
    the link's exact twist Jacobian column (v + w x r, r from the link's origin to the grasp)."""
    pose, jac = Kinematics.of(inst).link_pose_jacobian(link)
    column = jac[:, inst.concept.joint_index[joint]]
    return column[:3] + np.cross(column[3:], grasp[:3, 3] - pose[:3, 3])


def _material_width(
    geo: _Geometry, held: list[str], origin: np.ndarray, y: np.ndarray, gripper: Gripper
) -> float:
    """Width of the material the pads would close on: along +y through the origin, the run of
    points inside the part nearest to the origin (a 1 mm scan over +-0.5 m or twice the hand's
    opening, its ends refined by bisection); 0 when there is none."""
    reach = max(2 * gripper.max_width, 0.5)
    t = np.arange(-reach, reach + 5e-4, 1e-3)
    inside = geo.sdf(origin + t[:, None] * y, held) <= 0
    if not inside.any():
        return 0.0
    idx = np.flatnonzero(inside)
    lo = hi = int(idx[np.argmin(np.abs(t[idx]))])
    while lo > 0 and inside[lo - 1]:
        lo -= 1
    while hi < len(t) - 1 and inside[hi + 1]:
        hi += 1

    def edge(a: float, b: float) -> float:  # a inside, b outside (or the end of the scan)
        for _ in range(30):
            m = (a + b) / 2
            if geo.sdf((origin + m * y)[None], held)[0] <= 0:
                a = m
            else:
                b = m
        return (a + b) / 2

    low = t[lo] if lo == 0 else edge(float(t[lo]), float(t[lo - 1]))
    high = t[hi] if hi == len(t) - 1 else edge(float(t[hi]), float(t[hi + 1]))
    return float(high - low)


# ---- display -----------------------------------------------------------------------------------


def _joint_dim(concept: Concept, joint: str) -> str:
    return "length" if concept.joints[joint]["kind"] == "prismatic" else "angle"


def _display(inst: Instance, grasp: str | None, free: Mapping[str, float]) -> dict[str, str]:
    """Parameters, joint values (``q.<joint>``) and free grasp parameters as people read them."""
    c = inst.concept
    out: dict[str, str] = {}
    values = inst.params
    for p in c.params:
        v = values[p.name]
        if isinstance(v, str):
            out[p.name] = f'"{v}"'
        else:
            out[p.name] = str(v) if p.kind == "bool" else format_si(v, p.dim)
    for name, q in inst.joints.items():  # the joints this draw has
        out[f"q.{name}"] = format_si(q, _joint_dim(c, name))
    if grasp is not None:
        dims = {f["name"]: f.get("dim") for f in c.grasps[grasp]["free"]}
        for k, v in free.items():
            out[k] = format_si(v, dims.get(k))
    return out


def _si(inst: Instance, free: Mapping[str, float]) -> dict[str, Any]:
    """The same values in SI, JSON-ready: ``concept.instantiate(pose=..., joints=..., **params)``
    (with ``ranges="valid"`` for a report at a scale other than 1) and
    ``inst.grasp(name, **free)`` reproduce the failure."""
    params = {k: list(v) if isinstance(v, tuple) else v for k, v in inst.params.items()}
    joints = {n: float(q) for n, q in inst.joints.items()}
    return {
        "params": params,
        "joints": joints,
        "free": {k: float(v) for k, v in free.items()},
        "pose": inst.pose.tolist(),
    }


def summarize(failures: Iterable[Failure]) -> list[tuple[Failure, int]]:
    """The worst failure of each (concept, check, member) and how many draws failed it."""
    groups: dict[tuple[str, str, str], list[Failure]] = {}
    for f in failures:
        groups.setdefault((f.concept, f.check, f.member), []).append(f)
    out = []
    for fs in groups.values():
        worst = max(fs, key=_badness)
        out.append((worst, len(fs)))
    return out


def _badness(f: Failure) -> float:
    """How far a failure is from passing, in its own unit (larger is worse)."""
    if f.check in ("power", "into"):
        return -f.value if f.check == "power" else f.value
    if f.check == "width":
        return max(f.value - f.limit, -f.value)
    return f.value - f.limit
