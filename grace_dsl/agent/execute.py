"""Carry out a grounded plan in simulation, checking each sub-task and retrying what fails.

The paper's loop (its section 3.1): for each sub-task (l_i, c_i) the system reads the object's
concept parameters, picks the manipulation function the hand can execute, acts, and checks c_i;
when c_i does not hold it tries again. Here, per sub-task:

1. the parameters come from a ``ParamSource``: ``Oracle`` reads them from the scene file (the
   simulation's ground truth); an estimator from perception plugs in through the same protocol
   (``estimated`` mode) and the agent then ranks and follows paths on ITS model of the object
   while the world stays the true one;
2. the object's model takes the MEASURED joint values of the world (what earlier steps left);
3. ``inst.rank`` orders the manipulation functions for the hand; the first feasible one not yet
   tried is executed (``grace_dsl.sim.multi``) towards a joint value inside the condition;
4. the condition is checked on the measured joint; on failure the next-ranked option is tried,
   then the best one again from the new state, up to ``max_attempts`` in all.

Every attempt is reported (``Attempt``: option, joint before and after, verified, reason), every
step too (``StepResult``), and the run (``RunResult``). A failed sub-task is a result; a plan that
does not fit the scene (an unknown object, a concept that differs from the scene's, an action
the concept lacks) raises ``ExecutionError`` before anything moves.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING, Any, Literal, Protocol

from grace_dsl.agent.errors import ExecutionError
from grace_dsl.agent.plan import Condition, Plan, SceneObject, SceneSpec, SubTask, Target
from grace_dsl.perception.errors import PerceptionError
from grace_dsl.runtime.errors import GraceError
from grace_dsl.runtime.gripper import Gripper
from grace_dsl.sim.episode import FOLLOW_TO
from grace_dsl.sim.multi import MultiWorld, place

if TYPE_CHECKING:
    from grace_dsl.runtime.instance import Instance
    from grace_dsl.runtime.library import Library
    from grace_dsl.runtime.manipulation import Option
    from grace_dsl.sim.camera import Camera

Mode = Literal["oracle", "estimated"]
MAX_ATTEMPTS = 3  # per sub-task: the ranked options, then the best again from the new state
SECONDS = 20.0  # simulated seconds per attempt
MARGIN = 0.03  # fraction of the range the aim keeps inside a condition's bounds
#: Why an attempt failed ("" when its condition holds): the episode's vocabulary, plus the
#: agent's own ("already_held" is a success without acting).
REASONS = (
    "",
    "already_held",
    "no_feasible_grasp",
    "collision",
    "slip",
    "wrong_direction",
    "timeout",
    "unstable",
    "unreachable_target",
    "low_confidence",  # estimated mode: the agent refused its estimate of the object
    "ik_failure",  # the arm: no plan from any base placement (``ArmExecutor``)
)
#: Reasons after which another attempt cannot do better: the step stops there.
FINAL = ("no_feasible_grasp", "unreachable_target", "ik_failure")


class ParamSource(Protocol):
    """Where the agent's concept parameters of a scene object come from.

    ``Oracle`` reads the scene file. A perception estimator implements the same method, reading
    the world's camera (``world.render()``) and returning its estimate: the ``estimated`` mode."""

    def params(self, obj: SceneObject, world: MultiWorld) -> dict[str, Any]: ...


# Optional, additive: a source may also have ``instance(obj, world) -> Instance`` (its posed
# model with its own joints: the executor then acts on it) and ``last_look(name) -> dict`` (a
# JSON-able account of its last estimate, kept on each attempt); ``agent.estimated.Estimator``.


@dataclass(frozen=True)
class Oracle:
    """The scene file's parameters: the simulation's ground truth (oracle mode)."""

    def params(self, obj: SceneObject, world: MultiWorld) -> dict[str, Any]:
        return dict(obj.params)


