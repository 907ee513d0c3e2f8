"""A self-contained HTML page of a scene: opens from ``file://``, with no server and no network.

The page embeds the scene as JSON (meshes as base64 little-endian float32 vertices and uint32
triangle indices) and the viewer ``viewer.js`` (plain JavaScript: WebGL, or a Canvas-2D painter's
algorithm where WebGL is missing, so a headless browser always draws something). It starts from
the same front-right-above view as the PNG.
"""

from __future__ import annotations

import base64
import html
import json
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.render import style
from grace_dsl.render.camera import frame_scene
from grace_dsl.render.scene import Scene

if TYPE_CHECKING:
    from grace_dsl.render.robot import Animation

ASPECT = 4 / 3  # the initial framing; the viewer keeps the field of view when resized
MARGIN = 1.3  # room for the title and legend panels around the object

LEGEND = (
    ("x axis of a frame", style.AXIS_X),
    ("y axis (a gripper's closing direction)", style.AXIS_Y),
    ("z axis (a gripper's approach)", style.AXIS_Z),
    ("force of an action", style.FORCE),
    ("turning axis of an action", style.TWIST),
    ("joint axis (head: opening)", style.JOINT),
)


def _b64(array: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def animation_json(animation: Animation) -> dict[str, Any]:
    """The motions of the animated parts: per part, its 4x4 matrices (row-major, float32) at
    every frame; the times (and the object's joint value) per frame."""
    values = animation.values
    return {
        "frames": len(animation.times),
        "times": _b64(animation.times, "<f4"),
        "values": None if values is None else _b64(values, "<f4"),
        "label": animation.label,
        "tracks": [
            {"part": int(i), "poses": _b64(poses.reshape(-1), "<f4")}
            for i, poses in sorted(animation.tracks.items())
        ],
    }


def scene_json(scene: Scene, animation: Animation | None = None) -> dict[str, Any]:
    """Everything the viewer draws, JSON-ready (with the animation, when there is one)."""
    view = frame_scene(scene, ASPECT, margin=MARGIN)
    return {
        "animation": None if animation is None else animation_json(animation),
        "title": scene.title,
        "background": list(style.BACKGROUND),
        "size": scene.size,
        "up": [float(x) for x in scene.pose[:3, 1]],
        "view": {"eye": list(view.eye), "target": list(view.target), "fovy": view.fovy},
        "parts": [
            {
                "link": p.link,
                "color": list(p.color),
                "opacity": p.opacity,
                "positions": _b64(p.vertices.reshape(-1), "<f4"),
                "indices": _b64(p.faces.reshape(-1), "<u4"),
            }
            for p in scene.parts
        ],
        "segments": [
            {
                "kind": s.kind,
                "label": s.label,
                "start": list(s.start),
                "end": list(s.end),
                "color": list(s.color),
                "radius": s.radius,
                "head": s.head,
            }
            for s in scene.segments()
        ],
    }


# Inside <script>, the HTML parser looks for `</script`, and after `<!--` a `<script` changes
# what ends the block; none of them may appear in what the page embeds there.
SCRIPT_HAZARDS = ("<!--", "<script", "</")

# JSON may spell any character as \uXXXX; these are the ones that can start HTML inside a
# script block (< and >, and & for good measure) or end a JavaScript line (U+2028/9).
_JSON_ESCAPES = {ord(c): f"\\u{ord(c):04x}" for c in "<>&\u2028\u2029"}


def script_json(data: Any) -> str:
    """``data`` as JSON that is inert inside ``<script>``: no ``<`` at all, so no user text
    (a title ``<!--<script>``, say) can end the block early or stop the next one running."""
    text = json.dumps(data, separators=(",", ":"))
    return text.translate(_JSON_ESCAPES)


def _viewer_source() -> str:
    """The viewer's code; it is ours, but is checked all the same before it goes into a page."""
    text = resources.files("grace_dsl.render").joinpath("viewer.js").read_text(encoding="utf-8")
    hazard = next((h for h in SCRIPT_HAZARDS if h in text.lower()), None)
    if hazard is not None:
        raise ValueError(f"viewer.js contains {hazard!r}, which would break its <script> block")
    return text


def _legend(scene: Scene) -> str:
    kinds = {s.color for s in scene.segments()}
    rows = [
        f'<li><span class="swatch" style="background:{style.hex_color(c)}"></span>'
        f"{html.escape(text)}</li>"
        for text, c in LEGEND
        if c in kinds
    ]
    rows += [
        f'<li><span class="swatch" style="background:{style.hex_color(p.color)}"></span>'
        f"link {html.escape(p.link)}</li>"
        for p in scene.parts
    ]
    return "<ul>" + "".join(rows) + "</ul>"


PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
  html, body {{ margin: 0; height: 100%; overflow: hidden; background: {bg};
    font: 13px/1.4 system-ui, sans-serif; color: #333; }}
  #view {{ display: block; width: 100%; height: 100%; touch-action: none; cursor: grab; }}
  .panel {{ position: absolute; background: rgba(255, 255, 255, 0.8); padding: 6px 10px;
    border-radius: 4px; pointer-events: none; }}
  #title {{ top: 8px; left: 8px; }}
  #title b {{ font-size: 15px; }}
  #legend {{ bottom: 8px; right: 8px; font-size: 11px; }}
  #legend ul {{ list-style: none; margin: 0; padding: 0; }}
  .swatch {{ display: inline-block; width: 10px; height: 10px; margin-right: 6px;
    border-radius: 2px; vertical-align: -1px; }}
  #player {{ bottom: 8px; left: 8px; pointer-events: auto; }}
  #player input {{ width: 240px; vertical-align: middle; }}
</style>
</head>
<body>
<canvas id="view"></canvas>
<div id="title" class="panel"><b>{title}</b><br>{subtitle}</div>
<div id="legend" class="panel">{legend}</div>
{player}<script type="application/json" id="scene-data">{data}</script>
<script>
{viewer}
</script>
</body>
</html>
"""


PLAYER = (
    '<div id="player" class="panel"><button id="play" type="button">play</button> '
    '<input id="scrub" type="range" min="0" max="{last}" value="0"> <span id="clock"></span>'
    "</div>\n"
)


def scene_html(scene: Scene, subtitle: str = "", animation: Animation | None = None) -> str:
    """The page's text; with ``animation``, a play button and a time slider drive it."""
    data = script_json(scene_json(scene, animation))
    player = "" if animation is None else PLAYER.format(last=len(animation.times) - 1)
    hint = "drag: orbit &middot; wheel: zoom &middot; shift-drag: pan &middot; double-click: reset"
    return PAGE.format(
        title=html.escape(scene.title),
        subtitle=(html.escape(subtitle) + "<br>" if subtitle else "") + hint,
        bg=style.hex_color(style.BACKGROUND),
        legend=_legend(scene),
        player=player,
        data=data,
        viewer=_viewer_source(),
    )


def write_html(scene: Scene, path: str | Path, subtitle: str = "") -> Path:
    """Write the page of ``scene`` to ``path``."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(scene_html(scene, subtitle), encoding="utf-8")
    return target
