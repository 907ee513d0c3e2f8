"""A task parser that asks a vision-language model on any OpenAI-compatible server.

The conversation follows the paper's two prompts, built from the concept catalog:

1. *Objects*: the instruction, the image (a PNG data URI) and the scene's objects, with every
   concept's synopsis; the model lists the objects the instruction concerns with their concept
   and state, and the spatial relations between them (the object graph).
2. *Plan*: for those objects, their concepts' manipulation blueprint from the catalog
   (parameters, joints, grasps and actions) and each moving part's range, value and handle
   position in the world; the model lists the steps (object, part, action, target).

Each reply must be JSON of the given schema (asked for with ``response_format`` json_schema),
and is checked against the catalog and the scene: an unknown object, concept, part or action, or a
target out of range, is sent back with the problems and asked again, at most ``attempts`` times
in all; then ``ParseError``. The accepted steps become sub-tasks with the same targets and
conditions as the offline parser's (``grounding.make_subtask``).

Setup: ``pip install grace-dsl[vlm]`` (the ``openai`` package) and the environment:
``GRACE_VLM_BASE_URL`` (or ``OPENAI_BASE_URL``; e.g. ``http://localhost:11434/v1`` for Ollama),
``GRACE_VLM_API_KEY`` (or ``OPENAI_API_KEY``; any text for a local server) and
``GRACE_VLM_MODEL`` (default ``gpt-4o``).
"""

from __future__ import annotations

import base64
import json
import os
import struct
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.agent.errors import ParseError, VLMError
from grace_dsl.agent.grounding import GroundedScene, Unit, assemble, ground_scene, make_subtask
from grace_dsl.agent.grounding import nominal as nominal_value
from grace_dsl.agent.plan import Plan, SceneSpec, SubTask, Target

if TYPE_CHECKING:
    from grace_dsl.runtime.library import Library

DEFAULT_MODEL = "gpt-4o"
_BLUEPRINTS: dict[tuple[int, str], dict[str, Any]] = {}
KINDS = ("open", "close", "fraction", "delta")

OBJECTS_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "objects": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "name": {"type": "string"},
                    "concept": {"type": "string"},
                    "state": {"type": "string"},
                },
                "required": ["name", "concept", "state"],
                "additionalProperties": False,
            },
        },
        "relations": {
            "type": "array",
            "items": {"type": "array", "items": {"type": "string"}},
        },
    },
    "required": ["objects", "relations"],
    "additionalProperties": False,
}
STEPS_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "steps": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "text": {"type": "string"},
                    "object": {"type": "string"},
                    "part": {"type": "string"},
                    "action": {"type": "string"},
                    "target": {
                        "type": "object",
                        "properties": {
                            "kind": {"type": "string", "enum": list(KINDS)},
                            "value": {"type": "number"},
                        },
                        "required": ["kind", "value"],
                        "additionalProperties": False,
                    },
                    "success": {"type": "string"},
                },
                "required": ["text", "object", "part", "action", "target", "success"],
                "additionalProperties": False,
            },
        }
    },
    "required": ["steps"],
    "additionalProperties": False,
}

ROLE = (
    "You are an expert robotic task planner. A robot with one arm and a parallel-jaw gripper "
    "works in the scene shown. Break the user's instruction down into steps that each move one "
    "part of one object with one of that object's actions, and say how to check each step. "
    "Use only the names given. Reply with JSON only, following the schema."
)


@dataclass(frozen=True)
class VLMSettings:
    """Where the model is and how to ask it."""

    api_key: str
    base_url: str | None = None
    model: str = DEFAULT_MODEL
    attempts: int = 3  # replies per question, the first included
    timeout: float = 120.0  # s per request
    temperature: float = 0.0

    @classmethod
    def from_env(cls, env: Mapping[str, str] | None = None) -> VLMSettings:
        """From ``GRACE_VLM_*`` (or ``OPENAI_*``); ``VLMError`` when no key is set."""
        env = os.environ if env is None else env
        key = env.get("GRACE_VLM_API_KEY") or env.get("OPENAI_API_KEY")
        if not key:
            raise VLMError(
                "no API key for the vision-language model: set GRACE_VLM_API_KEY (or "
                "OPENAI_API_KEY; any text for a local server) and GRACE_VLM_BASE_URL"
            )
        return cls(
            api_key=key,
            base_url=env.get("GRACE_VLM_BASE_URL") or env.get("OPENAI_BASE_URL") or None,
            model=env.get("GRACE_VLM_MODEL") or DEFAULT_MODEL,
        )


