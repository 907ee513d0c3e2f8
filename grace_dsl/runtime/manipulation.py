"""Ranking the manipulation functions of an action for a given hand.

An action (``open``) may be performed through several manipulation functions: pinch the handle,
hook the fingers behind it, push the door's edge. Each asks something of the hand, and ``rank``
checks all of it over the grasp's free-parameter range (and spins, for symmetric grasps):

- **the hand's abilities**: a pinch needs fingers that close and open wide enough;
- **the whole rotation**: the hand's rotation at the grasp must lie within its orientation cones
  (approach and closing axis, for a top-down hand); among poses that do, the one needing the
  smallest rotation from the hand's home orientation is preferred (its required orientation, else
  the caller's ``reference``, else the Panda's home pointing down);
- **force transmission**: a pinch holds both ways (and turns the hand for a twist, if its wrist
  turns); a hook rests the side of its closed fingers on a wall on the grasp's +x side, so it
  only pulls towards that wall and never pushes in along its approach; a push or press only
  pushes, within 60 deg of the contact's +z;
- **the wrist**: a hand that cannot turn is not offered a twist in place, nor a pinch whose path
  turns it;
- **geometry**: the hand's boxes (pads, finger blocks, palm) against the instance's signed
  distance while it comes in (backed off along the contact's -z, fingers open for a pinch, then
  closing), at the grasp, and along the whole follow path of a joint action (the instance at each
  joint value), each allowed ``PENETRATION`` (the rubber pads give that much); both ways: the
  boxes' face samples in the part, and the part's surface samples in the swept boxes (a thin
  plate between two face samples).

A push may be made with the fingertips, the side of a closed finger or the palm (``contacts``);
the first of those that works is the option's ``contact``. Options are ordered feasible first,
then pinch, hook, push/press, then by the order the action's ``using`` lists them (its author's
preference: a concept lists the grasp made for the hand, a handle, before a fallback such as a
free edge; ``also`` grasps after), then by rotation. The mode comes before the listed order
because it is physics (a pinch holds both ways, a hook or a push one way); the listed order
before the rotation because a small turn of the hand says nothing about how well the grip
holds (an edge pinched from above turns the Panda less than its handle at the front, and slips
where the edge's place is estimated). Among poses whose rotation is within ``TIE`` of the
best, the one nearest the grasp's default free parameters wins (the default is always tried). When
the geometry fails at the best ``GEOMETRY_TRIES`` poses, ``SEARCH_TRIES`` more, spread over the
free parameters (and spins) away from those tried, are checked, nearest the default first: a
bounded, deterministic search for a contact where the hand fits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.runtime.contact import CLEAR, Scene, hand_poses, rotation_from, sweep
from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.runtime.inputs import MAX_RANK_SAMPLES, as_count
from grace_dsl.runtime.kinematics import Kinematics
from grace_dsl.runtime.masks import has_masks, present
from grace_dsl.runtime.sampling import spread
from grace_dsl.runtime.specs import ActionSpec
from grace_dsl.runtime.symmetry import HAND_HOME, spin_about, spin_to_reference
from grace_dsl.tolerances import RANGE_SLACK

if TYPE_CHECKING:
    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.runtime.instance import Instance

MODE_ORDER = {"pinch": 0, "hook": 1, "push": 2, "press": 2}
# A push transmits force within this angle of the contact's +z: 60 deg, a friction cone with
# mu ~ 1.7, generous on purpose; a hook anything outside it (towards its +x side).
CONTACT_CONE = math.radians(60.0)
# A hook's force needs a positive component along the grasp's +x, the side its fingers rest on:
# more than this (cosine), so that a force along the wall (cosine 0) does not count.
HOOK_GRIP = 1e-6
SPIN_STEPS = 12  # spins tried for a grasp symmetric about an axis other than its approach
TIE = math.radians(1.0)  # rotations this close are equal: the default free parameters win
PENETRATION = CLEAR  # m a box may enter the part (as eacc verify allows the pads)
CLEARANCE = 0.01  # m a pinch opens beyond its width on each side while coming in
PATH_STEPS = 6  # joint values along a follow path checked for geometry
GEOMETRY_TRIES = 2  # candidate poses per contact whose geometry is checked, best first
# When those fail, the contact search: this many more poses spread over the free parameters
# (farthest first from those already tried), tried in order of preference. It finds a contact
# away from the default (a push near a front's top edge, where the palm clears the carcass).
SEARCH_TRIES = 6
EXTRA_DIMS = 3  # the search adds the corners and midpoints of a box of at most this many
TURN_SLACK = math.radians(5.0)  # how far a path may turn a hand whose wrist cannot turn
CONTACTS = {"pinch": ("pads",), "hook": ("fingers",)}  # push/press: the hand's push modes


@dataclass(frozen=True)
class Option:
    """One manipulation function of an action, judged for one hand."""

    grasp: str
    mode: str
    feasible: bool
    tilt: float  # radians between the hand's approach and its required approach (0: any)
    free: dict[str, float] = field(default_factory=dict)  # free parameters of the best pose
    pose: np.ndarray | None = field(default=None, compare=False, repr=False)  # the grasp pose
    reasons: tuple[str, ...] = ()  # why it is infeasible (empty when feasible)
    doc: str = ""
    rotation: float = 0.0  # radians the hand turns from its home orientation to the grasp
    turn: float = 0.0  # radians between its closing axis and its required closing line (0: any)
    contact: str = ""  # pads (pinch), fingers (hook), tip, side or palm (push)
    hand_pose: np.ndarray | None = field(default=None, compare=False, repr=False)
    listed: int = 0  # place in the action's ``using`` list (0 for all when it has none)

    def sort_key(self) -> tuple[int, int, int, float]:
        feasible = 0 if self.feasible else 1
        return (feasible, MODE_ORDER.get(self.mode, 3), self.listed, self.rotation)


def rank(
    inst: Instance,
    action: str,
    gripper: Gripper,
    samples: int = 32,
    reference: Any = None,
    to: float | None = None,
    also: Sequence[str] = (),
) -> tuple[Option, ...]:
    """Every manipulation function of ``action``, best first (see the module docstring); the
    follow path judged as far as joint value ``to`` (default the end the action drives to);
    ``also``: grasps judged besides those the action names."""
    spec = inst._action_spec(action)
    samples = as_count("samples", samples, 1, MAX_RANK_SAMPLES)
    ctx = _Context(inst, spec, gripper, reference, to)
    names = candidates(inst, spec)
    names += [g for g in also if g not in names and g in inst.grasp_names]
    options = [replace(_judge_in(ctx, g, samples), listed=listed(spec, g)) for g in names]
    return tuple(sorted(options, key=Option.sort_key))


def listed(action: ActionSpec, grasp: str) -> int:
    """Where ``grasp`` stands in the action's ``using`` list: its author's order of preference
    among grasps of one mode; a grasp it does not list (an ``also``) after those it does, and 0
    for every grasp of an action without a list (the rotation alone decides there)."""
    using = list(action.using)
    return using.index(grasp) if grasp in using else len(using)


def candidates(inst: Instance, action: ActionSpec) -> list[str]:
    """The grasps an action names with ``using``; else every grasp on the link it moves."""
    if action.using:
        names = list(action.using)
    elif action.joint is None:
        names = list(inst.concept.grasps)
    else:
        child = inst.concept.joints[action.joint].child
        names = [n for n, g in inst.concept.grasps.items() if g.link == child]
    entry = inst.concept.entry
    if not has_masks(entry):
        return names
    params = inst.params  # copies and options the instance does not have drop out
    return [n for n in names if present(entry, params, n)]


class _Context:
    """What the options of one rank call share: the hand's home, the scene, the path's end."""

    def __init__(
        self,
        inst: Instance,
        action: ActionSpec,
        gripper: Gripper,
        reference: Any,
        to: float | None = None,
    ):
        self.inst, self.action, self.gripper = inst, action, gripper
        fallback = HAND_HOME if reference is None else np.asarray(reference, float)[:3, :3]
        self.home = gripper.home(fallback)
        # a constrained hand spins symmetric grasps towards where it can be
        constrained = gripper.approach is not None or gripper.closing is not None
        self.reference = self.home if constrained or reference is not None else None
        self._scene: Scene | None = None
        self.end = _path_end(inst, action, to)

    @property
    def scene(self) -> Scene:
        if self._scene is None:
            self._scene = Scene.of(self.inst)
        return self._scene


def _path_end(inst: Instance, action: ActionSpec, to: float | None = None) -> float | None:
    """The joint value a follow path ends at: ``to`` (clamped to the range), else the end of
    the range the action drives towards (a quarter turn for a joint that turns freely); None
    without a joint or path."""
    if action.joint is None:
        return None
    lo, hi = inst.joint_limits()[action.joint]
    q0 = inst.joints[action.joint]
    end = hi if action.opening else lo
    if to is not None:
        end = min(max(float(to), lo), hi)
    if not math.isfinite(end):
        end = q0 + action.sign * math.pi / 2
    return None if abs(end - q0) < 1e-9 else float(end)


def _judge(
    inst: Instance,
    action: ActionSpec,
    name: str,
    gripper: Gripper,
    samples: int,
    reference: Any,
) -> Option:
    """One grasp judged for an action (whether or not the action lists it)."""
    return _judge_in(_Context(inst, action, gripper, reference), name, samples)


def _judge_in(ctx: _Context, name: str, samples: int) -> Option:
    inst, gripper = ctx.inst, ctx.gripper
    g = inst.concept.grasps[name]
    mode = g.mode
    why = inst.grasp_inapplicable(name)
    if why is not None:  # its `when` fails at the instance's joints: nothing else to judge
        return Option(name, mode, False, 0.0, {}, inst.grasps(name, 1)[0], (why,), g.doc)
    hand = _hand_reasons(inst, name, mode, gripper)
    cands = _poses(inst, name, samples, ctx.reference)
    poses, free = cands.poses, cands.free
    force_ok, first_why = _contacts(inst, ctx.action, mode, poses, gripper)
    contacts = CONTACTS.get(mode, gripper.push_modes)
    if not contacts:
        hand.append(f"{gripper.name} has nothing to {mode} with")
    verdicts: list[_Verdict] = []
    for c in contacts:  # the first contact that works is the option's
        verdicts.append(_Verdict.judge(ctx, name, mode, c, cands, force_ok, not hand))
        if verdicts[-1].feasible or hand:
            break
    best = next((v for v in verdicts if v.feasible), verdicts[0] if verdicts else None)
    reasons = list(hand)
    if not force_ok.any():
        reasons.append(
            f"a {mode} contact cannot apply the force of {ctx.action.name} here: {first_why}"
        )
    elif best is not None and not best.feasible and not hand:
        reasons += _contact_reasons(verdicts)
    i = best.grasp_index if best is not None else 0
    return Option(
        name,
        mode,
        not reasons,
        best.tilt if best is not None else 0.0,
        free[i],
        poses[i],
        tuple(reasons),
        g.doc,
        best.rotation if best is not None else 0.0,
        best.turn if best is not None else 0.0,
        best.contact if best is not None else "",
        best.hand_pose if best is not None else None,
    )


def _contact_reasons(verdicts: Sequence[_Verdict]) -> list[str]:
    if len(verdicts) == 1:
        return [verdicts[0].reason]
    return ["; ".join(f"by {v.contact}: {v.reason}" for v in verdicts)]


@dataclass(frozen=True)
class _Verdict:
    """The best pose of one contact (a pinch's pads, a push's palm ...) and why it fails."""

    contact: str
    feasible: bool
    grasp_index: int
    hand_pose: np.ndarray
    rotation: float
    tilt: float
    turn: float
    reason: str

    @staticmethod
    def judge(
        ctx: _Context,
        name: str,
        mode: str,
        contact: str,
        cands: _Poses,
        force_ok: np.ndarray,
        geometry: bool = True,
    ) -> _Verdict:
        gripper = ctx.gripper
        grasps, dist = cands.poses, cands.dist
        hands, index = hand_poses(gripper, contact, grasps, ctx.home)
        rotation = rotation_from(ctx.home, hands[:, :3, :3])
        tilt, turn = gripper.orientation_error(hands[:, :3, :3])
        oriented = gripper.allows(tilt, turn)
        usable = force_ok[index] & oriented
        # the search's own corner poses wait for the search; the rest go first, best first
        pool = _preference(rotation, dist[index], usable)
        order = _preference(rotation, dist[index], usable & ~cands.extra[index])
        order = order if len(order) else pool[:1]

        def verdict(k: int, ok: bool, reason: str) -> _Verdict:
            return _Verdict(
                contact,
                ok,
                int(index[k]),
                hands[k],
                float(rotation[k]),
                float(tilt[k]),
                float(turn[k]),
                reason,
            )

        if not usable.any():
            pool = np.flatnonzero(force_ok[index])
            k = int(_preference(rotation, dist[index], force_ok[index] | ~force_ok.any())[0])
            return verdict(k, False, _orientation_reason(gripper, tilt[pool], turn[pool]))
        if not geometry:  # already infeasible for the hand: skip the costly part
            return verdict(int(order[0]), False, "")
        width = ctx.inst.grasp_width(name) if mode == "pinch" else None
        first_reason = ""
        tried = [int(k) for k in order[:GEOMETRY_TRIES]]
        # where each hand pose lies for the search: its grasp's free parameters, and which
        # face of the fingers pushes (a side push tries four per grasp, 1 apart)
        face = (np.arange(len(index)) // len(grasps))[:, None]
        coords = np.hstack([cands.unit[index], face])
        for k in [*tried, *_search(pool, tried, coords)]:
            reason = _geometry(ctx, name, mode, contact, hands[k], grasps[index[k]], width)
            if reason is None:
                return verdict(k, True, "")
            first_reason = first_reason or reason
        return verdict(int(order[0]), False, first_reason)


def _search(order: np.ndarray, tried: list[int], coords: np.ndarray) -> list[int]:
    """The contact search: up to ``SEARCH_TRIES`` more of the usable poses ``order`` (best
    first), picked farthest first from those tried in the free parameters' unit box (each
    pick the one whose nearest tried or picked pose is farthest; ties to the preferred), then
    returned in order of preference. Deterministic: no random choice."""
    done = set(tried)
    rest = [int(k) for k in order if int(k) not in done]
    if not rest or not tried:
        return []
    points = coords[rest]
    near = np.min(np.linalg.norm(points[:, None, :] - coords[tried][None, :, :], axis=2), axis=1)
    picked: list[int] = []
    for _ in range(min(SEARCH_TRIES, len(rest))):
        j = int(np.argmax(near))  # the first of equals: the preferred
        if near[j] <= 1e-9:  # every remaining pose sits on one already tried
            break
        picked.append(j)
        near = np.minimum(near, np.linalg.norm(points - points[j], axis=1))
    return [rest[j] for j in sorted(picked)]


def _preference(rotation: np.ndarray, dist: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Usable poses best first: those within ``TIE`` of the smallest rotation by distance to
    the default free parameters, then the rest by rotation."""
    pool = np.flatnonzero(usable)
    if not len(pool):
        return pool
    best = rotation[pool].min()
    tied = rotation[pool] <= best + TIE
    key = np.where(tied, 0.0, 1.0)
    second = np.where(tied, dist[pool], rotation[pool])
    return pool[np.lexsort((dist[pool], second, key))]


