"""``eacc export``: instantiate a concept from command-line values and write URDF, MJCF or a
mesh file (OBJ, STL, GLB).

Kept out of ``cli/eacc.py`` so the command line stays a thin layer: here the textual values
(``--param size=0.5,0.8,0.025``) are turned into typed ones using the concept's schema, and
every error a user can cause becomes one message and exit code 1. ``add_instance_arguments`` and
``instance_from_args`` serve every command that makes an instance (``eacc show`` too).
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from grace_dsl.export.common import geom_file_stem, mesh_dir_name
from grace_dsl.export.meshes import MESH_FORMATS, mesh_summary, write_instance_mesh
from grace_dsl.export.mjcf import MJCF_NATIVE, write_mjcf
from grace_dsl.export.model import ExportModel, build_model
from grace_dsl.export.urdf import URDF_NATIVE, write_urdf
from grace_dsl.runtime.concept import ParamSpec
from grace_dsl.runtime.errors import GraceError
from grace_dsl.runtime.instance import Instance


class ExportUsageError(GraceError):
    """A malformed ``name=value`` or an unreadable parameter file."""


def assignments(items: Sequence[str], option: str) -> dict[str, str]:
    """``["a=1", "b=x"]`` -> ``{"a": "1", "b": "x"}``; later items win."""
    out: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ExportUsageError(f"{option} expects NAME=VALUE, got {item!r}")
        out[name.strip()] = value.strip()
    return out


def typed_value(spec: ParamSpec, text: str) -> Any:
    """A command-line value in the parameter's type (SI numbers, vectors as ``x,y,z``)."""
    if spec.kind == "choice":
        return text.strip("'\"")
    if spec.kind == "bool":
        if text.lower() not in ("true", "false", "1", "0"):
            raise ExportUsageError(f"{spec.name} is a bool: give true or false, not {text!r}")
        return text.lower() in ("true", "1")
    parts = [x for x in text.strip("()[] ").replace(",", " ").split() if x]
    try:
        values = [float(x) for x in parts]
    except ValueError:
        raise ExportUsageError(
            f"{spec.name} takes {spec.size} number(s) in SI units ({spec.type}), not {text!r}"
        ) from None
    return tuple(values) if spec.kind == "vec" or len(values) != 1 else values[0]


def param_values(
    specs: Sequence[ParamSpec], from_file: Mapping[str, Any], given: Mapping[str, str]
) -> dict[str, Any]:
    """File values (already typed JSON) overridden by command-line ones (converted by schema).

    Unknown names pass through so ``instantiate`` reports them with a suggestion."""
    by_name = {s.name: s for s in specs}
    out = {k: tuple(v) if isinstance(v, list) else v for k, v in from_file.items()}
    for name, text in given.items():
        out[name] = typed_value(by_name[name], text) if name in by_name else text
    return out


