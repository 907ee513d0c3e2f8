"""``eacc export``: instantiate a concept from command-line values and write URDF, MJCF or a
mesh file (OBJ, STL, GLB).

Every file goes through ``cli.files.staged``: the exporter writes into a private directory and
each file is then moved into place atomically. The summary says which files were overwritten
(a symlink in the way is replaced, not followed), and meshes left in ``<stem>_meshes/`` by an
earlier export that this one no longer writes are removed, since the export owns that directory.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from grace_dsl.cli.files import Written, remove_files, staged
from grace_dsl.cli.instance_args import ExportUsageError, add_instance_arguments, instance_from_args
from grace_dsl.cli.output import count, error, print_json, print_text
from grace_dsl.cli.units import UnitSyntaxError, quantity
from grace_dsl.export.common import geom_file_stem, mesh_dir_name, output_file
from grace_dsl.export.meshes import MESH_FORMATS, mesh_summary, write_instance_mesh
from grace_dsl.export.mjcf import MJCF_NATIVE, write_mjcf
from grace_dsl.export.model import DENSITY, WALL, ExportModel, ExportOptions, build_model
from grace_dsl.export.urdf import URDF_NATIVE, write_urdf
from grace_dsl.runtime.errors import GraceError

MESH_SUFFIXES = (".obj", ".stl")  # what the URDF and MJCF writers put in <stem>_meshes/


def add_export_arguments(p: argparse.ArgumentParser) -> None:
    """``eacc export``'s arguments: the instance, one output format, ``--link``, the material,
    ``--json``."""
    add_instance_arguments(p)
    fmt = p.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--urdf", metavar="FILE", help="write URDF here (meshes next to it)")
    fmt.add_argument("--mjcf", metavar="FILE", help="write MJCF (MuJoCo) here (meshes next to it)")
    fmt.add_argument("--obj", metavar="FILE", help="write the instance's mesh as OBJ (world frame)")
    fmt.add_argument("--stl", metavar="FILE", help="write the instance's mesh as STL (world frame)")
    fmt.add_argument("--glb", metavar="FILE", help="write a GLB scene: one coloured node per link")
    p.add_argument("--link", metavar="NAME", help="with --obj/--stl/--glb: only this link")
    p.add_argument(
        "--density", metavar="KG_M3", help=f"material density (default {DENSITY:g} kg/m^3, wood)"
    )
    p.add_argument(
        "--wall",
        metavar="M",
        help=f"wall thickness of hollow bodies (default {WALL:g} m; 18mm works too): each "
        "solid weighs the lesser of its volume and a shell this thick",
    )
    p.add_argument("--json", action="store_true", help="print a summary as JSON")


def positive(
    text: str | None, option: str, unit: str, default: float, dim: str | None = None
) -> float:
    """A strictly positive, finite number given as text, with a unit of ``dim`` if any
    (``default`` when not given)."""
    if text is None:
        return default
    try:
        value = quantity(text, dim)
    except UnitSyntaxError:
        value = -1.0
    if not value > 0:
        raise ExportUsageError(f"{option} takes a positive number in {unit}, not {text!r}")
    return value


def export_options(args: Any) -> ExportOptions:
    """``--density`` and ``--wall`` as export options."""
    return ExportOptions(
        density=positive(getattr(args, "density", None), "--density", "kg/m^3", DENSITY),
        wall=positive(getattr(args, "wall", None), "--wall", "m", WALL, "length"),
    )


def _format(args: Any) -> tuple[str, str]:
    for fmt in ("urdf", "mjcf", *MESH_FORMATS):
        target = getattr(args, fmt, None)
        if target is not None:
            return fmt, target
    raise ExportUsageError("give one of --urdf, --mjcf, --obj, --stl, --glb")


def run_export(args: Any, library: Any) -> int:
    """The body of ``eacc export`` once the library is compiled (``args`` from argparse)."""
    try:
        fmt, name = _format(args)
        link = getattr(args, "link", None)
        if link is not None and fmt not in MESH_FORMATS:
            raise ExportUsageError(
                "--link picks one link of a mesh file: use --obj, --stl or --glb"
            )
        options = export_options(args)
        target = output_file(name, {"urdf": ".urdf", "mjcf": ".xml"}.get(fmt, f".{fmt}"))
        inst = instance_from_args(args, library)
        if fmt in MESH_FORMATS:
            mesh, written = staged(target, lambda p: write_instance_mesh(inst, p, fmt, link))
            removed: list[Path] = []
        else:
            model = build_model(inst, options)
            write = write_urdf if fmt == "urdf" else write_mjcf
            _, written = staged(target, lambda p: write(model, p))
            removed = _remove_stale_meshes(target, written)
    except (GraceError, OSError, ValueError) as exc:
        error(str(exc))
        return 1
    if fmt in MESH_FORMATS:
        _mesh_summary(inst.concept.name, mesh, fmt, target, link, args.json, written)
    else:
        _summary(model, fmt, target, args.json, written, removed)
    return 0


def _remove_stale_meshes(target: Path, written: list[Written]) -> list[Path]:
    """Mesh files in ``<stem>_meshes/`` that this export did not write: left by an earlier
    export of another instance, they would be mistaken for part of this one."""
    mesh_dir = target.parent / mesh_dir_name(target)
    if mesh_dir.is_symlink() or not mesh_dir.is_dir():
        return []
    fresh = {w.path for w in written}
    stale = [
        p
        for p in sorted(mesh_dir.iterdir())
        if p.suffix in MESH_SUFFIXES and p not in fresh and (p.is_symlink() or p.is_file())
    ]
    removed = remove_files(stale)
    if not any(mesh_dir.iterdir()):
        mesh_dir.rmdir()
    return removed


def _notes(written: list[Written], removed: list[Path]) -> list[str]:
    """What the export replaced or removed, one line each; many overwritten meshes are counted,
    not listed."""
    notes = [w.note() for w in written if w.replaced == "symlink"]
    files = [w for w in written if w.replaced == "file"]
    meshes = [w for w in files if w.path.suffix in MESH_SUFFIXES]
    notes += [w.note() for w in files if w not in meshes]
    if meshes:
        notes.append(f"overwrote {len(meshes)} mesh file(s) in {meshes[0].path.parent}")
    if removed:
        names = ", ".join(p.name for p in removed)
        notes.append(f"removed {len(removed)} stale mesh file(s) from {removed[0].parent}: {names}")
    return notes


def _changes(written: list[Written], removed: list[Path]) -> dict[str, list[str]]:
    return {
        "overwritten": [str(w.path) for w in written if w.replaced],
        "removed": [str(p) for p in removed],
    }


def _mesh_summary(
    name: str,
    mesh: Any,
    fmt: str,
    target: Path,
    link: str | None,
    as_json: bool,
    written: list[Written],
) -> None:
    info = mesh_summary(mesh)
    if as_json:
        print_json(
            {
                "concept": name,
                "format": fmt,
                "output": str(target),
                "link": link,
                **info,
                **_changes(written, []),
            }
        )
        return
    what = f"link {link}" if link else "all links"
    print_text(
        f"wrote {target} ({fmt}, {what}): {count(len(mesh.vertices), 'vertex', 'vertices')}, "
        f"{count(len(mesh.faces), 'face')}, volume {info['volume']:.6g} m^3"
    )
    for note in _notes(written, []):
        print_text(f"note: {note}")


def _summary(
    model: ExportModel,
    fmt: str,
    target: Path,
    as_json: bool,
    written: list[Written],
    removed: list[Path],
) -> None:
    native, ext = (URDF_NATIVE, "obj") if fmt == "urdf" else (MJCF_NATIVE, "stl")
    geoms = [g for link in model.links for g in link.geoms]
    if fmt == "urdf":  # its collision elements: the convex pieces, as ``<piece>.collision``
        geoms += [replace(g, name=f"{g.name}.collision") for x in model.links for g in x.collision]
    meshes = [
        str(target.parent / mesh_dir_name(target) / f"{geom_file_stem(g)}.{ext}")
        for g in geoms
        if (g.native() or ("mesh",))[0] not in native
    ]
    if as_json:
        print_json(
            {
                "concept": model.name,
                "format": fmt,
                "output": str(target),
                "meshes": meshes,
                "links": [link.name for link in model.links],
                "masses": {link.name: link.inertial.mass for link in model.links},
                "joints": [
                    {"name": j.name, "kind": j.kind, "value": j.value, "range": [j.lo, j.hi]}
                    for j in model.joints
                ],
                "warnings": list(model.warnings),
                **_changes(written, removed),
            }
        )
        return
    mass = sum(link.inertial.mass for link in model.links)
    print_text(
        f"wrote {target} ({fmt}): {count(len(model.links), 'link')}, "
        f"{count(len(model.joints), 'joint')}, {count(len(meshes), 'mesh file')}, "
        f"{mass:.3g} kg"
    )
    for note in _notes(written, removed):
        print_text(f"note: {note}")
