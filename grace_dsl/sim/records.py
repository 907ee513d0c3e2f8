"""What one simulated episode is asked to do and what it reports.

An episode is a pure function of ``(EpisodeConfig, seed)``: everything random (the concept's
parameters, its initial joint value, the camera) is drawn from the seed, so a record can be
replayed from its ``config`` and ``seed`` alone, in any process or on any Ray worker.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Literal

Task = Literal["open", "close"]
Agent = Literal["gripper", "arm"]
Mode = Literal["oracle", "estimated"]

#: Why an episode failed; "" for success. A fixed vocabulary so that reports can count them.
FAILURE_REASONS = (
    "",
    "no_feasible_grasp",  # rank found no option this hand can execute
    "ik_failure",  # arm mode: no joint solution for the chosen grasp or along the path
    "collision",  # the hand or arm hit the object before the interaction
    "slip",  # the hand lost the part during the interaction
    "wrong_direction",  # the joint moved, but against the task
    "timeout",  # the episode's simulated time ran out short of the goal
    "invalid_draw",  # the drawn parameters violate the concept's requirements
    "error",  # the episode's own code raised: a bug to fix, never a physical outcome
)


@dataclass(frozen=True)
class EpisodeConfig:
    """One episode's settings: the concept, the task and the agent that does it."""

    concept: str
    task: Task = "open"
    agent: Agent = "gripper"
    hand: str = "panda"  # a shipped hand name or a hand file (runtime.hands)
    mode: Mode = "oracle"
    scale: tuple[float, float] = (1.0, 1.0)  # the object's size factor, drawn uniformly
    ranges: Literal["typical", "valid"] = "typical"
    engine: Literal["mujoco", "sapien"] = "mujoco"
    max_seconds: float = 20.0  # simulated time budget

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class EpisodeRecord:
    """The outcome of one episode: enough to count it, explain it and replay it."""

    config: EpisodeConfig
    seed: int
    joint: str  # the joint the task moves
    q_range: tuple[float, float]  # the joint's declared range
    q_initial: float
    q_final: float
    lenient: bool  # moved >= 0.01 m or rad the right way
    strict: bool  # open: >= 50% of the range; close: <= 5% of the range
    reason: str = ""  # one of FAILURE_REASONS
    detail: str = ""  # a sentence for a person
    params: dict[str, Any] = field(default_factory=dict)
    camera: dict[str, float] = field(default_factory=dict)  # azimuth, elevation (deg), distance
    option: str = ""  # the manipulation function used, e.g. "handle.pull"
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0
    #: estimated mode: the agent's looks (view, confidence, residual), the estimate's errors
    #: against the truth (parameters, pose, joint) and whether it was refused; {} in oracle mode
    estimate: dict[str, Any] = field(default_factory=dict)
    #: arm mode: the base's world pose (x, y, z m, yaw rad) for each stage executed, in order (a
    #: base that moved between stages shows as a second, different entry); [] for the flying hand
    bases: list[list[float]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["config"] = self.config.to_json()
        return out