class VLMParser:
    """A ``TaskParser`` that asks a vision-language model, checked against the catalog."""

    def __init__(
        self,
        lib: Library | None = None,
        settings: VLMSettings | None = None,
        client: Any = None,
    ):
        if lib is None:
            from grace_dsl import load_library

            lib = load_library()
        self.lib = lib
        self.settings = settings or VLMSettings.from_env()
        self.client = client or _client(self.settings)
        self.transcript: list[dict[str, Any]] = []  # every request's messages, for a person

    def parse(self, instruction: str, scene: SceneSpec, *, image: np.ndarray | None = None) -> Plan:
        grounded = ground_scene(scene, self.lib)
        picked = self._ask(
            _objects_prompt(instruction, scene, self.lib),
            image,
            "object_graph",
            OBJECTS_SCHEMA,
            lambda reply: _check_objects(reply, scene, self.lib),
        )
        names = [o["name"] for o in picked["objects"]]
        steps = self._ask(
            self._plan_prompt(instruction, names, grounded),
            image,
            "plan",
            STEPS_SCHEMA,
            lambda reply: _check_steps(reply, names, grounded),
        )
        return _plan(instruction, picked, steps, grounded)

    # ---- the conversation -----------------------------------------------------------------

    def _ask(
        self, prompt: str, image: np.ndarray | None, name: str, schema: dict[str, Any], check: Any
    ) -> dict[str, Any]:
        """Ask until a reply passes ``check`` (which returns its problems), ``attempts`` times."""
        messages: list[dict[str, Any]] = [
            {"role": "system", "content": ROLE},
            {"role": "user", "content": _content(prompt, image)},
        ]
        problems: list[str] = []
        for _ in range(max(self.settings.attempts, 1)):
            text = self._complete(messages, name, schema)
            reply, problems = _decode(text, schema)
            if not problems:
                problems = check(reply)
            if not problems:
                return reply
            messages += [
                {"role": "assistant", "content": text},
                {
                    "role": "user",
                    "content": "Your reply was rejected:\n- "
                    + "\n- ".join(problems)
                    + "\nReply again with JSON that follows the schema and uses only the "
                    "names given.",
                },
            ]
        raise ParseError(
            f"the model ({self.settings.model}) gave no valid {name.replace('_', ' ')} in "
            f"{self.settings.attempts} attempts; the last reply's problems: " + "; ".join(problems)
        )

    def _complete(self, messages: list[dict[str, Any]], name: str, schema: dict[str, Any]) -> str:
        self.transcript.append({"request": name, "messages": list(messages)})
        try:
            response = self.client.chat.completions.create(
                model=self.settings.model,
                messages=messages,
                temperature=self.settings.temperature,
                response_format={
                    "type": "json_schema",
                    "json_schema": {"name": name, "schema": schema, "strict": True},
                },
            )
        except Exception as exc:  # the openai package's connection and status errors
            if type(exc).__module__.startswith("openai"):
                raise VLMError(
                    f"the model server at {self.settings.base_url or 'the default URL'} "
                    f"failed: {type(exc).__name__}: {exc}"
                ) from exc
            raise
        try:
            content = response.choices[0].message.content
        except (AttributeError, IndexError) as exc:
            raise VLMError(f"the model server sent a reply without a message: {exc}") from exc
        return content or ""

    def _plan_prompt(self, instruction: str, names: Sequence[str], grounded: GroundedScene) -> str:
        scene = {o.name: o for o in grounded.scene.objects}
        lines = [
            f"Task: {instruction!r}",
            "",
            "Conventions: SI units (m, rad). A joint's value is 0 closed and grows as it opens. "
            "Left and right are as seen by the robot standing in front of an object and facing "
            "it; a higher z is higher in the room.",
            "",
            "Targets: open (fully open), close (closed), fraction (value in [0, 1] of the "
            "joint's range: halfway is 0.5), delta (move by value, m or rad, > 0, in the "
            "action's direction).",
        ]
        for name in names:
            obj = scene[name]
            c = self._blueprint(obj.concept)
            lines += ["", f"## Object {name!r}: concept {obj.concept}", _first(c["doc"])]
            lines.append("Parameters: " + ", ".join(
                f"{p['name']}={obj.params.get(p['name'], p['default'])}" for p in c["params"]
            ))  # fmt: skip
            lines.append("Grasps: " + "; ".join(
                f"{g['name']} ({_first(g['doc']) or g['mode']})" for g in c["grasps"]
            ))  # fmt: skip
            lines.append("Actions: " + "; ".join(
                f"{a['name']} ({a['verb']} along {a['joint']}, {a['sense']})"
                for a in c["actions"] if a["joint"]
            ))  # fmt: skip
            lines.append("Moving parts (part, joint, range, value now, handle x y z):")
            for u in grounded.units:
                if u.object == name:
                    lines.append(
                        f"- part {u.part!r}: joint {u.joint!r} ({u.kind}) in "
                        f"[{u.lo:.4g}, {u.hi:.4g}], now {u.q0:.4g}; handle at "
                        + " ".join(f"{x:.2f}" for x in u.position)
                        + "; actions "
                        + ", ".join(u.actions)
                    )
        lines += ["", "List the steps, in order, as JSON."]
        return "\n".join(lines)

    def _blueprint(self, concept: str) -> dict[str, Any]:
        return blueprint(self.lib, concept)


