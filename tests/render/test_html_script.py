"""The viewer page's script blocks are inert to user text: a title such as ``<!--<script>`` (set
through the Python API) used to put the HTML parser into its double-escaped state, so the
viewer's own ``</script>`` no longer ended its block and the viewer never ran."""

from __future__ import annotations

import json
import re
import subprocess
from dataclasses import replace
from pathlib import Path

import pytest

from grace_dsl.render import describe
from grace_dsl.render.html import SCRIPT_HAZARDS, scene_html, script_json
from tests.render.conftest import chromium, needs_chromium

HOSTILE = ["<!--<script>", "</script><script>alert(1)</script>", "a\u2028b & <b>", "<!--"]


@pytest.fixture(scope="module")
def hostile(toy):
    scene = describe(toy["ToyBox"].instantiate(joints={"hinge": 0.5}))
    return replace(scene, title=" ".join(HOSTILE))


def _scripts(page: str) -> list[str]:
    """The text of every script block, cut where the HTML parser would cut it: at the first
    ``</script`` (valid only while no ``<!--`` is open, which the assertions below ensure)."""
    return re.findall(r"<script[^>]*>(.*?)</script", page, re.S | re.I)


def test_script_blocks_hold_no_html_hazards(hostile) -> None:
    page = scene_html(hostile, "<!--<script>")
    scripts = _scripts(page)
    assert len(scripts) == 2  # the scene data and the viewer
    for text in scripts:
        for hazard in SCRIPT_HAZARDS:
            assert hazard not in text.lower(), hazard
    data = json.loads(scripts[0])
    assert data["title"] == hostile.title  # the escapes decode to the title as given


@pytest.mark.parametrize("text", [*HOSTILE, "<SCRIPT", "</ScRiPt >", "\u2029"])
def test_script_json_has_no_angle_brackets_and_round_trips(text: str) -> None:
    encoded = script_json({"t": text, "n": [1.5, None]})
    assert "<" not in encoded and ">" not in encoded and "\u2028" not in encoded
    assert json.loads(encoded) == {"t": text, "n": [1.5, None]}


@needs_chromium
@pytest.mark.slow
def test_viewer_runs_with_a_hostile_title(hostile, tmp_path: Path) -> None:
    page = tmp_path / "hostile.html"
    page.write_text(scene_html(hostile, "<!--<script>"), encoding="utf-8")
    dom = subprocess.run(
        [
            str(chromium()),
            "--headless",
            "--no-sandbox",
            "--window-size=640,480",
            "--virtual-time-budget=3000",
            "--dump-dom",
            page.resolve().as_uri() + "#2d",
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    body = re.search(r"<body[^>]*>", dom)
    assert body is not None and 'data-renderer="2d"' in body.group(0)  # the viewer ran
    assert dom.lower().count("<script") == 2  # the title made no element of its own
