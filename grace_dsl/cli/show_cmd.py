"""``eacc show`` (one instance as PNG and/or HTML) and ``eacc gallery`` (a PNG of every concept
and primitive). The instance comes from the same arguments as ``eacc export``; every error a
user can cause is one message and exit code 1. Pictures and pages are written atomically
(``cli.files``), and the report says what they overwrote.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from grace_dsl.cli.files import Written, atomic_write, staged
from grace_dsl.cli.instance_args import ExportUsageError, add_instance_arguments, instance_from_args
from grace_dsl.cli.output import count, error, print_json, print_text
from grace_dsl.render.png import RenderError
from grace_dsl.render.scene import Scene, describe, primitive_scene
from grace_dsl.runtime.concept import suggest
from grace_dsl.runtime.errors import GraceError

GALLERY_SIZE = (640, 480)
DEFAULT_GALLERY = "docs/gallery"


def add_show_arguments(p: argparse.ArgumentParser) -> None:
    add_instance_arguments(p)
    p.add_argument("--png", metavar="FILE", help="render with MuJoCo (offscreen) to this PNG")
    p.add_argument("--html", metavar="FILE", help="write a self-contained viewer page here")
    p.add_argument(
        "--grasps", type=int, default=3, metavar="N", help="frames per grasp family (default 3)"
    )
    p.add_argument("--size", default="800x600", metavar="WxH", help="PNG size (default 800x600)")
    p.add_argument("--json", action="store_true", help="print what the scene shows as JSON")


def add_gallery_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("paths", nargs="*", help="default: the standard library")
    p.add_argument(
        "-o", "--output", default=DEFAULT_GALLERY, help=f"directory (default {DEFAULT_GALLERY})"
    )
    p.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="NAME",
        help="draw only this concept or primitive (repeatable)",
    )
    p.add_argument("--json", action="store_true", help="print the pictures written as JSON")


def image_size(text: str) -> tuple[int, int]:
    """``"800x600"`` -> (800, 600)."""
    w, sep, h = text.lower().partition("x")
    if not sep or not w.strip().isdigit() or not h.strip().isdigit():
        raise ExportUsageError(f"--size takes WIDTHxHEIGHT in pixels, e.g. 800x600, not {text!r}")
    return int(w), int(h)


# ---- show ---------------------------------------------------------------------------------------


def run_show(args: Any, library: Any) -> int:
    """The body of ``eacc show`` once the library is compiled."""
    from grace_dsl.render.html import scene_html

    written: list[Written] = []
    try:
        width, height = image_size(args.size)
        inst = instance_from_args(args, library)
        scene = describe(inst, grasps=args.grasps)
        subtitle = _subtitle(inst)
        if args.png is not None:
            from grace_dsl.export.model import build_model
            from grace_dsl.render.png import write_png

            model = build_model(inst)
            png = Path(args.png)
            written += staged(png, lambda p: write_png(scene, p, width, height, model))[1]
        if args.html is not None:
            written.append(atomic_write(args.html, scene_html(scene, subtitle)))
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc))
        return 1
    _report(scene, len(inst.concept.links), args, written)
    return 0


def _subtitle(inst: Any) -> str:
    joints = ", ".join(f"{n} = {v:.4g}" for n, v in inst.joints.items())  # present copies only
    return joints or "no moving joints"


def _report(scene: Scene, links: int, args: Any, changes: list[Written]) -> None:
    """One line: the concept's links (and how many have shapes, when not all do, since a
    link without shapes draws nothing), grasp frames, forces and joint axes; then a note per
    file overwritten."""
    info = scene.summary()
    written = [f for f in (args.png, args.html) if f is not None]
    overwritten = [str(w.path) for w in changes if w.replaced]
    if args.json:
        print_json({**info, "png": args.png, "html": args.html, "overwritten": overwritten})
        return
    frames = sum(info["grasp_frames"].values())
    shaped = f" ({len(scene.parts)} with shapes)" if len(scene.parts) != links else ""
    print_text(
        f"{scene.title}: {count(links, 'link')}{shaped}, {count(frames, 'grasp frame')}, "
        f"{count(len(scene.forces), 'force')}, "
        f"{count(len(scene.joints), 'joint axis', 'joint axes')}"
        + (f" -> {', '.join(written)}" if written else "")
    )
    for note in [*scene.notes, *(w.note() for w in changes if w.replaced)]:
        print_text(f"note: {note}")


# ---- gallery ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Picture:
    name: str
    kind: str  # concept | primitive
    path: Path


def gallery_jobs(library: Any, output: Path) -> list[tuple[Picture, Callable[[], Any]]]:
    """What the gallery draws: every concept of ``library`` (``<output>/<Name>.png``) and every
    primitive of the geometry registry (``<output>/primitives/<Name>.png``), at defaults."""
    from grace_dsl.geometry import PRIMITIVES

    jobs: list[tuple[Picture, Callable[[], Any]]] = []
    for name in library:
        concept = library[name]
        if concept.entry["kind"] == "concept":
            pic = Picture(name, "concept", output / f"{name}.png")
            jobs.append((pic, partial(_concept_png, concept, pic.path)))
    for name in PRIMITIVES:
        pic = Picture(name, "primitive", output / "primitives" / f"{name}.png")
        jobs.append((pic, partial(_primitive_png, name, pic.path)))
    return jobs


def _concept_png(concept: Any, path: Path) -> Path:
    from grace_dsl.export.model import build_model
    from grace_dsl.render.png import write_png

    inst = concept.instantiate()
    scene, model = describe(inst), build_model(inst)
    staged(path, lambda p: write_png(scene, p, *GALLERY_SIZE, model, palette=True))
    return path


def _primitive_png(name: str, path: Path) -> Path:
    from grace_dsl.render.png import write_png

    scene = primitive_scene(name)
    staged(path, lambda p: write_png(scene, p, *GALLERY_SIZE, palette=True))
    return path


@contextmanager
def _progress(total: int, enabled: bool) -> Iterator[Callable[[str], None]]:
    """A rich progress bar on a terminal (stderr); silent when piped."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    out = Console(stderr=True)
    if not (enabled and out.is_terminal):
        yield lambda _name: None
        return
    columns = (TextColumn("{task.description:<28}"), BarColumn(), MofNCompleteColumn())
    with Progress(*columns, console=out, transient=True) as bar:
        task = bar.add_task("gallery", total=total)

        def step(name: str) -> None:
            bar.update(task, advance=1, description=name)

        yield step


