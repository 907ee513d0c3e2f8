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
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.export.common import geom_file_stem, mesh_dir_name, output_file, rpy_matrix
from grace_dsl.export.meshes import MESH_FORMATS, mesh_summary, write_instance_mesh
from grace_dsl.export.mjcf import MJCF_NATIVE, write_mjcf
from grace_dsl.export.model import DENSITY, WALL, ExportModel, ExportOptions, build_model
from grace_dsl.export.urdf import URDF_NATIVE, write_urdf
from grace_dsl.runtime.concept import ParamSpec
from grace_dsl.runtime.errors import GraceError
from grace_dsl.runtime.instance import Instance, rigid_problem


class ExportUsageError(GraceError):
    """A malformed ``name=value``, pose or option, or an unreadable or malformed instance file."""


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
    try:
        values = numbers(text)
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


def numbers(text: str) -> list[float]:
    """``"1, 2 3"`` or ``"[1,2,3]"`` -> [1.0, 2.0, 3.0] (ValueError if a part is not a number)."""
    return [float(x) for x in text.strip("()[] ").replace(",", " ").split() if x]


def pose_from_numbers(values: Sequence[float], where: str) -> np.ndarray:
    """A rigid 4x4 pose from 3 numbers (x, y, z), 6 (x, y, z, roll, pitch, yaw; m, rad) or 16
    (a row-major 4x4); ``where`` names the source in the error."""
    v = np.asarray(values, dtype=float).reshape(-1)
    if not np.all(np.isfinite(v)):
        raise ExportUsageError(f"{where}: every number must be finite, got {v.tolist()}")
    pose = np.eye(4)
    if len(v) in (3, 6):
        pose[:3, 3] = v[:3]
        if len(v) == 6:
            pose[:3, :3] = rpy_matrix(*v[3:])
        return pose
    if len(v) != 16:
        raise ExportUsageError(
            f"{where} takes 3 numbers (x,y,z), 6 (x,y,z,roll,pitch,yaw in m and rad) or 16 "
            f"(a row-major 4x4 matrix), got {len(v)}"
        )
    pose = v.reshape(4, 4)
    problem = rigid_problem(pose)
    if problem is not None:
        raise ExportUsageError(f"{where}: the 4x4 matrix is not a rigid transform: {problem}")
    return pose


def parse_pose(text: str, where: str = "--pose") -> np.ndarray:
    """``--pose x,y,z`` | ``x,y,z,roll,pitch,yaw`` | 16 numbers (row-major 4x4)."""
    try:
        values = numbers(text)
    except ValueError:
        raise ExportUsageError(
            f"{where} takes numbers separated by commas (x,y,z[,roll,pitch,yaw] or 16 for a "
            f"4x4), not {text!r}"
        ) from None
    return pose_from_numbers(values, where)


INSTANCE_KEYS = ("params", "joints", "pose")


@dataclass(frozen=True)
class InstanceFile:
    """What an instance file (``--instance-json``) says: parameters, joint values, a pose."""

    params: dict[str, Any] = field(default_factory=dict)
    joints: dict[str, float] = field(default_factory=dict)
    pose: np.ndarray | None = None


def read_instance_json(path: str | None) -> InstanceFile:
    """The file's values: a flat object is parameters ``{name: value}``; an object with any of
    the keys ``params``, ``joints``, ``pose`` is the structured form and holds nothing else."""
    if path is None:
        return InstanceFile()
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExportUsageError(f"cannot read the instance file {path}: {exc}") from None
    if not isinstance(data, dict):
        raise ExportUsageError(
            f"{path} must hold a JSON object: {{name: value}} parameters, or "
            '{"params": {...}, "joints": {...}, "pose": [...]}'
        )
    if not any(k in data for k in INSTANCE_KEYS):
        return InstanceFile(params=data)
    extra = [k for k in data if k not in INSTANCE_KEYS]
    if extra:
        raise ExportUsageError(
            f"{path}: unknown key(s) {', '.join(map(repr, extra))}; an instance file with "
            '"params", "joints" or "pose" holds only those (parameters go inside "params")'
        )
    return InstanceFile(
        _json_object(data.get("params", {}), f'{path}: "params"'),
        _json_joints(data.get("joints", {}), f'{path}: "joints"'),
        None if data.get("pose") is None else _json_pose(data["pose"], f'{path}: "pose"'),
    )


