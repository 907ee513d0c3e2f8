"""The long-horizon suite end to end: parse accuracy and task success in simulation.

Each task of the shipped suite (``grace_dsl.agent.suite``) is parsed in its scene (the offline
parser by default) and compared with its expected plan; the parsed plan is then carried out by
the flying hand (or, ``agent="arm"``, the full Panda on a base placed beside each object:
``agent.arm_execute``) in a fresh MuJoCo world of that scene (oracle parameters). A
task succeeds when every sub-task verified and every object's last condition holds at the end
(``RunResult.success``); a plan the parser refused is a failed task. The issue's targets with the
offline parser: parse accuracy >= 0.95, task success >= 0.85.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from grace_dsl.agent.errors import ExecutionError, ParseError
from grace_dsl.agent.execute import Executor

if TYPE_CHECKING:
    from grace_dsl.agent.execute import RunResult
    from grace_dsl.agent.plan import Plan, SceneSpec
    from grace_dsl.agent.suite import SuiteTask
    from grace_dsl.runtime.library import Library

AGENTS = {"gripper": "flying Panda hand", "arm": "full Panda arm, base placed per sub-task"}
SMALL = ("k01", "k04")  # a one-step and a three-step task: the smoke run's subset


@dataclass(frozen=True)
class TaskRun:
    """One suite task: whether its plan was right and whether executing it succeeded."""

    id: str
    scene: str
    instruction: str
    parsed: bool  # the parser returned a plan
    correct: bool  # the plan is the expected one
    success: bool  # every condition held (see the module docstring)
    steps: int
    attempts: int  # attempts over all steps (a retry adds one)
    problem: str  # "" on success: the parse problem, or the first failed step's reason
    seconds: float  # wall time of its execution


@dataclass(frozen=True)
class TaskReport:
    runs: tuple[TaskRun, ...]
    parser: str
    wall_seconds: float
    agent: str = "gripper"

    @property
    def parse_accuracy(self) -> float:
        return sum(r.correct for r in self.runs) / max(len(self.runs), 1)

    @property
    def task_success(self) -> float:
        return sum(r.success for r in self.runs) / max(len(self.runs), 1)

    def table(self) -> str:
        n = len(self.runs)
        lines = [
            f"tasks: {n} ({self.parser} parser, {AGENTS[self.agent]}, oracle parameters)",
            f"parse accuracy: {self.parse_accuracy:.3f} ({sum(r.correct for r in self.runs)}/{n})",
            f"task success:   {self.task_success:.3f} ({sum(r.success for r in self.runs)}/{n})",
            f"retries: {sum(r.attempts - r.steps for r in self.runs)} extra attempts; "
            f"wall {self.wall_seconds:.0f} s",
        ]
        lines += [f"  {r.id}: {r.problem}" for r in self.runs if r.problem]
        return "\n".join(lines)

    def to_json(self) -> dict[str, Any]:
        from dataclasses import asdict

        return {
            "parser": self.parser,
            "agent": self.agent,
            "parse_accuracy": self.parse_accuracy,
            "task_success": self.task_success,
            "wall_seconds": self.wall_seconds,
            "runs": [asdict(r) for r in self.runs],
        }


def run_tasks(
    lib: Library,
    ids: Sequence[str] | None = None,
    parse: Callable[[str, SceneSpec], Plan] | None = None,
    parser: str = "offline",
    progress: bool = True,
    agent: str = "gripper",
) -> TaskReport:
    """Parse and execute the suite's tasks (``ids``: a subset, in suite order) with ``agent``
    (``gripper``: the flying hand; ``arm``: the full Panda)."""
    from grace_dsl.agent.suite import compare, load_suite, shipped_scene_specs

    if agent not in AGENTS:
        raise ExecutionError(f"no agent {agent!r}; agents: {sorted(AGENTS)}")
    if parse is None:
        from grace_dsl.agent.offline import OfflineParser

        parse = OfflineParser(lib).parse
    tasks = [t for t in load_suite() if ids is None or t.id in ids]
    if ids is not None and len(tasks) != len(set(ids)):
        known = {t.id for t in load_suite()}
        raise ExecutionError(f"no suite task {sorted(set(ids) - known)}; tasks: {sorted(known)}")
    scenes = shipped_scene_specs(lib)
    started = time.perf_counter()
    runs = []
    with _bar(progress, len(tasks)) as advance:
        for task in tasks:
            runs.append(_one(task, scenes, lib, parse, compare, agent))
            advance()
    return TaskReport(tuple(runs), parser, time.perf_counter() - started, agent)


def _one(
    task: SuiteTask,
    scenes: Mapping[str, SceneSpec],
    lib: Library,
    parse: Callable[[str, SceneSpec], Plan],
    compare: Callable[[SuiteTask, Plan], str],
    agent: str = "gripper",
) -> TaskRun:
    scene = scenes[task.scene]
    common = (task.id, task.scene, task.instruction)
    try:
        plan = parse(task.instruction, scene)
    except ParseError as exc:
        return TaskRun(*common, False, False, False, 0, 0, f"refused: {exc}", 0.0)
    wrong = compare(task, plan)
    started = time.perf_counter()
    if agent == "arm":
        from grace_dsl.agent.arm_execute import ArmExecutor

        result = ArmExecutor(scene, lib).run(plan)
    else:
        result = Executor(scene, lib).run(plan)
    problem = _problem(result) if not result.success else ""
    if wrong:
        problem = f"parse: {wrong}" + (f"; run: {problem}" if problem else "")
    return TaskRun(
        *common,
        True,
        not wrong,
        result.success,
        len(result.steps),
        sum(len(s.attempts) for s in result.steps),
        problem,
        time.perf_counter() - started,
    )


def _problem(result: RunResult) -> str:
    for step in result.steps:
        if not step.verified:
            a = step.attempts[-1]
            return (
                f"step {step.index + 1} ({step.subtask.text!r}) not verified after "
                f"{len(step.attempts)} attempts: {a.reason} {a.detail}".strip()
            )
    undone = [s.subtask.text for s, ok in zip(result.steps, result.final) if not ok]
    return f"undone by a later step: {undone}"


class _bar:
    """A rich progress bar over the tasks (nothing when ``enabled`` is false)."""

    def __init__(self, enabled: bool, total: int):
        self.enabled, self.total = enabled, total

    def __enter__(self) -> Callable[[], None]:
        if not self.enabled:
            return lambda: None
        from rich.progress import Progress

        self.progress = Progress(transient=True)
        self.progress.start()
        task = self.progress.add_task("tasks", total=self.total)
        return lambda: self.progress.advance(task)

    def __exit__(self, *exc: object) -> None:
        if self.enabled:
            self.progress.stop()