def blueprint(lib: Library, concept: str) -> dict[str, Any]:
    """The catalog entry of ``concept`` (cached per library: the catalog reads its grasp
    formulas, seconds per concept)."""
    key = (id(lib), concept)
    if key not in _BLUEPRINTS:
        from grace_dsl.agent.catalog import build_catalog

        _BLUEPRINTS[key] = build_catalog(lib, [concept])["categories"][0]["concepts"][0]
    return _BLUEPRINTS[key]


def _client(settings: VLMSettings) -> Any:
    try:
        from openai import OpenAI
    except ImportError as exc:
        raise VLMError(
            "the VLM parser needs the openai package: pip install grace-dsl[vlm]"
        ) from exc
    return OpenAI(
        api_key=settings.api_key,
        base_url=settings.base_url,
        timeout=settings.timeout,
        max_retries=0,  # the parser's own bounded loop re-asks
    )


def _first(doc: str) -> str:
    from grace_dsl.agent.catalog import _first_sentence

    return _first_sentence(doc or "")


def _objects_prompt(instruction: str, scene: SceneSpec, lib: Library) -> str:
    lines = [
        f"Task: {instruction!r}",
        "",
        "Objects in the scene (name: concept):",
        *(f"- {o.name}: {o.concept}" for o in scene.objects),
        "",
        "Concept synopses (the library):",
    ]
    for name in lib:
        c = lib[name]
        if c.entry["kind"] != "primitive":
            lines.append(f"- {name}: {_first(c.doc)}")
    lines += [
        "",
        "First identify the objects the task concerns, each as a node {name, concept, state} "
        "with the scene's name and concept, then the directed spatial relations between them "
        "as [object, relation, object] triples (left_of, right_of, above, below, part_of).",
    ]
    return "\n".join(lines)


def _content(prompt: str, image: np.ndarray | None) -> Any:
    if image is None:
        return prompt
    return [
        {"type": "text", "text": prompt},
        {"type": "image_url", "image_url": {"url": data_uri(image)}},
    ]


def data_uri(image: np.ndarray) -> str:
    """An RGB (H, W, 3) or grey (H, W) uint8 image as a ``data:image/png;base64,`` URI."""
    return "data:image/png;base64," + base64.b64encode(png_bytes(image)).decode("ascii")