@dataclass(frozen=True)
class Attempt:
    """One execution of one manipulation function for a sub-task."""

    option: str  # "grasp (mode)", e.g. "handle1.pull (pinch)"; "" when nothing was executed
    q_before: float
    q_after: float
    goal: float | None  # the joint value aimed at (None: pressed against the closed stop)
    verified: bool  # the sub-task's condition holds after it
    reason: str = ""  # one of REASONS
    detail: str = ""  # a sentence for a person
    sim_seconds: float = 0.0
    estimate: dict[str, Any] = field(default_factory=dict)  # estimated mode: the look used
    base: tuple[float, ...] = ()  # the arm's base (x, y, z, yaw) it acted from; () for the hand
    arm_before: tuple[float, ...] = ()  # the arm's joint angles before and after (the arm only)
    arm_after: tuple[float, ...] = ()


@dataclass(frozen=True)
class StepResult:
    """A sub-task's outcome: its attempts, first to last."""

    index: int
    subtask: SubTask
    attempts: tuple[Attempt, ...]
    q_before: float
    q_after: float
    verified: bool

    @property
    def reason(self) -> str:
        return self.attempts[-1].reason if self.attempts else ""

    @property
    def option(self) -> str:
        return self.attempts[-1].option if self.attempts else ""


@dataclass(frozen=True)
class RunResult:
    """A whole plan's outcome and the world's joint values at its end."""

    plan: Plan
    steps: tuple[StepResult, ...]
    joints: dict[str, dict[str, float]] = field(default_factory=dict)
    final: tuple[bool, ...] = ()  # per step: its condition still holds at the end (see ``held``)

    @property
    def success(self) -> bool:
        """Every step verified, and no later step undid one that a later step does not redo."""
        return all(s.verified for s in self.steps) and all(self.final)

    def to_json(self) -> dict[str, Any]:
        return {
            "instruction": self.plan.instruction,
            "success": self.success,
            "plan": self.plan.to_json(),
            "steps": [{**asdict(s), "reason": s.reason, "option": s.option} for s in self.steps],
            "final": list(self.final),
            "joints": self.joints,
        }


def against_action(sub: SubTask, q0: float, goal: float | None, sign: float) -> Attempt | None:
    """The ``unreachable_target`` attempt when the goal lies the other way from where the
    sub-task's action moves its joint (nothing is executed), else None."""
    if goal is None or (goal - q0) * sign > 0:
        return None
    return Attempt(
        "", q0, q0, goal, False, "unreachable_target",
        f"{sub.action} moves {sub.joint} the other way: from {q0:.3f} it cannot reach "
        f"{goal:.3f}",
    )  # fmt: skip


