"""``grace parse "instruction" --scene F [--parser offline|vlm] [--json]``: the plan, no execution.

Prints the object graph, the sub-tasks (object, part, action, target) with their verification
conditions, and what the parser assumed; exit 1 with the parser's question when the instruction
cannot be parsed or is ambiguous in the scene.
"""

from __future__ import annotations

import argparse
from typing import Any

from grace_dsl.cli.output import error, print_json, print_table, print_text
from grace_dsl.errors import GraceError


def add_parse_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("instruction", help='what to do, e.g. "open the top drawer, then close it"')
    p.add_argument(
        "--scene",
        required=True,
        help="a scene file (JSON or YAML) or a shipped scene: kitchen, hall, bathroom",
    )
    p.add_argument(
        "--parser",
        choices=("offline", "vlm"),
        default="offline",
        help="offline (default: no model) or vlm (an OpenAI-compatible server; GRACE_VLM_*)",
    )
    p.add_argument("--json", action="store_true", help="print the plan as JSON")


def run_parse(args: argparse.Namespace) -> int:
    import grace_dsl as eac
    from grace_dsl.agent.scene_file import load_scene

    try:
        lib = eac.load_library()
        scene = load_scene(args.scene, lib)
        parser: Any
        if args.parser == "vlm":
            from grace_dsl.agent.vlm import VLMParser

            parser = VLMParser(lib)
        else:
            from grace_dsl.agent.offline import OfflineParser

            parser = OfflineParser(lib)
        plan = parser.parse(args.instruction, scene)
    except GraceError as exc:
        error(str(exc))
        return 1
    if args.json:
        print_json(plan.to_json())
        return 0
    print_text(f"plan for {plan.instruction!r} in scene {scene.name!r}")
    for node in plan.objects:
        rel = ", ".join(f"{r} {o}" for r, o in node.relations)
        print_text(
            f"  object {node.name} ({node.concept}): parts {', '.join(node.parts)}"
            + (f"; {rel}" if rel else "")
        )
    rows = []
    for k, s in enumerate(plan.subtasks, 1):
        c = s.condition
        rows.append(
            [
                str(k),
                s.object,
                s.part,
                s.action,
                _target(s.target.kind, s.target.value),
                f"{c.lo:.3f} <= {s.joint} <= {c.hi:.3f}",
                s.text,
            ]
        )
    print_table(
        "sub-tasks",
        ["#", "object", "part", "action", "target", "condition (m or rad)", "from"],
        rows,
    )
    for note in plan.notes:
        print_text(f"note: {note}")
    return 0


def _target(kind: str, value: float) -> str:
    if kind == "fraction":
        return f"{value:.0%} of the range"
    if kind == "delta":
        return f"by {value:g}"
    return kind
