"""``grace run "instruction" --scene SCENE``: parse, ground, execute and verify in simulation.

The instruction is parsed against the scene (``--parser offline``: the deterministic parser;
``vlm``: an OpenAI-compatible vision-language model), or a plan is read from ``--plan FILE`` (a
``Plan.to_json`` document, e.g. from ``--json`` of an earlier run) to replay or hand-write one.
The plan is then carried out in MuJoCo by the flying hand (``grace_dsl.agent.execute``), or with
``--agent arm`` by the full Panda on a base placed beside each object in turn
(``grace_dsl.agent.arm_execute``): each
sub-task's manipulation function is ranked for the hand, executed, and its condition checked on
the measured joint, retrying with the next-ranked function. One line per attempt is printed, or
the whole result as JSON. ``--png DIR`` writes the scene before and after; ``--html FILE`` a page
with both pictures and the step table.

Exit codes: 0 every sub-task verified, 3 some did not (the run itself worked), 1 a bad argument,
scene or plan, 2 a mode that is not built yet (``--mode estimated --agent arm``). ``--mode
estimated``: the agent's model of each object comes from the camera
(``grace_dsl.agent.estimated.Estimator``), and a failed attempt (or a refused estimate) is
retried after a new look from the next view. ``--agent arm``: the Panda on a base placed beside
each sub-task's object (``grace_dsl.agent.arm_execute.ArmExecutor``).
"""

from __future__ import annotations

import argparse
import base64
import html
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.agent.errors import ExecutionError, ParseError
from grace_dsl.agent.plan import Condition, ObjectNode, Plan, SceneSpec, SubTask, Target
from grace_dsl.cli.output import error, print_json, print_table, print_text
from grace_dsl.runtime.errors import GraceError

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Library

FAILED = 3  # exit code: the run worked, some sub-task's condition did not hold


class NotBuiltError(GraceError):
    """A mode of ``grace run`` whose layer is not built yet (exit code 2)."""


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("instruction", nargs="?", default="", help='e.g. "open the top drawer"')
    p.add_argument(
        "--scene",
        required=True,
        help="a scene file (JSON or YAML) or a shipped scene: kitchen, hall, bathroom",
    )
    p.add_argument("--parser", choices=("offline", "vlm"), default="offline")
    p.add_argument("--plan", help="a plan JSON file to execute instead of parsing")
    p.add_argument("--agent", choices=("gripper", "arm"), default="gripper")
    p.add_argument("--mode", choices=("oracle", "estimated"), default="oracle")
    p.add_argument("--hand", default="panda", help="a shipped hand or a hand file (panda)")
    p.add_argument("--attempts", type=int, default=3, help="per sub-task, retries included (3)")
    p.add_argument("--seconds", type=float, default=20.0, help="simulated s per attempt (20)")
    p.add_argument("--png", metavar="DIR", help="write before.png and after.png here")
    p.add_argument("--html", metavar="FILE", help="write a page with the pictures and steps")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def run_run(args: Any) -> int:
    """The body of ``grace run``."""
    try:
        return _run(args)
    except NotBuiltError as exc:
        error(str(exc))
        return 2
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc))
        return 1