def _orientation_reason(gripper: Gripper, tilt: np.ndarray, turn: np.ndarray) -> str:
    if not len(tilt):
        return "no pose of this contact can apply the force"
    if tilt.min() > gripper.approach_tolerance:
        return (
            f"the hand would tilt {math.degrees(float(tilt.min())):.0f} deg from its "
            f"approach; it allows {math.degrees(gripper.approach_tolerance):.0f} deg"
        )
    within = tilt <= gripper.approach_tolerance
    return (
        f"its fingers would close {math.degrees(float(turn[within].min())):.0f} deg from "
        f"where they can; it allows {math.degrees(gripper.closing_tolerance):.0f} deg"
    )


def _hand_reasons(inst: Instance, name: str, mode: str, gripper: Gripper) -> list[str]:
    reasons = []
    if mode == "pinch" and not gripper.can_close:
        reasons.append(f"{name} pinches: it needs fingers that close")
    width = inst.grasp_width(name)
    if mode == "pinch" and width is not None and width > gripper.max_width + RANGE_SLACK:
        reasons.append(
            f"{name} needs a {width * 1e3:.0f} mm opening; {gripper.name} opens "
            f"{gripper.max_width * 1e3:.0f} mm"
        )
    return reasons


@dataclass(frozen=True)
class _Poses:
    """The candidate grasp poses of one grasp family, row by row with their free parameters,
    distance from the default (in range widths), place in the unit box of free parameters (and
    spin: a half turn is 1 apart) and whether the row is one of the box's corners and midpoints
    only the contact search tries."""

    poses: np.ndarray
    free: list[dict[str, float]]
    dist: np.ndarray
    unit: np.ndarray
    extra: np.ndarray


