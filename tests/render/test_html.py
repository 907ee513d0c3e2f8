"""The HTML viewer: self-contained (nothing fetched), its data decodes back to the scene, and the
real browser (headless Chromium) draws it with WebGL and with the Canvas-2D fallback."""

from __future__ import annotations

import base64
import json
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from grace_dsl.render import describe, style
from grace_dsl.render.html import scene_html, write_html
from tests.render.conftest import chromium, needs_chromium


@pytest.fixture(scope="module")
def scene(toy):
    return describe(toy["ToyBox"].instantiate(joints={"hinge": 0.5}))


def _data(page: str) -> dict:
    m = re.search(r'<script type="application/json" id="scene-data">(.*?)</script>', page, re.S)
    assert m is not None
    return json.loads(m.group(1))


def test_page_fetches_nothing(scene) -> None:
    page = scene_html(scene)
    assert not re.search(r"https?:|//cdn|<script[^>]+src=|<link[^>]+href=|@import|url\(", page)
    assert "fetch(" not in page and "XMLHttpRequest" not in page


def test_embedded_data_decodes_to_the_scene(scene) -> None:
    data = _data(scene_html(scene, "subtitle <b>escaped</b>"))
    assert [p["link"] for p in data["parts"]] == [p.link for p in scene.parts]
    for entry, part in zip(data["parts"], scene.parts):
        pos = np.frombuffer(base64.b64decode(entry["positions"]), "<f4").reshape(-1, 3)
        idx = np.frombuffer(base64.b64decode(entry["indices"]), "<u4").reshape(-1, 3)
        np.testing.assert_allclose(pos, part.vertices, rtol=1e-6, atol=1e-7)
        np.testing.assert_array_equal(idx, part.faces)
        assert entry["color"] == list(part.color)
    segs = scene.segments()
    assert len(data["segments"]) == len(segs)
    assert data["segments"][0]["start"] == list(segs[0].start)
    assert data["up"] == pytest.approx(list(scene.pose[:3, 1]))


def test_titles_are_escaped(scene) -> None:
    page = scene_html(scene, "<script>alert(1)</script>")
    assert "<script>alert(1)" not in page and "&lt;script&gt;alert(1)" in page


def _screenshot(page: Path, out: Path, fragment: str = "") -> np.ndarray:
    cmd = [
        str(chromium()),
        "--headless",
        "--no-sandbox",
        "--hide-scrollbars",
        f"--screenshot={out}",
        "--window-size=640,480",
        page.resolve().as_uri() + fragment,
    ]
    subprocess.run(cmd, check=True, capture_output=True, timeout=120)
    return np.asarray(Image.open(out).convert("RGB"))


def _check_drawn(img: np.ndarray) -> None:
    """Many colours; the grasp-frame red and the body's shaded colour both present."""
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 100
    r, g, b = (img[..., k].astype(int) for k in range(3))
    assert ((r > 150) & (g < 100) & (b < 100)).sum() > 20  # the x axes of the grasp frames
    # the body (link 0): its warm grey keeps r > g > b whatever the shading
    body = (r - b > 12) & (r >= g) & (g > b) & (r > 80) & (r < 245)
    assert body.sum() > 2000
    bg = np.round(255 * np.array(style.BACKGROUND))
    assert (np.abs(img[5, 320].astype(int) - bg) <= 2).all()  # the page's background


@pytest.mark.slow
@needs_chromium
def test_chromium_draws_the_page(scene, tmp_path) -> None:
    page = write_html(scene, tmp_path / "box.html")
    _check_drawn(_screenshot(page, tmp_path / "shot.png"))


@pytest.mark.slow
@needs_chromium
def test_chromium_draws_the_canvas_2d_fallback(scene, tmp_path) -> None:
    page = write_html(scene, tmp_path / "box.html")
    _check_drawn(_screenshot(page, tmp_path / "shot2d.png", "#2d"))


PROBE = """
<script>
window.addEventListener("error", function (e) {
  document.body.setAttribute("data-error", String(e.message));
});
function later(f) { setTimeout(f, 300); }
setTimeout(function () {
  var c = document.getElementById("view");
  c.dispatchEvent(new MouseEvent("dblclick", { bubbles: true }));
  later(probe);
  function probe() {
  var before = c.toDataURL();
  var at = { clientX: 300, clientY: 200, bubbles: true, pointerId: 1, button: 0 };
  c.dispatchEvent(new PointerEvent("pointerdown", at));
  c.dispatchEvent(new PointerEvent("pointermove", Object.assign({}, at, { clientX: 380 })));
  window.dispatchEvent(new PointerEvent("pointerup", at));
  c.dispatchEvent(new WheelEvent("wheel", { deltaY: 300, bubbles: true, cancelable: true }));
  later(function () {
    var orbited = c.toDataURL();
    c.dispatchEvent(new MouseEvent("dblclick", { bubbles: true }));
    later(function () {
      document.body.setAttribute("data-moved", String(orbited !== before));
      document.body.setAttribute("data-reset", String(c.toDataURL() === before));
    });
  });
  }
}, 100);
</script>
</body>"""


@needs_chromium
@pytest.mark.parametrize("fragment", ["", "#2d"])
def test_orbit_zoom_and_reset_in_chromium(scene, tmp_path, fragment) -> None:
    """Synthetic drag and wheel change the picture; a double-click restores the first view."""
    page = tmp_path / "probe.html"
    page.write_text(scene_html(scene).replace("</body>", PROBE), encoding="utf-8")
    dom = subprocess.run(
        [
            str(chromium()),
            "--headless",
            "--no-sandbox",
            "--window-size=640,480",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.resolve().as_uri() + fragment,
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    body = re.search(r"<body[^>]*>", dom)
    assert body is not None
    assert "data-error" not in body.group(0), body.group(0)
    # the script ran: with WebGL where the browser has it (SwiftShader here), 2D for #2d
    mode = re.search(r'data-renderer="(\w+)"', body.group(0))
    assert mode is not None and mode.group(1) in (("2d",) if fragment else ("webgl", "2d"))
    assert 'data-moved="true"' in body.group(0) and 'data-reset="true"' in body.group(0)
