"""The arguments that make an instance (``CONCEPT [PATHS] --param --joint --pose
--instance-json``), shared by ``eacc export`` and ``eacc show``.

Textual values become typed ones through the concept's schema; numbers take the language's
units (``--joint hinge=45deg``, ``--param size=600mm,400mm,20mm``; a bare number is SI), and
every error a user can cause is an ``ExportUsageError`` with one line of message.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.cli.files import UserFileError, read_bytes
from grace_dsl.cli.units import UnitSyntaxError, quantities, quantity
from grace_dsl.export.common import rpy_matrix
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
    """A command-line value in the parameter's type: numbers with the language's units
    (``600mm``, ``45deg``; bare numbers are SI), vectors as ``x,y,z``."""
    if spec.kind == "choice":
        return text.strip("'\"")
    if spec.kind == "bool":
        if text.lower() not in ("true", "false", "1", "0"):
            raise ExportUsageError(f"{spec.name} is a bool: give true or false, not {text!r}")
        return text.lower() in ("true", "1")
    try:
        values = quantities(text, spec.dim)
    except UnitSyntaxError as exc:
        example = {"length": " (e.g. 600mm or 0.6)", "angle": " (e.g. 45deg or 0.785)"}
        raise ExportUsageError(
            f"{spec.name} takes {spec.size} number(s) of type {spec.type}"
            f"{example.get(spec.dim or '', '')}: {exc}"
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


def joint_values(given: Mapping[str, str], kinds: Mapping[str, str]) -> dict[str, float]:
    """``{"hinge": "45deg"}`` -> ``{"hinge": 0.785...}``: a revolute joint takes an angle, a
    prismatic one a length (``kinds``: joint name -> kind); bare numbers are SI. Unknown joint
    names pass through as plain numbers so ``instantiate`` reports them with a suggestion."""
    out: dict[str, float] = {}
    for name, text in given.items():
        kind = kinds.get(name)
        dim = None if kind is None else "length" if kind == "prismatic" else "angle"
        try:
            out[name] = quantity(text, dim)
        except UnitSyntaxError as exc:
            unit = {"length": " (m, or 100mm)", "angle": " (rad, or 45deg)"}.get(dim or "", "")
            raise ExportUsageError(f"joint {name} takes a number{unit}: {exc}") from None
    return out


def pose_numbers(text: str, where: str = "--pose") -> list[float]:
    """The numbers of ``x,y,z[,roll,pitch,yaw]`` (lengths and angles may carry units:
    ``0.5,100mm,0,0,0,90deg``) or of a row-major 4x4."""
    parts = [x for x in text.strip("()[] ").replace(",", " ").split() if x]
    dims = ("length",) * 3 + ("angle",) * 3 if len(parts) in (3, 6) else ()
    values = []
    for i, part in enumerate(parts):
        try:
            values.append(quantity(part, dims[i] if dims else None))
        except UnitSyntaxError as exc:
            try:
                values.append(float(part))  # nan and inf: refused as not finite below
            except ValueError:
                raise ExportUsageError(
                    f"{where} takes numbers separated by commas (x,y,z[,roll,pitch,yaw] or 16 "
                    f"for a 4x4), not {text!r}: {exc}"
                ) from None
    return values


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
    return pose_from_numbers(pose_numbers(text, where), where)


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
        data = json.loads(read_bytes(Path(path)).decode("utf-8"))
    except UserFileError as exc:
        raise ExportUsageError(f"cannot read the instance file {exc}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ExportUsageError(f"cannot read the instance file {path}: {exc}") from None
    except RecursionError:
        raise ExportUsageError(
            f"cannot read the instance file {path}: its JSON is nested too deeply"
        ) from None
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
    p.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a parameter's value with units (600mm, 45deg; a vector 600mm,400mm,20mm); "
        "a bare number is SI (m, rad)",
    )
    p.add_argument(
        "--joint",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a joint's value: 45deg or 100mm; a bare number is SI (rad, m)",
    )
    p.add_argument(
        "--pose",
        metavar="X,Y,Z[,R,P,Y]",
        help="the instance pose in the world: x,y,z (m, or with units: 500mm), "
        "x,y,z,roll,pitch,yaw (rad, or 90deg; Rz(yaw) Ry(pitch) Rx(roll)) or 16 numbers "
        "(row-major 4x4); --pose=-1,0,0 for a leading minus",
    )
    p.add_argument(
        "--instance-json",
        "--params-json",
        dest="instance_json",
        metavar="FILE",
        help='{name: value} parameters, or {"params": {...}, "joints": {...}, "pose": [...]}; '
        "command-line values override it",
    )


def instance_from_args(args: Any, library: Any) -> Instance:
    """The instance that ``add_instance_arguments``'s values describe (typed errors if bad):
    the file's values overridden by the command line's."""
    concept = library[args.concept]
    file = read_instance_json(getattr(args, "instance_json", None))
    params = param_values(concept.params, file.params, assignments(args.param, "--param"))
    kinds = {name: j["kind"] for name, j in concept.joints.items()}
    joints = {**file.joints, **joint_values(assignments(args.joint, "--joint"), kinds)}
    given = getattr(args, "pose", None)
    pose = parse_pose(given) if given is not None else file.pose
    return concept.instantiate(pose=pose, joints=joints, **params)