def _run(args: Any) -> int:
    from grace_dsl.agent.execute import Executor
    from grace_dsl.agent.scene_file import load_scene
    from grace_dsl.runtime.gripper import Gripper
    from grace_dsl.runtime.library import load_library
    from grace_dsl.sim.camera import Camera

    if args.agent == "arm" and args.hand != "panda":
        raise ExecutionError(f"--agent arm is the Panda with its own hand, not {args.hand!r}")
    if args.agent == "arm" and args.mode == "estimated":
        raise NotBuiltError(
            "--mode estimated drives the flying hand only; run the arm with --mode oracle"
        )
    library = load_library()
    scene = load_scene(args.scene, library)
    camera = Camera(width=640, height=480)
    if args.agent == "arm":
        from grace_dsl.agent.arm_execute import ArmExecutor

        executor: Executor = ArmExecutor(
            scene, library, max_attempts=args.attempts, seconds=args.seconds, camera=camera
        )
    else:
        executor = Executor(
            scene,
            library,
            Gripper.load(args.hand),
            params=_source(args),
            max_attempts=args.attempts,
            seconds=args.seconds,
            camera=camera,
        )
    shown = args.png or args.html or (args.parser == "vlm" and not args.plan)
    before = executor.world.render().rgb if shown else None
    plan = load_plan(Path(args.plan)) if args.plan else parse(args, scene, library, before)
    result = executor.run(plan)
    after = executor.world.render().rgb if args.png or args.html else None
    if args.png:
        out = Path(args.png)
        out.mkdir(parents=True, exist_ok=True)
        for name, rgb in (("before", before), ("after", after)):
            (out / f"{name}.png").write_bytes(_png(rgb))
    if args.html:
        Path(args.html).parent.mkdir(parents=True, exist_ok=True)
        Path(args.html).write_text(_page(result, before, after), encoding="utf-8")
    if args.json:
        print_json(result.to_json())
    else:
        _print(result)
    return 0 if result.success else FAILED


def _source(args: Any) -> Any:
    """The agent's parameters: the scene file's (oracle) or the camera's (estimated: each
    attempt looks anew from the next view, so a retry re-estimates; ``agent.estimated``)."""
    if args.mode != "estimated":
        return None
    from grace_dsl.agent.estimated import Estimator

    return Estimator()


def run_suite(args: Any) -> int:
    """``grace bench --suite tasks``: the instruction suite's parse accuracy and task success
    (``grace_dsl.agent.task_bench``), the table printed (or the summary with ``--json``) and
    ``tasks.json`` written to ``--out``. Exit 0 whatever the rates, 1 on a bad setup."""
    from grace_dsl.agent.task_bench import run_tasks
    from grace_dsl.runtime.library import load_library

    if args.mode != "oracle":
        error("--suite tasks runs with --mode oracle only (the others: not built)")
        return 2
    try:
        report = run_tasks(load_library(), agent=args.agent)
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "tasks.json").write_text(json.dumps(report.to_json(), indent=2) + "\n")
    except (GraceError, OSError) as exc:
        error(str(exc))
        return 1
    if args.json:
        print_json(report.to_json())
    else:
        print_text(report.table())
        print_text(f"tasks: {out / 'tasks.json'}")
    return 0


def parse(args: Any, scene: SceneSpec, lib: Library, image: np.ndarray | None) -> Plan:
    """The instruction's plan from the chosen parser (the VLM is shown the scene camera's
    picture of the world before anything moves)."""
    if not args.instruction:
        raise ParseError('give an instruction ("open the top drawer") or --plan FILE')
    parser: Any
    if args.parser == "vlm":
        from grace_dsl.agent.vlm import VLMParser

        parser = VLMParser(lib)
    else:
        from grace_dsl.agent.offline import OfflineParser

        parser = OfflineParser(lib)
    plan: Plan = parser.parse(args.instruction, scene, image=image)
    return plan


