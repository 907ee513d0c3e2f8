"""Build driver: front end on every file, then cached, incremental, atomic units per file.

A unit is the compiled form of one .eac file: the manifest entries of its concepts, their
serialized CasADi functions and, where a C compiler exists, a native library of them.  Its key
hashes the compiler's own source, the file's text and the keys of the files it imports, so editing
one file rebuilds exactly the files that depend on it.  A unit is written into a private temporary
directory and renamed into place: readers never see half a unit, and when two builds race, the
loser discards its copy and uses the winner's.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import platformdirs

from grace_dsl.compiler import native
from grace_dsl.compiler.check import Checked, check
from grace_dsl.compiler.resolve import Program, resolve
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, error, has_errors

UNIT_FORMAT = 1
Progress = Callable[[str, int, int], None]  # (file, index, total)


@dataclass(frozen=True)
class Unit:
    file: str
    key: str
    dir: Path
    concepts: dict[str, dict[str, Any]]


@dataclass
class BuildResult:
    diagnostics: list[Diagnostic]
    sources: dict[str, str]
    units: list[Unit] = field(default_factory=list)
    rebuilt: list[str] = field(default_factory=list)  # files compiled in this run
    cache_dir: Path | None = None

    @property
    def ok(self) -> bool:
        return not has_errors(self.diagnostics)


def default_cache_dir() -> Path:
    env = os.environ.get("GRACE_CACHE_DIR")
    return Path(env) if env else Path(platformdirs.user_cache_dir("grace-dsl")) / "build"


def front_end(
    paths: Sequence[str | Path], search_path: Sequence[str | Path] = ()
) -> tuple[Program, Checked, list[Diagnostic]]:
    """Parse, resolve and check; the diagnostics of all three passes."""
    prog, diags = resolve(paths, search_path)
    checked, more = check(prog)
    return prog, checked, diags + more


def build(
    paths: Sequence[str | Path],
    cache_dir: Path | None = None,
    search_path: Sequence[str | Path] = (),
    use_native: bool = True,
    progress: Progress | None = None,
) -> BuildResult:
    """Compile ``paths`` and everything they import into cached units."""
    prog, checked, diags = front_end(paths, search_path)
    result = BuildResult(diags, prog.sources())
    if not result.ok:
        return result
    cache = _usable_cache(cache_dir or default_cache_dir(), result.diagnostics)
    result.cache_dir = cache
    keys = _unit_keys(prog)
    files = [f for f in prog.files if _concepts_of(prog, f)]
    missing = [f for f in files if not (cache / "units" / keys[f] / "unit.json").is_file()]
    # Lowering holds the GIL but the C compiler runs in a subprocess, so a thread per core
    # overlaps one unit's compilation with the next one's lowering.
    with ThreadPoolExecutor(max_workers=max(1, min(len(missing), os.cpu_count() or 1))) as pool:
        jobs = {
            pool.submit(
                _write_unit, cache / "units" / keys[f], prog, checked, f, keys[f], use_native
            ): f
            for f in missing
        }
        for done, job in enumerate(as_completed(jobs)):
            job.result()  # re-raise a failure here
            if progress is not None:
                progress(jobs[job], done + 1, len(missing))
    result.rebuilt = missing
    result.units = [load_unit(cache / "units" / keys[f]) for f in files]
    return result


def _usable_cache(cache: Path, diags: list[Diagnostic]) -> Path:
    try:
        (cache / "units").mkdir(parents=True, exist_ok=True)
        (cache / "tmp").mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=cache / "tmp"):
            pass  # proves the cache is writable
        return cache
    except OSError as exc:
        fallback = Path(tempfile.mkdtemp(prefix="grace-dsl-cache-"))
        diags.append(
            Diagnostic(
                "E301",
                f"the cache directory is not writable ({exc.strerror}); building in {fallback}",
                ast.Span(str(cache), 0, 0, 0, 0),
                "set GRACE_CACHE_DIR to a writable directory",
                "warning",
            )
        )
        (fallback / "units").mkdir()
        (fallback / "tmp").mkdir()
        return fallback


@lru_cache(maxsize=1)
def compiler_fingerprint() -> str:
    """A hash of the compiler's own source: a new compiler never reuses an old unit."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256(f"unit-format-{UNIT_FORMAT}".encode())
    for sub in ("lang", "compiler"):
        for path in sorted((root / sub).glob("*.py")) + sorted((root / sub).glob("*.lark")):
            h.update(path.name.encode())
            h.update(path.read_bytes())
    h.update((root / "tolerances.py").read_bytes())  # compiled code holds some of its values
    return h.hexdigest()


