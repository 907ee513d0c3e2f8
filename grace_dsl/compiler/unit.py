"""A unit on disk: its files, the digest that seals them, and the checks made before any use.

A unit directory (named by its key) holds ``unit.json`` (manifest entries), ``functions.json``
(serialized CasADi functions), optionally a native library ``grace_<hash>.so`` with its ``.c`` and
``.so.sha256``, and ``digest.json``: the sha256 of every other file. ``verify`` checks all of it
before anything is deserialized or ``dlopen``ed: the directory is private (``grace_dsl.cache``),
its name is a key, the files are exactly the sealed ones, plain files, with the recorded bytes,
and both JSON files carry this compiler's format and the directory's key. A unit that fails is
rebuilt by ``build``, or refused with one line by ``load_artifact``; it is never half-used.
"""

from __future__ import annotations

import json
import logging
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi

from grace_dsl.cache import untrusted_reason
from grace_dsl.compiler import native
from grace_dsl.compiler.native import LIBRARY_NAME, file_sha256
from grace_dsl.runtime.errors import GraceError

logger = logging.getLogger(__name__)

#: The schema of unit.json, digest.json and an artifact's manifest.json; bump on any change.
UNIT_FORMAT = 2
DIGEST = "digest.json"
KEY = re.compile(r"[0-9a-f]{32}\Z")


class UnitError(GraceError):
    """A compiled unit or artifact that is corrupted, of another format, or not safe to load."""


@dataclass(frozen=True)
class Unit:
    file: str
    key: str
    dir: Path
    concepts: dict[str, dict[str, Any]]
    source_sha256: str = ""
    native: str | None = None  # file name of the unit's library, if it has one


def seal(unit_dir: Path, key: str) -> None:
    """Make the files private and read-only for others, then record their digests."""
    files = {}
    for path in sorted(unit_dir.iterdir()):
        path.chmod(0o644)
        files[path.name] = file_sha256(path)
    unit_dir.chmod(0o755)
    text = json.dumps({"format": UNIT_FORMAT, "key": key, "files": files}, indent=1)
    (unit_dir / DIGEST).write_text(text)
    (unit_dir / DIGEST).chmod(0o644)


def verify(unit_dir: Path) -> str | None:
    """Why the unit in ``unit_dir`` must not be used, or None when it is intact and trusted."""
    if not KEY.match(unit_dir.name):
        return f"{unit_dir.name!r} is not a unit key"
    reason = untrusted_reason(unit_dir)
    if reason is not None:
        return reason
    try:
        digest = _json_object(unit_dir / DIGEST)
        files = digest.get("files")
        if digest.get("format") != UNIT_FORMAT or digest.get("key") != unit_dir.name:
            found = digest.get("format")
            return f"{DIGEST} has format {found!r}, this compiler reads {UNIT_FORMAT}"
        if not isinstance(files, dict):
            return f"{DIGEST} lists no files"
        present = {p.name for p in unit_dir.iterdir()} - {DIGEST}
        if present != set(files) or not {"unit.json", "functions.json"} <= present:
            return f"its files {sorted(present)} are not the sealed ones {sorted(files)}"
        for name, sha in files.items():
            st = os.lstat(unit_dir / name)
            if not stat.S_ISREG(st.st_mode):
                return f"{name} is not a regular file"
            if st.st_uid not in (os.geteuid(), 0) or st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
                return f"{name} is writable by someone else"
            if file_sha256(unit_dir / name) != sha:
                return f"{name} does not match its digest"
        unit = _json_object(unit_dir / "unit.json")
    except (OSError, ValueError) as exc:
        return f"unreadable ({exc})"
    if unit.get("format") != UNIT_FORMAT or unit.get("key") != unit_dir.name:
        return f"unit.json has format {unit.get('format')!r}, this compiler reads {UNIT_FORMAT}"
    lib = unit.get("native")
    if lib is not None and (not isinstance(lib, str) or not LIBRARY_NAME.match(lib)):
        return f"unit.json names a library {lib!r} this compiler does not write"
    return None


def load_unit(unit_dir: Path) -> Unit:
    """The verified unit in ``unit_dir``; :class:`UnitError` names what is wrong otherwise."""
    reason = verify(unit_dir)
    if reason is not None:
        raise UnitError(f"{unit_dir}: {reason}; rebuild it with `eacc build`")
    return read_verified(unit_dir)


def read_verified(unit_dir: Path) -> Unit:
    """The unit in ``unit_dir``, which :func:`verify` has just accepted."""
    data = _json_object(unit_dir / "unit.json")
    try:
        return Unit(
            str(data["file"]),
            str(data["key"]),
            unit_dir,
            dict(data["concepts"]),
            str(data.get("source_sha256", "")),
            data.get("native"),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise UnitError(f"{unit_dir}: unit.json is incomplete ({exc}); rebuild it") from None


def unit_evaluators(unit: Unit) -> dict[str, native.Evaluator]:
    """The unit's functions, verified again just before they are deserialized and loaded
    (the files may have changed since the build): native kernels where the unit has them."""
    reason = verify(unit.dir)
    if reason is not None:
        raise UnitError(f"{unit.dir}: {reason}; run again to rebuild it")
    data = _json_object(unit.dir / "functions.json")
    functions = {n: casadi.Function.deserialize(s) for n, s in data.items()}
    if unit.native is not None:
        try:
            return native.load_unit_library(unit.dir / unit.native, functions)
        except (OSError, ValueError) as exc:
            logger.warning("cannot load %s (%s); using CasADi's VM", unit.native, exc)
    return {n: native.CasadiEvaluator(f) for n, f in functions.items()}


def _json_object(path: Path) -> dict[str, Any]:
    data = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError(f"{path.name} is not a JSON object")
    return data
