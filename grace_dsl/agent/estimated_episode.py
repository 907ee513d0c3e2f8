"""One benchmark episode in ``estimated`` mode: a pure function of (config, seed).

The same draw as the oracle episode (``grace_dsl.sim.episode``: parameters, initial joint value,
camera from the seed), the same physical world built from the TRUE instance, the same hand and
controller; the one difference is the agent's model of the object. Here it is estimated from
the protocol's RGB-D view (``grace_dsl.agent.estimated.look``): ``inst.rank`` picks the grasp on
the ESTIMATED instance and the hand follows the estimated instance's path, while the physics
moves the true one.

Views (a decision, documented in docs/benchmarks.md): the agent looks from the protocol's
camera first. Half of the protocol's azimuths (0-360 degrees) face the object's back, where its
handle cannot be seen; the agent does not act on a view whose estimated front faces away from
the camera, nor on one showing fewer than ``MIN_PART_POINTS`` of the handle's pixels, nor on
one whose confidence is below ``MIN_CONFIDENCE``: it walks round and looks again, up to
``LOOKS`` looks in all, each next view chosen from what the refused ones showed
(``estimated.next_view``: toward the face where the handle's pixels were, else the face the
estimated front points at, else from the opposite side). If every look is refused the episode
fails with ``no_feasible_grasp`` (no grasp the agent trusts; the record's ``estimate`` says the
estimate was refused and why). ``looks=1`` (the bench's ``--single-view``) refuses instead of
looking again.

Every look's cloud carries a label per point (its shape, part or link: the renderer's
segmentation), and the fit gets every pixel with its label (``estimated.labelled_cloud``).

Perception estimates the real-valued parameters, the pose and the joints; the discrete ones
(integers, choices, flags: a concept's structure, which the task parser or a VLM names with the
concept) are the draw's.

The record carries, in ``estimate``: every look (view, points, residual, confidence), the
errors of the accepted estimate against the truth (each real-valued parameter, the worst and
mean length error, the pose's origin and rotation, the task joint) and ``refused``.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from grace_dsl.agent.estimated import (
    LOOKS,
    MIN_CONFIDENCE,
    Perceived,
    Sight,
    View,
    fixed_params,
    frame_of,
    frameless_joint,
    fuse,
    look,
    look_around,
    scene_of,
    with_joints_clipped,
)
from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.runtime.instance import Instance
from grace_dsl.sim.episode import Z_UP, _early, execute, outcome_record, start_episode
from grace_dsl.sim.records import EpisodeConfig, EpisodeRecord
from grace_dsl.sim.scene import Scene
from grace_dsl.sim.world import World

PARKED = np.array([0.0, 0.0, 5.0])  # m: the hand waits here until execute places it


def run_estimated_episode(config: EpisodeConfig, seed: int) -> EpisodeRecord:
    """``config`` (mode ``estimated``) with ``seed``; the same pair gives the same record."""
    return estimated_episode(config, seed)


def estimated_episode(
    config: EpisodeConfig,
    seed: int,
    *,
    min_confidence: float = MIN_CONFIDENCE,
    looks: int = LOOKS,
    fused: bool = True,
    frameless: bool = True,
) -> EpisodeRecord:
    """The episode, with the agent's confidence threshold, its number of looks (1: the
    protocol's view only), whether it fits the looks together (``fused``) and whether a
    frameless leaf's joint comes from the protocol's upright base (``frameless``,
    ``estimated.frameless_joint``) as arguments."""
    _check(config)
    started = time.perf_counter()
    start = start_episode(config, seed, started)
    if isinstance(start, EpisodeRecord):
        return start
    task, draw, ranges, true = start.task, start.draw, start.ranges, start.inst
    concept = true.concept
    first = View(draw.camera["azimuth"], draw.camera["elevation"])
    hold = str(concept.joints[task.joint]["child"])  # the link the task moves
    got, account = perceive_episode(true, first, seed, min_confidence, looks, hold, fused)
    if got is None:
        early = _early(config, seed, task, "no_feasible_grasp", _refused(account), started,
                       draw, true)  # fmt: skip
        return replace(early, estimate={"looks": account, "refused": True})
    leaf = frameless_joint(concept, got, task.joint, Z_UP[:3, :3]) if frameless else None
    if leaf is not None:  # a leaf with no frame: its joint from the protocol's upright base
        fitted = round(float(got.joints.get(task.joint, 0.0)), 4)
        got = leaf
    errors = estimate_errors(true, got, task.joint)
    if leaf is not None:
        errors["frameless_joint"] = {"fitted": fitted, "chosen": round(got.joints[task.joint], 4)}
    believed = _believed(got, concept, ranges)
    if isinstance(believed, str):
        early = _early(config, seed, task, "no_feasible_grasp", believed, started, draw, true)
        return replace(early, estimate={"looks": account, "refused": True, **errors})
    gripper = Gripper.load(config.hand)
    try:
        options = believed.rank(task.action, gripper=gripper)
    except GraceError as exc:
        early = _early(config, seed, task, "no_feasible_grasp", str(exc), started, draw, true)
        return replace(early, estimate={"looks": account, "refused": False, **errors})
    usable = [o for o in options if o.feasible]
    if not usable:
        why = "; ".join(f"{o.grasp}: {o.reasons[0]}" for o in options if o.reasons) or "no option"
        early = _early(config, seed, task, "no_feasible_grasp", why, started, draw, true)
        return replace(early, estimate={"looks": account, "refused": False, **errors})
    parked = np.eye(4)
    parked[:3, 3] = PARKED
    world = World.build(true, gripper, parked, driven=task.joint)
    outcome = execute(believed, task, usable[0], gripper, config.max_seconds, world=world,
                      relative=True, beyond=beyond(believed, task.joint, task.sign))  # fmt: skip
    record = outcome_record(config, seed, task, draw, true, outcome, usable[0], started)
    return replace(record, estimate={"looks": account, "refused": False, **errors})


#: m: how far a drawer's path goes on past its estimated travel while the drawer still moves
PRISMATIC_BEYOND = 0.3
#: of the estimated range: how far a close goes on past the estimated stop while the joint moves
CLOSE_BEYOND = 0.25


def beyond(believed: Instance, joint: str, sign: float) -> float:
    """How far (joint units) the hand's path goes on past the estimate's goal while the
    measured joint still moves (``sim.episode.execute``'s ``beyond``). A closed drawer's
    travel is in no view (the fit's value is the prior's), so an open follows a drawer until it
    stops, at least ``PRISMATIC_BEYOND`` past the estimated travel; a close follows any joint on
    past the estimated stop (an estimate a few centimetres off stops the hand short of the real
    one). A door's opening range is the concept's, not an estimate: an open ends where it did."""
    lo, hi = believed.joint_limits()[joint]
    prismatic = believed.concept.joints[joint]["kind"] == "prismatic"
    if sign < 0:
        return max(CLOSE_BEYOND * (hi - lo), PRISMATIC_BEYOND if prismatic else 0.0)
    return max(hi - lo, PRISMATIC_BEYOND) if prismatic else 0.0


def perceive_episode(
    true: Instance,
    first: View,
    seed: int,
    min_confidence: float = MIN_CONFIDENCE,
    looks: int = LOOKS,
    hold: str = "",
    fused: bool = True,
) -> tuple[Perceived | None, list[dict[str, Any]]]:
    """Look at the true instance (rendered by MuJoCo, no floor: the episode's world has none)
    from ``first``, then from views chosen from what the refused looks showed
    (``estimated.next_view``), until one gives an estimate the agent accepts or ``looks``
    looks were taken (``hold``: the link the task moves, which a look must show). From the
    second look on, every look taken is also fitted at once (``estimated.fuse``) unless not
    ``fused``. Look k's sensor noise has seed ``seed + 7919 k``."""
    scene, model, data = _scene(true)
    centre, radius = frame_of(true)
    taken: list[View] = []

    def see(view: View) -> Perceived:
        taken.append(view)
        return look(scene, model, data, 0, true.concept, view, centre, radius,
                    seed + 7919 * (len(taken) - 1), min_confidence=min_confidence,
                    fixed=fixed_params(true.concept, true.params), hold=hold)  # fmt: skip

    def together(sights: list[Sight], guesses: list[Perceived]) -> Perceived:
        return fuse(true.concept, sights, guesses, seed, min_confidence,
                    fixed_params(true.concept, true.params))  # fmt: skip

    return look_around(first, see, looks, together if fused else None)


def estimate_errors(true: Instance, got: Perceived, joint: str) -> dict[str, Any]:
    """The accepted estimate against the truth: per real-valued parameter (m or rad), the
    worst and mean length error (mm), the pose (origin mm, rotation deg) and the task joint."""
    from grace_dsl.perception.views import split_params

    concept = true.concept
    truth, _ = split_params(concept, true.params)
    est, _ = split_params(concept, got.params)
    per = {k: round(abs(est[k] - v), 5) for k, v in truth.items() if k in est}
    angles = {s.name for s in concept.params if getattr(s, "unit", "") in ("rad", "deg")}
    lengths = [v for k, v in per.items() if k.split("[")[0] not in angles]
    rot = got.pose[:3, :3].T @ true.pose[:3, :3]
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(rot)) - 1) / 2))))
    q_true = float(true.joints.get(joint, 0.0))
    return {
        "params_error": per,
        "length_error_max_mm": round(1000 * max(lengths), 2) if lengths else 0.0,
        "length_error_mean_mm": round(1000 * float(np.mean(lengths)), 2) if lengths else 0.0,
        "pose_error_mm": round(1000 * float(np.linalg.norm(got.pose[:3, 3] - true.pose[:3, 3])), 2),
        "pose_error_deg": round(angle, 2),
        "joint_error": round(abs(float(got.joints.get(joint, 0.0)) - q_true), 4),
        "confidence": round(got.confidence, 3),
    }


