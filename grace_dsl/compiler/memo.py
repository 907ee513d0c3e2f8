"""Skip the front end when nothing it read has changed: the build's memo.

Loading the standard library with every unit cached still parsed and checked all of its files
(1-4 s, most of a CLI command's or a simulation worker's start). A successful, warning-free build
therefore records what its front end depended on: the root files the request expanded to, each
file's text digest, and for every ``use`` the module it named and the file it resolved to. A
later build of the same request reads the files, compares digests, re-resolves each ``use``
(a few ``stat`` calls: a new module earlier on the search path changes the answer) and, when all
agree, loads the recorded units directly.

The memo is plain JSON naming unit keys; it lives in the private build cache and only selects
units, which are still verified one by one (and must name the file and text digest they were
built from), so a damaged or foreign memo can cost a rebuild, never load anything untrusted.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from grace_dsl.compiler.resolve import Program, find_module, root_files

MEMO_FORMAT = 1


@dataclass(frozen=True)
class Recalled:
    """What a memo hit gives the build: the sources and the unit key of each compiled file."""

    sources: dict[str, str]
    unit_keys: dict[str, str]  # file -> key, for the files that hold concepts


def request_key(paths: Sequence[str | Path], search: Sequence[Path], build_seed: str) -> str:
    """The memo's name: the request (its paths and search path) under one compiler and mode."""
    h = hashlib.sha256(f"memo-{MEMO_FORMAT}\0{build_seed}".encode())
    for p in paths:
        h.update(b"path\0" + str(Path(p).resolve()).encode())
    for s in search:
        h.update(b"search\0" + str(s).encode())
    return h.hexdigest()[:32]


def record(
    memo_dir: Path, key: str, prog: Program, unit_keys: dict[str, str], files: Sequence[str]
) -> None:
    """Write the memo of a successful build, atomically (a reader sees the old one or this)."""
    data: dict[str, Any] = {
        "format": MEMO_FORMAT,
        "roots": list(prog.roots),
        "files": {f: _sha(src.text) for f, src in prog.files.items()},
        "uses": {
            f: [[list(use.module), target] for use, target in _uses(prog, f)] for f in prog.files
        },
        "units": {f: unit_keys[f] for f in files},
    }
    with contextlib.suppress(OSError):
        memo_dir.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f"{key}-", suffix=".tmp", dir=memo_dir)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as out:
                json.dump(data, out)
            os.replace(tmp, memo_dir / f"{key}.json")
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def recall(
    memo_dir: Path, key: str, paths: Sequence[str | Path], search: Sequence[Path]
) -> Recalled | None:
    """The recorded build of this request if every file and ``use`` still reads the same."""
    try:
        data = json.loads((memo_dir / f"{key}.json").read_text(encoding="utf-8"))
        return _check(data, paths, search)
    except (OSError, ValueError, TypeError, KeyError, AttributeError):
        return None  # missing or damaged: the caller runs the front end


def _check(data: Any, paths: Sequence[str | Path], search: Sequence[Path]) -> Recalled | None:
    if data.get("format") != MEMO_FORMAT:
        return None
    if [str(p) for p in root_files(paths, [])] != list(data["roots"]):
        return None
    sources: dict[str, str] = {}
    for f, digest in dict(data["files"]).items():
        text = Path(f).read_bytes().decode("utf-8").removeprefix("\ufeff")
        if _sha(text) != digest:
            return None
        sources[str(f)] = text
    for f, uses in dict(data["uses"]).items():
        for module, target in uses:
            found = find_module(tuple(module), Path(f).parent, list(search))
            if (str(found) if found is not None else None) != target:
                return None
    units = {str(f): str(k) for f, k in dict(data["units"]).items()}
    if not set(units) <= set(sources):
        return None
    return Recalled(sources, units)


def _uses(prog: Program, file: str) -> list[tuple[Any, str | None]]:
    module = prog.files[file].module
    uses = list(module.uses) if module is not None else []
    return list(zip(uses, prog.use_targets.get(file, []), strict=False))


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()