def load_plan(path: Path) -> Plan:
    """A ``Plan.to_json`` document (a file written by ``grace run --json`` holds it under
    ``plan``) as a ``Plan``."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        return plan_from_json(data.get("plan", data))
    except (OSError, KeyError, TypeError, ValueError) as exc:
        raise ExecutionError(f"{path}: not a plan ({type(exc).__name__}: {exc})") from exc


def plan_from_json(data: dict[str, Any]) -> Plan:
    """The inverse of ``Plan.to_json``."""
    subtasks = tuple(
        SubTask(
            text=s["text"],
            object=s["object"],
            concept=s["concept"],
            part=s["part"],
            action=s["action"],
            joint=s["joint"],
            target=Target(s["target"]["kind"], float(s["target"].get("value", 0.0))),
            condition=Condition(**s["condition"]),
        )
        for s in data["subtasks"]
    )
    objects = tuple(
        ObjectNode(
            o["name"],
            o["concept"],
            tuple(o.get("parts", ())),
            tuple((str(r), str(t)) for r, t in o.get("relations", ())),
        )
        for o in data.get("objects", ())
    )
    return Plan(data["instruction"], objects, subtasks, tuple(data.get("notes", ())))


def _base(base: tuple[float, ...]) -> str:
    """The arm's base pose as a short text (- when the arm did not move)."""
    if not base:
        return "-"
    x, y, z, yaw = base
    return f"{x:.2f}, {y:.2f}, {z:.2f}, {np.degrees(yaw):.0f} deg"


def _print(result: Any) -> None:
    arm = any(a.base for s in result.steps for a in s.attempts)
    rows = []
    for step in result.steps:
        c = step.subtask.condition
        for k, a in enumerate(step.attempts):
            rows.append(
                [
                    f"{step.index + 1}.{k + 1}",
                    step.subtask.text,
                    f"{step.subtask.object}.{step.subtask.action}",
                    a.option or "-",
                    f"{a.q_before:.3f} -> {a.q_after:.3f}",
                    f"[{c.lo:.3f}, {c.hi:.3f}]",
                    "yes" if a.verified else "no",
                    (a.reason or "") + _looked(a),
                ]
                + ([_base(a.base)] if arm else [])
            )
    head = ["step", "text", "action", "option", "joint", "condition", "verified", "reason"]
    print_table(result.plan.instruction, head + (["base (x, y, z, yaw)"] if arm else []), rows)
    print_text("success" if result.success else "FAILED: a condition did not hold")


def _looked(attempt: Any) -> str:
    """Estimated mode: the look an attempt acted on (view, confidence), or ''."""
    look = getattr(attempt, "estimate", None) or {}
    if "confidence" not in look:
        return ""
    az, el = look.get("view", ["?", "?"])
    return f" (view {az:.0f}/{el:.0f} deg, confidence {look['confidence']:.2f})"


def _png(rgb: np.ndarray | None) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.asarray(rgb, dtype=np.uint8), "RGB").save(buf, format="PNG")
    return buf.getvalue()


def _page(result: Any, before: np.ndarray | None, after: np.ndarray | None) -> str:
    """A self-contained page: the two pictures side by side and one row per attempt."""
    pics = "".join(
        f'<figure><img src="data:image/png;base64,{base64.b64encode(_png(rgb)).decode()}">'
        f"<figcaption>{name}</figcaption></figure>"
        for name, rgb in (("before", before), ("after", after))
    )
    rows = "".join(
        "<tr>"
        + "".join(
            f"<td>{html.escape(str(v))}</td>"
            for v in (
                f"{s.index + 1}.{k + 1}",
                s.subtask.text,
                f"{s.subtask.object}.{s.subtask.action}",
                a.option,
                f"{a.q_before:.3f} -> {a.q_after:.3f}",
                "yes" if a.verified else "no",
                f"{a.reason} {a.detail}".strip(),
                _base(a.base),
            )
        )
        + "</tr>"
        for s in result.steps
        for k, a in enumerate(s.attempts)
    )
    title = html.escape(result.plan.instruction)
    verdict = "success" if result.success else "failed"
    return (
        f"<!doctype html><meta charset=utf-8><title>{title}</title>"
        "<style>body{font-family:sans-serif}figure{display:inline-block}td{padding:2px 8px}"
        "</style>"
        f"<h1>{title}</h1><p>{verdict}</p>{pics}<table><tr><th>step</th><th>text</th>"
        "<th>action</th><th>option</th><th>joint</th><th>verified</th><th>reason</th>"
        "<th>arm base (x, y, z, yaw)</th></tr>"
        f"{rows}</table>"
    )