def _json_object(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ExportUsageError(f"{where} must be an object {{name: value}}, not {value!r}")
    return value


def _json_joints(value: Any, where: str) -> dict[str, float]:
    joints = _json_object(value, where)
    for name, v in joints.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ExportUsageError(f"{where}: joint {name} takes a number (SI), not {v!r}")
    return {k: float(v) for k, v in joints.items()}


def _json_pose(value: Any, where: str) -> np.ndarray:
    """A list of 3, 6 or 16 numbers, or a 4x4 list of rows."""
    flat = value
    if isinstance(value, list) and value and all(isinstance(row, list) for row in value):
        if len(value) != 4 or any(len(row) != 4 for row in value):
            raise ExportUsageError(f"{where}: a matrix must be 4 rows of 4 numbers")
        flat = [x for row in value for x in row]
    if not isinstance(flat, list) or not all(
        isinstance(x, (int, float)) and not isinstance(x, bool) for x in flat
    ):
        raise ExportUsageError(
            f"{where} must be a list of 3, 6 (x,y,z,roll,pitch,yaw) or 16 numbers, or 4 rows "
            f"of 4, not {value!r}"
        )
    return pose_from_numbers(flat, where)


def add_instance_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments that pick a concept and its values: CONCEPT [PATHS] --param --joint --pose
    --instance-json (alias --params-json)."""
    p.add_argument("concept")
    p.add_argument("paths", nargs="*", help="default: the standard library")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE", help="SI")
    p.add_argument("--joint", action="append", default=[], metavar="NAME=VALUE", help="SI")
    p.add_argument(
        "--pose",
        metavar="X,Y,Z[,R,P,Y]",
        help="the instance pose in the world: x,y,z (m), x,y,z,roll,pitch,yaw (rad; "
        "Rz(yaw) Ry(pitch) Rx(roll)) or 16 numbers (row-major 4x4); --pose=-1,0,0 for a "
        "leading minus",
    )
    p.add_argument(
        "--instance-json",
        "--params-json",
        dest="instance_json",
        metavar="FILE",
        help='{name: value} parameters, or {"params": {...}, "joints": {...}, "pose": [...]}; '
        "command-line values override it",
    )


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
        help=f"wall thickness of hollow bodies (default {WALL:g} m: each solid weighs the "
        "lesser of its volume and a shell this thick)",
    )
    p.add_argument("--json", action="store_true", help="print a summary as JSON")


def instance_from_args(args: Any, library: Any) -> Instance:
    """The instance that ``add_instance_arguments``'s values describe (typed errors if bad):
    the file's values overridden by the command line's."""
    concept = library[args.concept]
    file = read_instance_json(getattr(args, "instance_json", None))
    params = param_values(concept.params, file.params, assignments(args.param, "--param"))
    joints = {**file.joints, **joint_values(assignments(args.joint, "--joint"))}
    given = getattr(args, "pose", None)
    pose = parse_pose(given) if given is not None else file.pose
    return concept.instantiate(pose=pose, joints=joints, **params)


def positive(text: str | None, option: str, unit: str, default: float) -> float:
    """A strictly positive, finite number given as text (``default`` when not given)."""
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ExportUsageError(f"{option} takes a positive number in {unit}, not {text!r}")
    return value


def export_options(args: Any) -> ExportOptions:
    """``--density`` and ``--wall`` as export options."""
    return ExportOptions(
        density=positive(getattr(args, "density", None), "--density", "kg/m^3", DENSITY),
        wall=positive(getattr(args, "wall", None), "--wall", "m", WALL),
    )


def count(n: int, one: str, many: str | None = None) -> str:
    """``count(1, "link")`` -> "1 link", ``count(2, "joint axis", "joint axes")`` -> "2 joint
    axes"."""
    return f"{n} {one if n == 1 else many or one + 's'}"


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
        options = export_options(args)
        output_file(target, {"urdf": ".urdf", "mjcf": ".xml"}.get(fmt, f".{fmt}"))
        inst = instance_from_args(args, library)
        if fmt in MESH_FORMATS:
            mesh = write_instance_mesh(inst, target, fmt, link)
        else:
            model = build_model(inst, options)
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
        f"wrote {target} ({fmt}, {what}): {count(len(mesh.vertices), 'vertex', 'vertices')}, "
        f"{count(len(mesh.faces), 'face')}, volume {info['volume']:.6g} m^3"
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
                "masses": {link.name: link.inertial.mass for link in model.links},
                "joints": [
                    {"name": j.name, "kind": j.kind, "value": j.value, "range": [j.lo, j.hi]}
                    for j in model.joints
                ],
                "warnings": list(model.warnings),
            }
        )
        return
    mass = sum(link.inertial.mass for link in model.links)
    print_text(
        f"wrote {target} ({fmt}): {count(len(model.links), 'link')}, "
        f"{count(len(model.joints), 'joint')}, {count(len(meshes), 'mesh file')}, "
        f"{mass:.3g} kg"
    )