def _unit_keys(prog: Program) -> dict[str, str]:
    keys: dict[str, str] = {}

    def key(f: str, stack: tuple[str, ...] = ()) -> str:
        if f not in keys:
            h = hashlib.sha256(compiler_fingerprint().encode())
            h.update(prog.files[f].text.encode())
            for dep in sorted(prog.imports.get(f, [])):
                if dep not in stack:  # cycles were reported; guard anyway
                    h.update(key(dep, (*stack, f)).encode())
            keys[f] = h.hexdigest()[:32]
        return keys[f]

    for f in prog.files:
        key(f)
    return keys


def _concepts_of(prog: Program, file: str) -> list[str]:
    return [n for n, e in prog.concepts.items() if e.file == file]


def _write_unit(
    unit_dir: Path, prog: Program, checked: Checked, file: str, key: str, use_native: bool
) -> None:
    from grace_dsl.compiler.functions import casadi_functions, sympy_model
    from grace_dsl.compiler.manifest import concept_entry

    tmp = Path(tempfile.mkdtemp(prefix=f"{key}-", dir=unit_dir.parent.parent / "tmp"))
    try:
        entries: dict[str, dict[str, Any]] = {}
        serialized: dict[str, str] = {}
        all_functions = {}
        for ci, name in enumerate(_concepts_of(prog, file)):
            compiled = casadi_functions(checked, name)
            names = {k: f"c{ci}_{f.name()}" for k, f in compiled.functions.items()}
            exact = sympy_model(checked, name)
            entries[name] = concept_entry(
                prog.concept(name),
                Path(file).name,
                prog.files[file].text,
                compiled.lowered,
                exact,
                names,
            )
            for k, f in compiled.functions.items():
                serialized[names[k]] = f.serialize()
                all_functions[names[k]] = f
        lib = _native_library(all_functions, tmp) if use_native else None
        unit = {
            "format": UNIT_FORMAT,
            "file": file,
            "key": key,
            "concepts": entries,
            "native": lib.name if lib is not None else None,
        }
        (tmp / "functions.json").write_text(json.dumps(serialized))
        (tmp / "unit.json").write_text(json.dumps(unit, indent=1))
        try:
            os.rename(tmp, unit_dir)
        except OSError:
            if not (unit_dir / "unit.json").is_file():
                raise
            shutil.rmtree(tmp, ignore_errors=True)  # another build won the race
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _native_library(functions: dict[str, Any], out_dir: Path) -> Path | None:
    """Compile the unit's functions to C once, at build time; None keeps CasADi's VM."""
    try:
        return native.build_native_library(functions, out_dir)
    except native.NativeUnsupportedError:
        return None


def load_unit(unit_dir: Path) -> Unit:
    data = json.loads((unit_dir / "unit.json").read_text())
    return Unit(data["file"], data["key"], unit_dir, data["concepts"])


def export_library(result: BuildResult, out_dir: Path) -> list[Diagnostic]:
    """Write a self-contained artifact: ``manifest.json`` plus a copy of every unit."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        for unit in result.units:
            target = out_dir / "units" / unit.key
            if not target.exists():
                tmp = Path(tempfile.mkdtemp(prefix=unit.key, dir=out_dir))
                shutil.copytree(unit.dir, tmp / "unit")
                target.parent.mkdir(exist_ok=True)
                with contextlib.suppress(OSError):  # a concurrent export placed the same unit
                    os.rename(tmp / "unit", target)
                shutil.rmtree(tmp, ignore_errors=True)
        manifest = library_manifest(result)
        fd, tmp_name = tempfile.mkstemp(prefix="manifest-", suffix=".json", dir=out_dir)
        with os.fdopen(fd, "w") as fh:
            json.dump(manifest, fh, indent=1)
        os.replace(tmp_name, out_dir / "manifest.json")
    except OSError as exc:
        return [
            error(
                "E301",
                f"cannot write the artifact to {out_dir}: {exc.strerror}",
                ast.Span(str(out_dir), 0, 0, 0, 0),
            )
        ]
    return []


def library_manifest(result: BuildResult) -> dict[str, Any]:
    return {
        "format": UNIT_FORMAT,
        "compiler": compiler_fingerprint()[:16],
        "units": {
            u.key: {"file": u.file, "source_sha256": _sha(result.sources.get(u.file, ""))}
            for u in result.units
        },
        "concepts": {
            name: {**entry, "unit": u.key}
            for u in result.units
            for name, entry in u.concepts.items()
        },
    }


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()
