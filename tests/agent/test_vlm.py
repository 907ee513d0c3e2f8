"""The VLM client against a fake OpenAI-compatible server on 127.0.0.1 (real HTTP, started here):
good replies, malformed JSON, schema violations, unknown names, and running out of attempts."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.agent.errors import ParseError, VLMError
from grace_dsl.agent.plan import SceneSpec, Target
from grace_dsl.agent.vlm import (
    STEPS_SCHEMA,
    VLMParser,
    VLMSettings,
    blueprint,
    png_bytes,
    schema_problems,
)

pytest.importorskip("openai")


class FakeServer:
    """Answers /v1/chat/completions with queued message contents and keeps every request."""

    def __init__(self) -> None:
        self.replies: list[str] = []
        self.requests: list[dict[str, Any]] = []
        fake = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self) -> None:  # noqa: N802 - the http.server interface
                body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
                fake.requests.append({"path": self.path, "body": body})
                content = fake.replies.pop(0) if fake.replies else "{}"
                data = json.dumps(
                    {
                        "id": f"fake-{len(fake.requests)}",
                        "object": "chat.completion",
                        "created": 0,
                        "model": body.get("model", ""),
                        "choices": [
                            {
                                "index": 0,
                                "message": {"role": "assistant", "content": content},
                                "finish_reason": "stop",
                            }
                        ],
                        "usage": {"prompt_tokens": 1, "completion_tokens": 1, "total_tokens": 2},
                    }
                ).encode()
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                self.end_headers()
                self.wfile.write(data)

            def log_message(self, *args: Any) -> None:
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/v1"
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)

    def __enter__(self) -> FakeServer:
        self.thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()


@pytest.fixture
def server() -> Iterator[FakeServer]:
    with FakeServer() as s:
        yield s


@pytest.fixture(scope="module", autouse=True)
def blueprints(lib: eac.Library) -> None:
    """The catalog entries the replies name, built once (seconds each) before the tests."""
    for concept in ("ChestOfDrawers", "Microwave"):
        blueprint(lib, concept)


@pytest.fixture
def vlm(lib: eac.Library, server: FakeServer) -> VLMParser:
    settings = VLMSettings(api_key="test", base_url=server.url, model="fake-vl", attempts=3)
    return VLMParser(lib, settings)


OBJECTS = json.dumps(
    {
        "objects": [
            {"name": "chest", "concept": "ChestOfDrawers", "state": "all drawers closed"},
            {"name": "microwave", "concept": "Microwave", "state": "door closed"},
        ],
        "relations": [["chest", "left_of", "microwave"]],
    }
)


def _steps(*steps: dict[str, Any]) -> str:
    return json.dumps({"steps": list(steps)})


def _step(
    obj: str, part: str, action: str, kind: str = "open", value: float = 0.0
) -> dict[str, Any]:
    return {
        "text": f"{action} the {part}",
        "object": obj,
        "part": part,
        "action": action,
        "target": {"kind": kind, "value": value},
        "success": f"the {part} is {kind}",
    }


GOOD_STEPS = _steps(
    _step("chest", "drawer1", "open1"),
    _step("microwave", "leaf", "open", "fraction", 0.5),
)


def test_good_replies_make_a_grounded_plan(
    vlm: VLMParser, server: FakeServer, scenes: dict[str, SceneSpec]
) -> None:
    server.replies += [OBJECTS, GOOD_STEPS]
    image = np.zeros((4, 6, 3), np.uint8)
    plan = vlm.parse(
        "open the top drawer and the microwave halfway", scenes["kitchen"], image=image
    )
    assert [(s.object, s.joint, s.target) for s in plan.subtasks] == [
        ("chest", "slide1", Target("open")),
        ("microwave", "hinge", Target("fraction", 0.5)),
    ]
    assert plan.subtasks[0].condition.lo == pytest.approx(0.175)
    assert plan.objects[0].relations == (("left_of", "microwave"),)
    first, second = (r["body"] for r in server.requests)
    assert all(r["path"] == "/v1/chat/completions" for r in server.requests)
    assert first["model"] == "fake-vl"
    assert first["response_format"]["type"] == "json_schema"
    content = first["messages"][1]["content"]
    assert content[1]["image_url"]["url"].startswith("data:image/png;base64,")
    assert "Refrigerator:" in content[0]["text"]  # the synopses of the whole library
    text = second["messages"][1]["content"][0]["text"]
    assert "open1 (pull along slide1, opening)" in text  # the blueprint of the chosen concept
    assert "part 'drawer1'" in text and "Refrigerator" not in text


@pytest.mark.parametrize(
    ("bad", "problem"),
    [
        ('{"objects": [', "not valid JSON"),
        ('{"objects": [{"name": "chest"}], "relations": []}', "$.objects[0].concept is missing"),
        ('{"objects": [], "relations": [], "x": 1}', "$.x is not allowed"),
    ],
)
def test_malformed_and_schema_violating_replies_are_re_asked(
    vlm: VLMParser, server: FakeServer, scenes: dict[str, SceneSpec], bad: str, problem: str
) -> None:
    server.replies += [bad, OBJECTS, GOOD_STEPS]
    plan = vlm.parse("open the top drawer and the microwave halfway", scenes["kitchen"])
    assert len(plan.subtasks) == 2
    retry = server.requests[1]["body"]["messages"]
    assert retry[-2] == {"role": "assistant", "content": bad}
    assert problem in retry[-1]["content"]


@pytest.mark.parametrize(
    ("objects", "steps", "problem"),
    [
        (OBJECTS.replace('"chest"', '"chset"', 1), GOOD_STEPS, "no object 'chset' in the scene"),
        (OBJECTS.replace("Microwave", "Toaster", 1), GOOD_STEPS, "'microwave' is a Microwave"),
        (OBJECTS, _steps(_step("chest", "drawer1", "open9")), "no action 'open9'"),
        (OBJECTS, _steps(_step("chest", "drawer2", "open1")), "moves part 'drawer1'"),
        (OBJECTS, _steps(_step("chest", "drawer1", "open1", "fraction", 1.5)), "within [0, 1]"),
        (OBJECTS, _steps(_step("chest", "drawer1", "open1", "ajar")), "must be one of"),
    ],
)
def test_unknown_names_are_rejected_with_the_error(
    vlm: VLMParser,
    server: FakeServer,
    scenes: dict[str, SceneSpec],
    objects: str,
    steps: str,
    problem: str,
) -> None:
    server.replies += (
        [objects, OBJECTS, steps, GOOD_STEPS]
        if objects != OBJECTS
        else [objects, steps, GOOD_STEPS]
    )
    plan = vlm.parse("open the top drawer", scenes["kitchen"])
    assert plan.subtasks[0].joint == "slide1"
    rejections = [
        m["content"]
        for r in server.requests
        for m in r["body"]["messages"]
        if m["role"] == "user" and isinstance(m["content"], str) and "rejected" in m["content"]
    ]
    assert any(problem in m for m in rejections), rejections


def test_running_out_of_attempts_is_a_parse_error(
    vlm: VLMParser, server: FakeServer, scenes: dict[str, SceneSpec]
) -> None:
    server.replies += ["not json"] * 3
    with pytest.raises(ParseError, match="no valid object graph in 3 attempts.*not valid JSON"):
        vlm.parse("open the top drawer", scenes["kitchen"])
    assert len(server.requests) == 3


def test_unreachable_server_and_missing_key(lib: eac.Library, scenes: dict[str, SceneSpec]) -> None:
    with FakeServer() as s:
        url = s.url
    settings = VLMSettings(api_key="test", base_url=url, timeout=2.0)  # nothing listens there now
    with pytest.raises(VLMError, match="failed: APIConnectionError"):
        VLMParser(lib, settings).parse("open the fridge", scenes["kitchen"])
    with pytest.raises(VLMError, match="GRACE_VLM_API_KEY"):
        VLMSettings.from_env({})
    env = {"OPENAI_API_KEY": "k", "GRACE_VLM_BASE_URL": "http://h/v1", "GRACE_VLM_MODEL": "m"}
    assert VLMSettings.from_env(env) == VLMSettings("k", "http://h/v1", "m")


def test_png_and_schema_helpers() -> None:
    data = png_bytes(np.full((2, 3, 3), 200, np.uint8))
    assert (
        data.startswith(b"\x89PNG\r\n\x1a\n")
        and b"IHDR" in data
        and data.endswith(b"IEND\xaeB`\x82")
    )
    problems = schema_problems({"steps": [{"text": 1}]}, STEPS_SCHEMA)
    assert "$.steps[0].text must be a string, not int" in problems
    assert "$.steps[0].object is missing" in problems