def _believed(got: Perceived, concept: Any, ranges: str) -> Instance | str:
    """The agent's instance, or why it cannot be built (an estimate outside the concept)."""
    try:
        inst = concept.instantiate(params=dict(got.params), pose=got.pose, ranges=ranges)
        return with_joints_clipped(inst, got.joints)
    except (GraceError, ValueError) as exc:
        return f"the estimate is no valid {concept.name}: {exc}"


def _scene(true: Instance) -> tuple[Scene, Any, Any]:
    """The true instance as a MuJoCo scene at its episode pose, without the floor (the
    episode's world has none and the object's centre is at the origin)."""
    return scene_of(true)


def _refused(account: list[dict[str, Any]]) -> str:
    reasons = "; ".join(str(a.get("refused", "")) for a in account)
    return f"estimate refused in every view: {reasons}"


def _check(config: EpisodeConfig) -> None:
    if config.mode != "estimated" or config.agent != "gripper" or config.engine != "mujoco":
        raise ParameterError(
            f"the estimated episode runs mode='estimated', agent='gripper', engine='mujoco'; got "
            f"mode={config.mode!r}, agent={config.agent!r}, engine={config.engine!r}"
        )
    if config.task not in ("open", "close"):
        raise ParameterError(f"task must be 'open' or 'close', not {config.task!r}")