def run_gallery(args: Any, library: Any) -> int:
    """The body of ``eacc gallery``: draw every picture; a failure is reported, not fatal."""
    output = Path(args.output)
    jobs = gallery_jobs(library, output)
    if args.only:
        names = [pic.name for pic, _ in jobs]
        unknown = [n for n in args.only if n not in names]
        if unknown:
            error(f"--only {unknown[0]}: no such concept or primitive" + suggest(unknown[0], names))
            return 1
        jobs = [(pic, job) for pic, job in jobs if pic.name in args.only]
    done: list[Picture] = []
    failed: list[tuple[Picture, str]] = []
    with _progress(len(jobs), not args.json) as step:
        for pic, job in jobs:
            try:
                job()
                done.append(pic)
            except RenderError as exc:  # no GL or no MuJoCo: every picture would fail alike
                error(str(exc))
                return 1
            except (GraceError, OSError, ValueError) as exc:
                failed.append((pic, str(exc)))
            step(pic.name)
    for pic, message in failed:
        error(f"{pic.kind} {pic.name}: {message}")
    if args.json:
        print_json(
            {
                "output": str(output),
                "pictures": [
                    {
                        "name": p.name,
                        "kind": p.kind,
                        "path": str(p.path),
                        "bytes": p.path.stat().st_size,
                    }
                    for p in done
                ],
                "failed": [{"name": p.name, "error": m} for p, m in failed],
            }
        )
    else:
        kb = sum(p.path.stat().st_size for p in done) / 1024
        n_prim = sum(p.kind == "primitive" for p in done)
        print_text(
            f"wrote {len(done) - n_prim} concept and {n_prim} primitive pictures to {output} "
            f"({kb:.0f} KB)" + (f"; {len(failed)} failed" if failed else "")
        )
    return 1 if failed else 0