class Executor:
    """A scene made physical, and the loop that carries plans out in it.

    The world persists: ``run`` after ``run`` acts on the state the previous one left."""

    def __init__(
        self,
        scene: SceneSpec,
        library: Library | Mapping[str, Any],
        gripper: Gripper | None = None,
        params: ParamSource | None = None,
        max_attempts: int = MAX_ATTEMPTS,
        seconds: float = SECONDS,
        camera: Camera | None = None,
    ):
        if max_attempts < 1:
            raise ExecutionError(f"max_attempts must be at least 1, got {max_attempts}")
        self.scene = scene
        self.library = library
        self.gripper = gripper or Gripper.load("panda")
        self.source: ParamSource = params or Oracle()
        self.max_attempts = max_attempts
        self.seconds = seconds
        self.objects = {o.name: o for o in scene.objects}
        truth = [(o.name, self._instance(o, o.params)) for o in scene.objects]
        self.world = self._world(truth, camera)
        self._limits = {name: inst.joint_limits() for name, inst in truth}

    def _world(self, truth: list[tuple[str, Instance]], camera: Camera | None) -> Any:
        """The physical world the agent acts in: the flying hand's (``ArmExecutor``: the arm's)."""
        return MultiWorld(truth, self.gripper, camera=camera)

    def _instance(self, obj: SceneObject, params: Mapping[str, Any]) -> Instance:
        try:
            concept = self.library[obj.concept]
            inst = concept.instantiate(params=dict(params), joints=dict(obj.joints))
        except GraceError as exc:
            raise ExecutionError(f"scene {self.scene.name!r}, object {obj.name!r}: {exc}") from exc
        return place(inst, obj.position, obj.yaw)

    def belief(self, name: str) -> Instance:
        """The agent's model of object ``name``: parameters from the ``ParamSource``, joint
        values measured in the world."""
        obj = self.objects[name]
        perceived = getattr(self.source, "instance", None)
        if perceived is not None:  # a posed model of its own (estimated mode)
            inst: Instance = perceived(obj, self.world)
            return inst
        params = self.source.params(obj, self.world)
        model = self._instance(obj, params) if params != obj.params else None
        inst = model if model is not None else self.world.instance(name)
        return inst.with_joints(self.world.joints(name))

    # -- the loop
    def run(self, plan: Plan) -> RunResult:
        """Check the plan against the scene, then execute and verify its sub-tasks in order."""
        for sub in plan.subtasks:
            self.check(sub)
        steps = tuple(self.step(i, sub) for i, sub in enumerate(plan.subtasks))
        joints = {n: self.world.joints(n) for n in self.objects}
        at = {n: {j: self.measured(n, j) for j in js} for n, js in joints.items()}
        return RunResult(plan, steps, joints, held(plan.subtasks, at))

    def measured(self, obj: str, joint: str) -> float:
        """The joint's measured value clipped into its range: a part pressed against its stop
        reads a hair past it (MuJoCo's joint limits are soft), and it is at the stop."""
        q = self.world.q(obj, joint)
        lo, hi = self._limits[obj].get(joint, (q, q))
        return min(max(q, lo), hi)

    def check(self, sub: SubTask) -> None:
        """Raise ``ExecutionError`` if ``sub`` does not fit the scene."""
        where = f"sub-task {sub.text!r}"
        obj = self.objects.get(sub.object)
        if obj is None:
            raise ExecutionError(
                f"{where}: no object {sub.object!r} in scene {self.scene.name!r}; "
                f"it has {sorted(self.objects)}"
            )
        if obj.concept != sub.concept:
            raise ExecutionError(
                f"{where}: {sub.object!r} is a {obj.concept} in the scene, not a {sub.concept}"
            )
        actions = self.library[obj.concept].actions
        if sub.action not in actions:
            raise ExecutionError(f"{where}: {obj.concept} has no action {sub.action!r}")
        if actions[sub.action].joint != sub.joint:
            raise ExecutionError(
                f"{where}: action {sub.action!r} moves joint {actions[sub.action].joint!r}, "
                f"not {sub.joint!r}"
            )
        if sub.condition.object != sub.object or sub.condition.joint not in self.world.joints(
            sub.object
        ):
            raise ExecutionError(
                f"{where}: its condition is on {sub.condition.object}.{sub.condition.joint}, "
                f"not a joint of {sub.object!r} ({sorted(self.world.joints(sub.object))})"
            )

    def step(self, index: int, sub: SubTask) -> StepResult:
        """One sub-task: act and verify, retrying with the next-ranked option (bounded)."""
        self.check(sub)
        cond = sub.condition
        q_start = self.world.q(sub.object, sub.joint)
        if cond.holds(self.measured(cond.object, cond.joint)):
            held_ = Attempt("", q_start, q_start, None, True, "already_held", "held before acting")
            return StepResult(index, sub, (held_,), q_start, q_start, True)
        sign = float(self.library[sub.concept].actions[sub.action].sign)
        attempts: list[Attempt] = []
        tried: list[str] = []
        for _ in range(self.max_attempts):
            attempt = self._attempt(sub, sign, tried)
            attempts.append(attempt)
            if attempt.verified or attempt.reason in FINAL:
                break
        q_end = self.world.q(sub.object, sub.joint)
        return StepResult(index, sub, tuple(attempts), q_start, q_end, attempts[-1].verified)

    def _attempt(self, sub: SubTask, sign: float, tried: list[str]) -> Attempt:
        q0 = self.world.q(sub.object, sub.joint)
        try:
            inst = self.belief(sub.object)
        except PerceptionError as exc:  # a refused estimate: never acted on; the next looks anew
            return Attempt("", q0, q0, None, False, "low_confidence", str(exc),
                           estimate=self._look(sub.object))  # fmt: skip
        attempt = self._act(sub, sign, tried, inst, q0)
        look = self._look(sub.object)
        return replace(attempt, estimate=look) if look else attempt

    def _look(self, name: str) -> dict[str, Any]:
        report = getattr(self.source, "last_look", None)
        return dict(report(name)) if report is not None else {}

    def _act(
        self, sub: SubTask, sign: float, tried: list[str], inst: Instance, q0: float
    ) -> Attempt:
        lo, hi = inst.joint_limits()[sub.joint]
        goal = aim(sub.target, sub.condition, q0, lo, hi, sign)
        wrong_way = against_action(sub, q0, goal, sign)
        if wrong_way is not None:
            return wrong_way
        option = self._choose(inst, sub.action, tried)
        if option is None:
            return Attempt("", q0, q0, goal, False, "no_feasible_grasp", "no feasible option")
        label = f"{option.grasp} ({option.mode})"
        tried.append(option.grasp)
        act = self.world.act(
            sub.object, sub.action, sub.joint, sign, option, goal, self.seconds, inst=inst
        )
        verified = sub.condition.holds(self.measured(sub.condition.object, sub.condition.joint))
        reason, detail = ("", "") if verified else _why(act.outcome, q0, act.q_after, sign)
        return Attempt(label, q0, act.q_after, goal, verified, reason, detail, act.sim_seconds)

    def _choose(self, inst: Instance, action: str, tried: list[str]) -> Option | None:
        """The best feasible option not tried yet; once all have been, the best one again."""
        try:
            options = [o for o in inst.rank(action, gripper=self.gripper) if o.feasible]
        except GraceError:
            return None
        fresh = [o for o in options if o.grasp not in tried]
        best = fresh or options
        return best[0] if best else None