def joint_values(given: Mapping[str, str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for name, text in given.items():
        try:
            out[name] = float(text)
        except ValueError:
            raise ExportUsageError(f"joint {name} takes a number (SI), not {text!r}") from None
    return out


def read_params_json(path: str | None) -> dict[str, Any]:
    if path is None:
        return {}
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ExportUsageError(f"cannot read parameters from {path}: {exc}") from None
    if not isinstance(data, dict):
        raise ExportUsageError(f"{path} must hold a JSON object {{name: value}}")
    return data


def add_instance_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments that pick a concept and its values: CONCEPT [PATHS] --param --params-json
    --joint."""
    p.add_argument("concept")
    p.add_argument("paths", nargs="*", help="default: the standard library")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="SI")
    p.add_argument("--params-json", metavar="FILE", help="a JSON object {name: value} (SI)")
    p.add_argument("--joint", action="append", default=[], metavar="NAME=VALUE", help="SI")


def add_export_arguments(p: argparse.ArgumentParser) -> None:
    """``eacc export``'s arguments: the instance, one output format, ``--link``, ``--json``."""
    add_instance_arguments(p)
    fmt = p.add_mutually_exclusive_group(required=True)
    fmt.add_argument("--urdf", metavar="FILE", help="write URDF here (meshes next to it)")
    fmt.add_argument("--mjcf", metavar="FILE", help="write MJCF (MuJoCo) here (meshes next to it)")
    fmt.add_argument("--obj", metavar="FILE", help="write the instance's mesh as OBJ (world frame)")
    fmt.add_argument("--stl", metavar="FILE", help="write the instance's mesh as STL (world frame)")
    fmt.add_argument("--glb", metavar="FILE", help="write a GLB scene: one coloured node per link")
    p.add_argument("--link", metavar="NAME", help="with --obj/--stl/--glb: only this link")
    p.add_argument("--json", action="store_true", help="print a summary as JSON")


def instance_from_args(args: Any, library: Any) -> Instance:
    """The instance that ``add_instance_arguments``'s values describe (typed errors if bad)."""
    concept = library[args.concept]
    params = param_values(
        concept.params,
        read_params_json(args.params_json),
        assignments(args.param, "--param"),
    )
    joints = joint_values(assignments(args.joint, "--joint"))
    return concept.instantiate(joints=joints, **params)


def _format(args: Any) -> tuple[str, str]:
    for fmt in ("urdf", "mjcf", *MESH_FORMATS):
        target = getattr(args, fmt, None)
        if target is not None:
            return fmt, target
    raise ExportUsageError("give one of --urdf, --mjcf, --obj, --stl, --glb")


def run_export(args: Any, library: Any) -> int:
    """The body of ``eacc export`` once the library is compiled (``args`` from argparse)."""
    try:
        fmt, target = _format(args)
        link = getattr(args, "link", None)
        if link is not None and fmt not in MESH_FORMATS:
            raise ExportUsageError(
                "--link picks one link of a mesh file: use --obj, --stl or --glb"
            )
        inst = instance_from_args(args, library)
        if fmt in MESH_FORMATS:
            mesh = write_instance_mesh(inst, target, fmt, link)
        else:
            model = build_model(inst)
            (write_urdf if fmt == "urdf" else write_mjcf)(model, target)
    except (GraceError, OSError, ValueError) as exc:
        sys.stderr.write(f"eacc: {exc}\n")
        return 1
    if fmt in MESH_FORMATS:
        _mesh_summary(inst.concept.name, mesh, fmt, Path(target), link, args.json)
    else:
        _summary(model, fmt, Path(target), args.json)
    return 0


def _mesh_summary(
    name: str, mesh: Any, fmt: str, target: Path, link: str | None, as_json: bool
) -> None:
    from grace_dsl.cli.output import print_json, print_text

    info = mesh_summary(mesh)
    if as_json:
        print_json({"concept": name, "format": fmt, "output": str(target), "link": link, **info})
        return
    what = f"link {link}" if link else "all links"
    print_text(
        f"wrote {target} ({fmt}, {what}): {info['vertices']} vertices, {info['faces']} faces, "
        f"volume {info['volume']:.6g} m^3"
    )


def _summary(model: ExportModel, fmt: str, target: Path, as_json: bool) -> None:
    from grace_dsl.cli.output import print_json, print_text

    native, ext = (URDF_NATIVE, "obj") if fmt == "urdf" else (MJCF_NATIVE, "stl")
    meshes = [
        str(target.parent / mesh_dir_name(target) / f"{geom_file_stem(g)}.{ext}")
        for link in model.links
        for g in link.geoms
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
                "joints": [
                    {"name": j.name, "kind": j.kind, "value": j.value, "range": [j.lo, j.hi]}
                    for j in model.joints
                ],
                "warnings": list(model.warnings),
            }
        )
        return
    print_text(
        f"wrote {target} ({fmt}): {len(model.links)} links, {len(model.joints)} joints, "
        f"{len(meshes)} mesh files"
    )
