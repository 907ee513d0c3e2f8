"""Helpers shared by the URDF and MJCF writers: number formatting, rotations, mesh files."""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from grace_dsl.export.shapes import Geom
from grace_dsl.runtime.errors import GraceError
from grace_dsl.tolerances import DEGENERATE


class ExportPathError(GraceError):
    """An output path that names a directory where a file is expected."""


def output_file(path: str | Path, suffix: str) -> Path:
    """``path`` as the file to write; a directory (existing, or written with a trailing
    separator) is refused, since writing "into" it would silently create a file named like it.
    ``suffix`` (``".urdf"``) only shapes the suggestion in the message."""
    text = os.fspath(path)
    target = Path(text)
    if text.endswith(("/", os.sep)) or target.is_dir():
        raise ExportPathError(
            f"{text} is a directory: give a file name, e.g. {target / ('model' + suffix)}"
        )
    return target


def num(v: float) -> str:
    """Enough digits that a round trip through the XML keeps poses to ~1e-15."""
    out = format(float(v), ".15g")
    return "0" if out == "-0" else out


def vec(values: Iterable[float]) -> str:
    return " ".join(num(v) for v in values)


def rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw of a rotation matrix: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) > DEGENERATE:
        return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])
    return 0.0, pitch, math.atan2(-r[0, 1], r[1, 1])  # gimbal lock: only yaw - roll is defined


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``: the language's ``rpy`` (fixed axes x, y, z), as URDF."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def quat_wxyz(r: np.ndarray) -> tuple[float, float, float, float]:
    """The unit quaternion (w, x, y, z; MJCF's order) of a rotation matrix (Shepperd's method)."""
    tr = float(np.trace(r))
    if tr > 0:
        s = 2 * math.sqrt(tr + 1)
        return s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2 * math.sqrt(1 + r[i, i] - r[j, j] - r[k, k])
    q = [0.0, 0.0, 0.0, 0.0]
    q[0] = (r[k, j] - r[j, k]) / s
    q[1 + i] = s / 4
    q[1 + j] = (r[j, i] + r[i, j]) / s
    q[1 + k] = (r[k, i] + r[i, k]) / s
    return q[0], q[1], q[2], q[3]


def mesh_dir_name(path: Path) -> str:
    """The mesh directory next to ``path``, as written in the XML (relative to the file)."""
    return f"{path.stem}_meshes"


def write_mesh(geom: Geom, directory: Path | None, relative: str, ext: str) -> str:
    """Write the geom's mesh (in its own frame) as ``<name>.<ext>``; return the relative name."""
    filename = f"{relative}/{geom_file_stem(geom)}.{ext}"
    if directory is not None:
        directory.mkdir(parents=True, exist_ok=True)
        geom.mesh.export(directory / f"{geom_file_stem(geom)}.{ext}")
    return filename


def geom_file_stem(geom: Geom) -> str:
    return xml_name(geom.name)  # the same spelling as links and joints


def xml_name(name: str) -> str:
    """``handle.pull`` -> ``handle__pull``; a repeated member's index and a variant's option
    join with one underscore: ``drawer[2].handle[0]@bar`` -> ``drawer_2__handle_0_bar``."""
    name = re.sub(r"\[(-?\d+)\]", lambda m: "_" + m.group(1).replace("-", "m"), name)
    return re.sub(r"[^A-Za-z0-9_]", "_", name.replace(".", "__"))


def to_text(root: ET.Element, comment: str) -> str:
    ET.indent(root, space="  ")
    body = ET.tostring(root, encoding="unicode")
    return f'<?xml version="1.0" encoding="utf-8"?>\n<!-- {comment} -->\n{body}\n'