def _poses(inst: Instance, name: str, samples: int, reference: Any) -> _Poses:
    """Poses over the free-parameter box and at the default, then the box's corners and
    midpoints for the search (at most ``EXTRA_DIMS`` free parameters); for grasps symmetric
    about an axis that is not the approach over spins as well (the spin changes where the hand
    comes from)."""
    ranges = inst.grasp_range(name)
    lo, hi, default = Kinematics.of(inst).grasp_range(name)
    values = np.vstack([spread(list(ranges.values()), samples), default[None, :]])
    span = np.where(hi > lo, hi - lo, 1.0)
    unit = (values - lo) / span
    ends = _box_points(unit, hi > lo)
    poses = [
        inst.grasps(name, samples, reference=reference),
        inst.grasp(name, reference=reference)[None],
    ]
    if len(ends):
        at = lo + ends * span
        poses.append(_grasps_at(inst, name, ends, at, reference))
        values, unit = np.vstack([values, at]), np.vstack([unit, ends])
    poses_ = np.concatenate(poses)
    extra = np.arange(len(values)) > samples
    free = [dict(zip(ranges, map(float, row))) for row in values]
    dist = np.abs((values - default) / span).sum(axis=1)
    g = inst.concept.grasps[name]
    if not g.symmetric or g.approach_symmetric:
        return _Poses(poses_, free, dist, unit, extra)
    axes = np.asarray(inst.concept.function("grasp_axis", name).batch(inst.p, values))
    spins = np.linspace(0.0, 2 * math.pi, SPIN_STEPS, endpoint=False)
    spun = [spin_about(poses_, axes.reshape(-1, 3), s) for s in spins]
    # the spin as a point on a circle of diameter 1: opposite spins 1 apart
    turn = np.repeat(np.stack([np.cos(spins), np.sin(spins)], axis=1) / 2, len(values), 0)
    return _Poses(
        np.concatenate(spun),
        free * SPIN_STEPS,
        np.tile(dist, SPIN_STEPS),
        np.hstack([np.tile(unit, (SPIN_STEPS, 1)), turn]),
        np.tile(extra, SPIN_STEPS),
    )