def aim(
    target: Target, cond: Condition, q0: float, lo: float, hi: float, sign: float
) -> float | None:
    """The joint value to drive to: the target's, kept ``MARGIN`` inside the condition.

    Fully open aims at the episode's ``FOLLOW_TO`` of the range (pulling on the stop tears the
    hand off); closed presses against the stop (None) when the condition holds the stop."""
    span = hi - lo
    if target.kind == "close" and cond.lo <= lo:
        return None
    want = {
        "open": lo + FOLLOW_TO * span,
        "close": lo,
        "fraction": lo + target.value * span,
        "delta": q0 + sign * target.value,
    }[target.kind]
    margin = min(MARGIN * span, (cond.hi - cond.lo) / 4)
    a, b = max(cond.lo + margin, lo), min(cond.hi - margin, hi)
    return min(max(want, a), b) if a <= b else min(max(want, lo), hi)


def held(
    subtasks: tuple[SubTask, ...], joints: Mapping[str, Mapping[str, float]]
) -> tuple[bool, ...]:
    """Per sub-task: its condition holds in ``joints``, or a later sub-task acts on the same
    joint (then that one's condition is the one the end state must meet)."""
    out = []
    for i, sub in enumerate(subtasks):
        c = sub.condition
        later = any(s.condition.object == c.object and s.condition.joint == c.joint
                    for s in subtasks[i + 1 :])  # fmt: skip
        out.append(later or c.holds(joints[c.object][c.joint]))
    return tuple(out)


def _why(outcome: Any, q0: float, q1: float, sign: float) -> tuple[str, str]:
    """The reason an attempt left its condition unmet, from what the execution saw."""
    moved = q1 - q0
    if outcome.unstable:
        return "unstable", outcome.detail or "the simulation became unstable"
    if not outcome.arrived:
        return "collision", "the hand was stopped on its way to the grasp"
    if sign * moved < -0.01:
        return "wrong_direction", f"the joint moved {moved:+.3f} against the action"
    if outcome.slipped or outcome.detail:
        return "slip", outcome.detail or "the hand came off the part while following the path"
    return "timeout", f"the joint moved {moved:+.3f} and stopped outside the condition"
