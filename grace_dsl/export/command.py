"""``eacc export``: instantiate a concept from command-line values and write URDF or MJCF.

Kept out of ``cli/eacc.py`` so the command line stays a thin layer: here the textual values
(``--param size=0.5,0.8,0.025``) are turned into typed ones using the concept's schema, and
every error a user can cause becomes one message and exit code 1.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from grace_dsl.export.common import geom_file_stem, mesh_dir_name
from grace_dsl.export.mjcf import MJCF_NATIVE, write_mjcf
from grace_dsl.export.model import ExportModel, build_model
from grace_dsl.export.urdf import URDF_NATIVE, write_urdf
from grace_dsl.runtime.concept import ParamSpec
from grace_dsl.runtime.errors import GraceError


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


def run_export(args: Any, library: Any) -> int:
    """The body of ``eacc export`` once the library is compiled (``args`` from argparse)."""
    try:
        concept = library[args.concept]
        params = param_values(
            concept.params,
            read_params_json(args.params_json),
            assignments(args.param, "--param"),
        )
        joints = joint_values(assignments(args.joint, "--joint"))
        inst = concept.instantiate(joints=joints, **params)
        model = build_model(inst)
        fmt, target = ("urdf", args.urdf) if args.urdf is not None else ("mjcf", args.mjcf)
        (write_urdf if fmt == "urdf" else write_mjcf)(model, target)
    except (GraceError, OSError) as exc:
        sys.stderr.write(f"eacc: {exc}\n")
        return 1
    _summary(model, fmt, Path(target), args.json)
    return 0


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
