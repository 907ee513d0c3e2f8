"""The evaluation protocol of the paper's appendix B, drawn from an episode's seed.

The object stands at the origin; its parameters are drawn uniformly in their typical ranges (or,
for a size study, every length scaled by a factor drawn from ``config.scale`` with
``ranges="valid"``); its joint starts closed with probability 0.5, else at a uniform open value;
an RGB-D camera looks at it from the upper hemisphere, azimuth uniform in [0, 360) degrees,
elevation uniform in [30, 60]. Success is reported two ways: lenient (the joint moved at least
0.01 m or 0.01 rad the right way) and strict (open: at least 50 % of the range; close: at most
5 % of the range).

One deviation keeps every episode meaningful: a start that already meets the strict goal would
count a motionless hand as a success, so the open value is drawn below the open goal and, for
``close``, the "closed" half of the draws starts fully open instead (the mirror of the paper's
closed start for ``open``).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.runtime.draws import draw_valid
from grace_dsl.runtime.errors import ParameterError, RequirementError, UnknownNameError
from grace_dsl.runtime.instance import Instance
from grace_dsl.runtime.library import Concept
from grace_dsl.runtime.verify import draw_params, scaled_specs
from grace_dsl.sim.records import EpisodeConfig, Task

if TYPE_CHECKING:
    from grace_dsl.runtime.concept import ParamSpec

MOVED = 0.01  # m or rad: the lenient criterion
OPEN_GOAL = 0.5  # strict open: at least this fraction of the range
CLOSE_GOAL = 0.05  # strict close: at most this fraction of the range
P_CLOSED = 0.5  # the paper's chance of a closed start
AZIMUTH = (0.0, 360.0)  # degrees
ELEVATION = (30.0, 60.0)  # degrees
DRAW_ATTEMPTS = 50  # uniform parameter draws, then as many repaired ones (``draw_valid``)
SCALE_ATTEMPTS = 8  # scales drawn in a size study before no valid draw is declared
# Parameters that say a part stands alone (no host around it), as every episode places it: a
# door leaf's or a drawer's free edge is reachable, so it is not drawn.
ALONE: dict[str, Any] = {"free_edge": 1}


@dataclass(frozen=True)
class TaskAction:
    """The action that performs a task on a concept, and the joint it moves."""

    action: str
    joint: str
    sign: float  # +1 the action opens (q grows), -1 it closes


@dataclass(frozen=True)
class Draw:
    """Everything random about one episode."""

    params: dict[str, Any]
    scale: float
    q_initial: float
    closed_start: bool
    camera: dict[str, float] = field(default_factory=dict)


def episode_rng(config: EpisodeConfig, seed: int) -> np.random.Generator:
    """The episode's generator: from the seed, the concept and the task, so that the same seed
    gives independent draws for different concepts and tasks."""
    key = [
        int(seed) & 0xFFFFFFFF,
        zlib.crc32(config.concept.encode()),
        zlib.crc32(config.task.encode()),
    ]
    return np.random.default_rng(np.random.SeedSequence(key))


def task_action(concept: Concept, task: Task) -> TaskAction:
    """The concept's action for ``task``: ``open``/``close`` by name when it has them on a
    bounded joint, else the first opening (closing) action on a bounded joint. For ``close`` the
    joint is the one ``open`` would move, so both tasks act on the same part."""
    kinds = {n: j.kind for n, j in concept.joints.items()}
    bounded = [
        a
        for a in concept.actions.values()
        if a.joint is not None and not a.fixed_twist and kinds[a.joint] in ("revolute", "prismatic")
    ]
    opening = sorted((a for a in bounded if a.opening), key=lambda a: a.name != "open")
    if not opening:
        raise UnknownNameError(
            f"{concept.name} has no opening action on a bounded joint; the open/close "
            "benchmark needs one (a revolute or prismatic joint with a range)"
        )
    joint = opening[0].joint
    assert joint is not None
    if task == "open":
        return TaskAction(opening[0].name, joint, 1.0)
    closing = sorted(
        (a for a in bounded if not a.opening and a.joint == joint), key=lambda a: a.name != "close"
    )
    if not closing:
        raise UnknownNameError(f"{concept.name} has no action that closes joint {joint}")
    return TaskAction(closing[0].name, joint, -1.0)


def draw_episode(config: EpisodeConfig, concept: Concept, seed: int) -> Draw:
    """Parameters (valid for the concept's requirements), initial joint value and camera.

    Uniform draws come first, so an episode keeps the draw it had before repairs existed; only
    a concept whose requirements reject ``DRAW_ATTEMPTS`` uniform draws in a row gets a repaired
    one. In a size study, a scale at which no draw of either kind meets the requirements is
    drawn again (up to ``SCALE_ATTEMPTS`` scales): the study covers the sizes the requirements
    allow. Raises ``RequirementError`` when no draw satisfies the requirements."""
    rng = episode_rng(config, seed)
    lo_s, hi_s = config.scale
    action = task_action(concept, config.task)
    for _ in range(SCALE_ATTEMPTS if hi_s > lo_s else 1):
        scale = float(rng.uniform(lo_s, hi_s)) if hi_s > lo_s else float(lo_s)
        if not (math.isfinite(scale) and scale > 0):
            raise ParameterError(f"scale must be a range of factors > 0, got {config.scale!r}")
        found = _valid_draw(concept, rng, scale, config.ranges)
        if found is not None:
            params, inst = found
            lo, hi = inst.joint_limits()[action.joint]
            q0, closed = initial_joint(config.task, lo, hi, rng)
            return Draw(params, scale, q0, closed, draw_camera(rng))
    raise RequirementError(
        f"{concept.name}: no parameter draw in {DRAW_ATTEMPTS} uniform and {DRAW_ATTEMPTS} "
        f"repaired tries satisfied the requirements at scale {scale:g}"
    )


def _valid_draw(
    concept: Concept, rng: np.random.Generator, scale: float, ranges: str
) -> tuple[dict[str, Any], Instance] | None:
    """A draw at ``scale`` that meets the requirements and its instance, or None."""
    specs = scaled_specs(concept, scale)
    ranges = "valid" if scale != 1.0 or ranges == "valid" else "typical"
    for attempt in range(2 * DRAW_ATTEMPTS):
        params = (
            _alone(draw_params(concept, rng, specs))
            if attempt < DRAW_ATTEMPTS
            else draw_valid(concept, rng, specs, _draw_alone, ranges)
        )
        try:
            return params, concept.instantiate(ranges=ranges, params=params)
        except RequirementError:
            continue
    return None


def _alone(params: dict[str, Any]) -> dict[str, Any]:
    params.update({k: v for k, v in ALONE.items() if k in params})
    return params


def _draw_alone(
    concept: Concept, rng: np.random.Generator, specs: Sequence[ParamSpec]
) -> dict[str, Any]:
    """``draw_params`` with the parameters a part standing alone pins (for ``draw_valid``)."""
    return _alone(draw_params(concept, rng, specs))


def initial_joint(task: Task, lo: float, hi: float, rng: np.random.Generator) -> tuple[float, bool]:
    """(q0, whether the start is the 'closed' half of the draws): see the module docstring."""
    closed = bool(rng.uniform() < P_CLOSED)
    span = hi - lo
    if task == "open":
        if closed:
            return lo, True
        return float(rng.uniform(lo, lo + OPEN_GOAL * span)), False
    if closed:
        return hi, True
    return float(rng.uniform(lo + CLOSE_GOAL * span, hi)), False


def draw_camera(rng: np.random.Generator) -> dict[str, float]:
    """Azimuth and elevation (degrees) on the upper hemisphere, as the paper's protocol."""
    return {
        "azimuth": float(rng.uniform(*AZIMUTH)),
        "elevation": float(rng.uniform(*ELEVATION)),
    }


def lenient_success(task: Task, q_initial: float, q_final: float) -> bool:
    """The joint moved at least ``MOVED`` (m or rad) the way the task asks."""
    moved = q_final - q_initial if task == "open" else q_initial - q_final
    return moved >= MOVED


def strict_success(task: Task, q_final: float, lo: float, hi: float) -> bool:
    """Open: at least ``OPEN_GOAL`` of the range; close: at most ``CLOSE_GOAL`` of it."""
    fraction = (q_final - lo) / (hi - lo) if hi > lo else 0.0
    return fraction >= OPEN_GOAL if task == "open" else fraction <= CLOSE_GOAL
