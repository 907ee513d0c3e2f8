"""Ranking the manipulation functions of an action for a given gripper.

An action (``open``) may be performed through several manipulation functions: pinch the handle,
hook the fingers behind it, push the door's edge.  Each asks something of the hand: a pinch needs
fingers that close and open wide enough; every function needs the hand to come in along the
grasp's approach (+z of the grasp frame).  A push or press contact can only push roughly along
its fingers.  A hook rests the side of its closed fingers on a wall (behind a bar, inside a
pocket); by convention that wall lies on the grasp's +x side, so a hook can only apply a force
with a positive component along +x (pressing the fingers onto the wall, not pulling them off it)
and never push in along its approach.  ``rank`` checks every function of the action against a
gripper's abilities over its free-parameter range and orders them: feasible first, then
prehensile before hooking before pushing, then by how far the hand must tilt from its preferred
approach.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.runtime.errors import ParameterError
from grace_dsl.runtime.inputs import MAX_RANK_SAMPLES, as_count
from grace_dsl.runtime.masks import has_masks, present
from grace_dsl.runtime.sampling import spread
from grace_dsl.runtime.specs import ActionSpec
from grace_dsl.runtime.symmetry import spin_about
from grace_dsl.tolerances import DEGENERATE, RANGE_SLACK

if TYPE_CHECKING:
    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.runtime.instance import Instance

MODE_ORDER = {"pinch": 0, "hook": 1, "push": 2, "press": 2}
# A push transmits force within this angle of the fingers' direction (+z): 60 deg, a friction
# cone with mu ~ 1.7, generous on purpose; a hook anything outside it (towards its +x side).
CONTACT_CONE = math.radians(60.0)
# A hook's force needs a positive component along the grasp's +x, the side its fingers rest on:
# more than this (cosine), so that a force along the wall (cosine 0) does not count.
HOOK_GRIP = 1e-6
SPIN_STEPS = 12  # spins tried for a grasp symmetric about an axis other than its approach


@dataclass(frozen=True)
class Option:
    """One manipulation function of an action, judged for one gripper."""

    grasp: str
    mode: str
    feasible: bool
    tilt: float  # radians between the best pose's approach and the gripper's required approach
    free: dict[str, float] = field(default_factory=dict)  # free parameters of the best pose
    pose: np.ndarray | None = field(default=None, compare=False, repr=False)
    reasons: tuple[str, ...] = ()  # why it is infeasible (empty when feasible)
    doc: str = ""

    def sort_key(self) -> tuple[int, int, float]:
        return (0 if self.feasible else 1, MODE_ORDER.get(self.mode, 3), self.tilt)


def rank(
    inst: Instance,
    action: str,
    gripper: Gripper,
    samples: int = 32,
    reference: Any = None,
) -> tuple[Option, ...]:
    """Every manipulation function of ``action``, best first (see the module docstring)."""
    spec = inst._action_spec(action)
    samples = as_count("samples", samples, 1, MAX_RANK_SAMPLES)
    options = [_judge(inst, spec, g, gripper, samples, reference) for g in candidates(inst, spec)]
    return tuple(sorted(options, key=Option.sort_key))


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


def _judge(
    inst: Instance,
    action: ActionSpec,
    name: str,
    gripper: Gripper,
    samples: int,
    reference: Any,
) -> Option:
    g = inst.concept.grasps[name]
    mode = g.mode
    reasons = list(_hand_reasons(inst, name, mode, gripper))
    poses, free = _poses(inst, name, samples, reference)
    tilt = _tilt(poses, gripper)
    why = [_contact(inst, action, mode, p) for p in poses]
    force_ok = np.array([w is None for w in why])
    within = tilt <= gripper.approach_tolerance + DEGENERATE
    usable = force_ok & within
    if not force_ok.any():
        reasons.append(f"a {mode} contact cannot apply the force of {action.name} here: {why[0]}")
    elif not usable.any():
        reasons.append(
            f"the hand would tilt {math.degrees(float(tilt[force_ok].min())):.0f} deg from its "
            f"approach; it allows {math.degrees(gripper.approach_tolerance):.0f} deg"
        )
    pool = np.flatnonzero(usable) if usable.any() else np.arange(len(poses))
    best = int(pool[np.argmin(tilt[pool])])
    return Option(
        name,
        mode,
        not reasons,
        float(tilt[best]),
        free[best],
        poses[best],
        tuple(reasons),
        g.doc,
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


def _poses(
    inst: Instance, name: str, samples: int, reference: Any
) -> tuple[np.ndarray, list[dict[str, float]]]:
    """Poses over the free-parameter box, and for grasps symmetric about an axis that is not the
    approach, over spins as well (the spin changes where the hand comes from)."""
    ranges = inst.grasp_range(name)
    values = spread(list(ranges.values()), samples)
    poses = inst.grasps(name, samples, reference=reference)
    free = [dict(zip(ranges, map(float, row))) for row in values]
    g = inst.concept.grasps[name]
    if not g.symmetric or g.approach_symmetric:
        return poses, free
    axes = np.asarray(inst.concept.function("grasp_axis", name).batch(inst.p, values))
    spins = np.linspace(0.0, 2 * math.pi, SPIN_STEPS, endpoint=False)
    spun = [spin_about(poses, axes.reshape(-1, 3), s) for s in spins]
    return np.concatenate(spun), free * SPIN_STEPS


def _tilt(poses: np.ndarray, gripper: Gripper) -> np.ndarray:
    if gripper.approach is None:
        return np.zeros(len(poses))
    want = np.asarray(gripper.approach, dtype=float)
    want = want / np.linalg.norm(want)
    return np.arccos(np.clip(poses[:, :3, 2] @ want, -1.0, 1.0))


def _contact(inst: Instance, action: ActionSpec, mode: str, pose: np.ndarray) -> str | None:
    """Why a contact of this mode cannot apply the action's force at this pose (None: it can)."""
    try:
        if action.fixed_twist:
            return _twist_contact(action, mode)
        f = inst.force(action.name, grasp=pose)
    except ParameterError:  # on the joint's axis: a twist, and only a grip turns the hand
        return _twist_contact(action, mode)
    along = float(f @ pose[:3, 2])
    if mode in ("push", "press") and along < math.cos(CONTACT_CONE):
        deg = math.degrees(math.acos(max(-1.0, min(1.0, along))))
        return f"the force is {deg:.0f} deg from the fingers' approach (at most 60 deg)"
    if mode == "hook":
        if along > math.cos(CONTACT_CONE):
            return "the force pushes the fingers in along their approach"
        if float(f @ pose[:3, 0]) <= HOOK_GRIP:
            return (
                "the force pulls the fingers off the wall they rest on (the hook's +x side) "
                "instead of pressing them onto it"
            )
    return None


def _twist_contact(action: ActionSpec, mode: str) -> str | None:
    """A twist (about a fixed axis, or a joint's axis through the grasp): only a grip turns it."""
    if action.turns and mode == "pinch":
        return None
    return "the action turns the hand here (no linear force), which only a grip can do"