def _grasps_at(
    inst: Instance, name: str, unit: np.ndarray, values: np.ndarray, reference: Any
) -> np.ndarray:
    """World grasp poses at points ``unit`` of the free-parameter box (``values`` the same
    points in the parameters' units), spun as ``inst.grasps`` spins symmetric grasps."""
    fn = inst.concept.function("grasps_world", name)
    poses = np.ascontiguousarray(fn.batch(inst.p, inst.q, unit, inst.pose[:3]), float)
    poses = poses.reshape(len(unit), 4, 4)
    if inst.concept.grasps[name].symmetric:
        axes = inst.concept.function("grasp_axis", name).batch(inst.p, values)
        ref = None if reference is None else np.asarray(reference, float)[:3, :3]
        poses = spin_to_reference(poses, np.asarray(axes).reshape(-1, 3), ref)
    return poses


def _box_points(unit: np.ndarray, moves: np.ndarray) -> np.ndarray:
    """The corners and midpoints of the free parameters' unit box ({0, 1/2, 1} along each
    parameter whose range is not a point) not already among ``unit``'s rows: where a feasible
    contact often lies (near an edge of the face) and a spread of a few samples misses."""
    d = unit.shape[1]
    if d == 0 or d > EXTRA_DIMS:
        return np.zeros((0, d))
    axes = [np.array([0.0, 0.5, 1.0]) if m else unit[-1:, i] for i, m in enumerate(moves)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
    near = np.min(np.abs(grid[:, None, :] - unit[None, :, :]).max(axis=2), axis=1)
    return grid[near > 1e-6]


def _contacts(
    inst: Instance, action: ActionSpec, mode: str, poses: np.ndarray, gripper: Gripper
) -> tuple[np.ndarray, str | None]:
    """Which poses' contacts can apply the action's force, and why the first cannot (None: it
    can). The forces come from one batched evaluation; a pose where the force is not finite (on
    a joint's axis: a twist) takes ``_contact``'s exact path, as do the first pose's reasons."""
    if action.fixed_twist:
        why = _twist_contact(action, mode, gripper)
        return np.full(len(poses), why is None), why
    fn = inst.concept.function("force", action.name)
    forces = np.asarray(fn.batch(inst.p, inst.q, inst.pose[:3], poses[:, :3, 3]), float)
    forces = forces.reshape(len(poses), 3)
    along = np.einsum("ni,ni->n", forces, poses[:, :3, 2])
    if mode in ("push", "press"):
        ok = along >= math.cos(CONTACT_CONE)
    elif mode == "hook":
        sideways = np.einsum("ni,ni->n", forces, poses[:, :3, 0])
        ok = (along <= math.cos(CONTACT_CONE)) & (sideways > HOOK_GRIP)
    else:
        ok = np.ones(len(poses), bool)
    odd = np.flatnonzero(~np.isfinite(forces).all(axis=1))
    for i in odd:
        ok[i] = _contact(inst, action, mode, poses[i], gripper) is None
    first = None if ok[0] and 0 not in odd else _contact(inst, action, mode, poses[0], gripper)
    return ok, first


def _contact(
    inst: Instance, action: ActionSpec, mode: str, pose: np.ndarray, gripper: Gripper
) -> str | None:
    """Why a contact of this mode cannot apply the action's force at this pose (None: it can)."""
    try:
        if action.fixed_twist:
            return _twist_contact(action, mode, gripper)
        f = inst.force(action.name, grasp=pose)
    except ParameterError:  # on the joint's axis: a twist, and only a grip turns the hand
        return _twist_contact(action, mode, gripper)
    return transmits(mode, f, pose)


def transmits(mode: str, force: np.ndarray, pose: np.ndarray) -> str | None:
    """Why a ``mode`` contact at grasp ``pose`` cannot apply the world ``force`` (None: it can):
    a pinch holds both ways, a push only pushes into its +z, a hook only pulls towards its +x."""
    along = float(force @ pose[:3, 2])
    if mode in ("push", "press") and along < math.cos(CONTACT_CONE):
        deg = math.degrees(math.acos(max(-1.0, min(1.0, along))))
        return f"the force is {deg:.0f} deg from the fingers' approach (at most 60 deg)"
    if mode == "hook":
        if along > math.cos(CONTACT_CONE):
            return "the force pushes the fingers in along their approach"
        if float(force @ pose[:3, 0]) <= HOOK_GRIP:
            return (
                "the force pulls the fingers off the wall they rest on (the hook's +x side) "
                "instead of pressing them onto it"
            )
    return None


def _twist_contact(action: ActionSpec, mode: str, gripper: Gripper) -> str | None:
    """A twist (about a fixed axis, or a joint's axis through the grasp): only a grip turns it,
    and only with a wrist that turns."""
    if not (action.turns and mode == "pinch"):
        return "the action turns the hand here (no linear force), which only a grip can do"
    if not gripper.can_turn:
        return f"the action turns the hand in place, and {gripper.name}'s wrist cannot turn"
    return None


# ---- geometry ----------------------------------------------------------------------------------


def _geometry(
    ctx: _Context,
    name: str,
    mode: str,
    contact: str,
    hand: np.ndarray,
    grasp: np.ndarray,
    width: float | None,
) -> str | None:
    """Why the hand at ``hand`` collides with the part or cannot follow the path (None: fine)."""
    gripper = ctx.gripper
    if mode == "pinch":
        hold = min(width if width is not None else gripper.max_width, gripper.max_width)
        hold = max(hold, 0.0)
        opened = min(gripper.max_width, hold + 2 * CLEARANCE)
    else:
        hold = opened = 0.0
    direction = hand[:3, :3].T @ grasp[:3, 2]  # the contact's +z in the hand frame
    sw = sweep(gripper, direction, opened, hold)
    path = _path(ctx, hand)
    if path is not None and mode == "pinch":
        reason = _path_orientation(gripper, path)
        if reason:
            return reason
    q = np.array([ctx.inst.q, ctx.inst.q])
    found = ctx.scene.deepest([sw.approach, sw.closing], [hand, hand], q)
    for (depth, part), when in zip(found, ("while coming in", "while closing")):
        if depth > PENETRATION:
            return f"the {part} enters the part {depth * 1e3:.0f} mm {when}"
    # and the other way: the part's surface inside the swept boxes (a plate thinner than the
    # face grid's spacing slices between its samples)
    for boxes, when in (
        (sw.approach_boxes, "while coming in"),
        (sw.closing_boxes, "while closing"),
    ):
        depth, part = ctx.scene.inside(boxes, hand)
        if depth > PENETRATION:
            return f"the {part} enters the part {depth * 1e3:.0f} mm {when}"
    if path is None:
        return None
    # along the path the hand rides its link: only the other links can come into its way
    poses, qs = path[0][1:], path[1][1:]
    link = ctx.inst.concept.grasps[name].link
    found = ctx.scene.deepest([sw.hold] * len(poses), list(poses), qs, skip=link)
    for (depth, part), pose, qk in zip(found, poses, qs):
        if depth <= PENETRATION:
            depth, part = ctx.scene.inside(sw.hold_boxes, pose, qk, skip=link)
        if depth > PENETRATION:
            at = f"{ctx.action.joint} = {float(qk[_joint(ctx)]):.3g}"
            return f"the {part} enters the part {depth * 1e3:.0f} mm along the path (at {at})"
    return None


def _joint(ctx: _Context) -> int:
    """The index in q of the action's joint (only called for actions along a joint)."""
    assert ctx.action.joint is not None
    return ctx.inst.concept.joint_index[ctx.action.joint]


def _path(ctx: _Context, hand: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The hand's poses along the follow path and the joint vectors they belong to."""
    if ctx.end is None:
        return None
    try:
        poses = ctx.inst.follow(ctx.action.name, grasp=hand, to=ctx.end, steps=PATH_STEPS)
    except GraceError:
        return None
    qs = np.tile(ctx.inst.q, (PATH_STEPS, 1))
    i = _joint(ctx)
    qs[:, i] = np.linspace(float(ctx.inst.q[i]), ctx.end, PATH_STEPS)
    return poses, qs


def _path_orientation(gripper: Gripper, path: tuple[np.ndarray, np.ndarray]) -> str | None:
    """A pinch carries the hand rigidly: its rotation along the path must stay reachable."""
    poses = path[0]
    if not gripper.can_turn:
        rel = np.einsum("ji,njk->nik", poses[0, :3, :3], poses[:, :3, :3])
        turned = np.arccos(np.clip((np.trace(rel, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0))
        if turned.max() > TURN_SLACK:
            return (
                f"the path turns the hand {math.degrees(float(turned.max())):.0f} deg and "
                f"{gripper.name}'s wrist cannot turn"
            )
    tilt, turn = gripper.orientation_error(poses[:, :3, :3])
    bad = ~gripper.allows(tilt, turn)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        return (
            f"along the path the hand would tilt {math.degrees(float(tilt[k])):.0f} deg "
            f"and its fingers turn {math.degrees(float(turn[k])):.0f} deg from where it can"
        )
    return None