def png_bytes(image: np.ndarray) -> bytes:
    """A minimal PNG encoder (no imaging library needed)."""
    a = np.asarray(image)
    if a.dtype != np.uint8:
        if np.issubdtype(a.dtype, np.floating):
            a = (np.clip(a, 0.0, 1.0) * 255).round().astype(np.uint8)
        else:
            a = np.clip(a, 0, 255).astype(np.uint8)
    if a.ndim == 2:
        colour = 0
    elif a.ndim == 3 and a.shape[2] in (3, 4):
        colour = 2 if a.shape[2] == 3 else 6
    else:
        raise ParseError(f"an image must be (H, W), (H, W, 3) or (H, W, 4), not {a.shape}")
    h, w = a.shape[:2]
    raw = b"".join(b"\x00" + a[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    header = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )


# ---- checking replies ---------------------------------------------------------------------------


def _decode(text: str, schema: dict[str, Any]) -> tuple[Any, list[str]]:
    """The reply's JSON and its schema problems."""
    body = text.strip()
    if body.startswith("```"):  # some servers wrap JSON in a code fence despite the format
        body = body.strip("`").removeprefix("json").strip()
    try:
        reply = json.loads(body)
    except json.JSONDecodeError as exc:
        return None, [f"not valid JSON ({exc.msg} at line {exc.lineno}, column {exc.colno})"]
    return reply, schema_problems(reply, schema)


def schema_problems(value: Any, schema: Mapping[str, Any], where: str = "$") -> list[str]:
    """Where ``value`` breaks ``schema`` (the subset of JSON Schema the prompts use)."""
    kind = schema.get("type")
    types: dict[str, type | tuple[type, ...]] = {
        "object": dict,
        "array": list,
        "string": str,
        "number": (int, float),
        "boolean": bool,
    }
    if kind in types and (
        not isinstance(value, types[kind]) or (kind == "number" and isinstance(value, bool))
    ):
        return [f"{where} must be a {kind}, not {type(value).__name__}"]
    if "enum" in schema and value not in schema["enum"]:
        return [f"{where} must be one of {', '.join(map(str, schema['enum']))}, not {value!r}"]
    out: list[str] = []
    if kind == "object":
        props = schema.get("properties", {})
        out += [f"{where}.{k} is missing" for k in schema.get("required", ()) if k not in value]
        if schema.get("additionalProperties") is False:
            out += [f"{where}.{k} is not allowed" for k in value if k not in props]
        for k, sub in props.items():
            if k in value:
                out += schema_problems(value[k], sub, f"{where}.{k}")
    elif kind == "array" and "items" in schema:
        for i, item in enumerate(value):
            out += schema_problems(item, schema["items"], f"{where}[{i}]")
    return out


def _check_objects(reply: Mapping[str, Any], scene: SceneSpec, lib: Library) -> list[str]:
    from grace_dsl.runtime.concept import suggest

    concepts = {o.name: o.concept for o in scene.objects}
    out = []
    if not reply["objects"]:
        out.append("objects is empty: name at least the object the task acts on")
    for i, o in enumerate(reply["objects"]):
        if o["name"] not in concepts:
            out.append(
                f"objects[{i}]: no object {o['name']!r} in the scene"
                + suggest(o["name"], list(concepts))
            )
        elif o["concept"] not in lib:
            out.append(
                f"objects[{i}]: no concept {o['concept']!r} in the library"
                + suggest(o["concept"], list(lib))
            )
        elif o["concept"] != concepts[o["name"]]:
            out.append(
                f"objects[{i}]: {o['name']!r} is a {concepts[o['name']]}, not a {o['concept']}"
            )
    for i, r in enumerate(reply["relations"]):
        if len(r) != 3:
            out.append(f"relations[{i}] must be [object, relation, object]")
        elif r[0] not in concepts or r[2] not in concepts:
            out.append(f"relations[{i}]: {r[0]!r} and {r[2]!r} must both be scene objects")
    return out  # fmt: skip


def _check_steps(reply: Mapping[str, Any], names: Sequence[str], g: GroundedScene) -> list[str]:
    out = []
    if not reply["steps"]:
        out.append("steps is empty: the task needs at least one step")
    for i, s in enumerate(reply["steps"]):
        where = f"steps[{i}]"
        if s["object"] not in names:
            out.append(f"{where}: object {s['object']!r} is not one of {', '.join(names)}")
            continue
        unit = _unit_of(g, s["object"], s["action"])
        if unit is None:
            known = sorted(a for u in g.units if u.object == s["object"] for a in u.actions)
            out.append(
                f"{where}: {s['object']!r} has no action {s['action']!r} that moves a joint; "
                f"its actions: {', '.join(known)}"
            )
            continue
        if s["part"] != unit.part:
            out.append(
                f"{where}: action {s['action']!r} moves part {unit.part!r}, not {s['part']!r}"
            )
        kind, value = s["target"]["kind"], s["target"]["value"]
        if kind == "fraction" and not 0.0 <= value <= 1.0:
            out.append(f"{where}: a fraction target must be within [0, 1], not {value}")
        if kind == "delta" and not value > 0.0:
            out.append(f"{where}: a delta target must be > 0 (the action gives the direction)")
    return out  # fmt: skip


def _unit_of(g: GroundedScene, obj: str, action: str) -> Unit | None:
    return next((u for u in g.units if u.object == obj and action in u.actions), None)


def _plan(
    instruction: str, picked: Mapping[str, Any], steps: Mapping[str, Any], g: GroundedScene
) -> Plan:
    q = {(u.object, u.joint): u.q0 for u in g.units}
    subtasks: list[SubTask] = []
    for s in steps["steps"]:
        unit = _unit_of(g, s["object"], s["action"])
        assert unit is not None  # checked
        value = float(s["target"]["value"]) if s["target"]["kind"] in ("fraction", "delta") else 0.0
        target = Target(s["target"]["kind"], value)
        key = (unit.object, unit.joint)
        subtasks.append(make_subtask(s["text"], unit, s["action"], target, q[key]))
        q[key] = nominal_value(target, unit, q[key], s["action"], unit.actions)
    relations: dict[str, list[tuple[str, str]]] = {}
    for a, r, b in picked["relations"]:
        relations.setdefault(a, []).append((r, b))
    notes = [f"{o['name']}: {o['state']}" for o in picked["objects"] if o["state"]]
    notes += [
        f"check {k + 1}: {s['success']}" for k, s in enumerate(steps["steps"]) if s["success"]
    ]
    return assemble(instruction, subtasks, g, notes, {k: tuple(v) for k, v in relations.items()})
