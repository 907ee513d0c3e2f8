"""What a picture costs: scene description, MuJoCo PNG and HTML page of every library concept.

Run: ``.venv/bin/python bench/bench_render.py [--concepts NAME ...] [--out FILE] [--smoke]``
(writes bench/results/render.json; ``--smoke``: one concept, as the test suite runs it). Every
concept of the standard library at its defaults: ``describe`` (meshes per link, grasps, forces,
joint axes), ``render_image`` at 640x480 (MJCF export, MuJoCo model compile, GL context, render,
read back) with ``MUJOCO_GL`` as set (default here: osmesa, software), the palette PNG's size,
and the HTML page's size and build time. The first render also pays MuJoCo's import.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import platform
import statistics
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "osmesa")

from PIL import Image  # noqa: E402

import grace_dsl as eac  # noqa: E402
from grace_dsl.export import build_model  # noqa: E402
from grace_dsl.render import describe  # noqa: E402
from grace_dsl.render.html import scene_html  # noqa: E402
from grace_dsl.render.png import import_mujoco, render_image  # noqa: E402

OUT = Path(__file__).parent / "results" / "render.json"


def _timed(fn: Any) -> tuple[Any, float]:
    t = time.perf_counter()
    value = fn()
    return value, time.perf_counter() - t


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--concepts", nargs="+", help="only these (default: every concept)")
    parser.add_argument("--out", type=Path, default=OUT, help="where the JSON goes")
    parser.add_argument("--smoke", action="store_true", help="one concept: checks it runs")
    args = parser.parse_args()
    if args.smoke:
        args.concepts = args.concepts or ["LidBox"]
    lib = eac.load_library()
    _, import_s = _timed(import_mujoco)
    rows = []
    names = args.concepts or [n for n in lib if lib[n].entry["kind"] == "concept"]
    for name in names:
        concept = lib[name]
        inst = concept.instantiate()
        scene, t_describe = _timed(lambda inst=inst: describe(inst))
        img, t_png = _timed(lambda s=scene, i=inst: render_image(s, 640, 480, build_model(i)))
        buf = io.BytesIO()
        Image.fromarray(img).quantize(256, method=Image.Quantize.MEDIANCUT).save(buf, "PNG")
        page, t_html = _timed(lambda s=scene: scene_html(s))
        rows.append(
            {
                "concept": name,
                "faces": sum(len(p.faces) for p in scene.parts),
                "describe_s": t_describe,
                "png_s": t_png,
                "png_bytes": buf.tell(),
                "html_s": t_html,
                "html_bytes": len(page.encode()),
            }
        )
        print(f"{name:16s} {t_describe:6.3f} s {t_png:6.3f} s {t_html:6.3f} s")
    summary = {
        key: {
            "median": statistics.median(r[key] for r in rows),
            "max": max(r[key] for r in rows),
        }
        for key in ("describe_s", "png_s", "png_bytes", "html_s", "html_bytes")
    }
    result = {
        "machine": platform.platform(),
        "python": platform.python_version(),
        "mujoco_gl": os.environ.get("MUJOCO_GL"),
        "mujoco_import_s": import_s,
        "concepts": len(rows),
        "summary": summary,
        "rows": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
