"""Build driver: front end on every file, then cached, incremental, atomic units per file.

A unit is the compiled form of one .eac file (its on-disk form and checks: ``unit.py``). Its key
hashes the compiler's own source, the C toolchain when native code is built, the file's path and
text, and the keys of the files it imports, so editing one file rebuilds exactly the files that
depend on it, and what a unit records (its file, its source hash) is what its key names.

A unit is written into a private temporary directory under ``tmp/`` (claimed by a lock file that
the kernel releases when the process dies, so the next build removes what a killed one left) and
renamed into place: readers never see half a unit, and when two builds race, the loser discards
its copy. A cached unit that fails verification is moved aside and rebuilt. A cache that is not
private is not read at all; one that is read-only is read, and only what is missing is built in
a private per-user directory. Ctrl-C cancels pending units and stops running compilations.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import logging
import os
import secrets
import shutil
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from grace_dsl.cache import build_dir, existing_private_dir, private_dir, untrusted_reason
from grace_dsl.compiler import memo, native
from grace_dsl.compiler.check import Checked, check
from grace_dsl.compiler.resolve import Program, resolve, search_dirs
from grace_dsl.compiler.unit import (
    UNIT_FORMAT,
    Unit,
    UnitError,
    load_unit,
    read_verified,
    seal,
    verify,
)
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, error, has_errors

__all__ = [
    "UNIT_FORMAT",
    "BuildResult",
    "Progress",
    "Unit",
    "build",
    "compiler_fingerprint",
    "default_cache_dir",
    "export_library",
    "front_end",
    "library_manifest",
    "load_unit",
]

logger = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]  # (file, index, total)
#: A temporary entry without a lock file (a crash before the lock was taken) is removed after this.
ORPHAN_AGE_S = 600.0


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
    """Where units live unless told otherwise: ``build/`` under ``grace_dsl.cache.cache_dir()``."""
    return build_dir()


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
    reuse_front_end: bool = False,
) -> BuildResult:
    """Compile ``paths`` and everything they import into cached units.

    With ``reuse_front_end`` a warning-free earlier build of the same request whose files and
    imports are unchanged is loaded without parsing and checking again (``compiler.memo``);
    callers that show diagnostics leave it off."""
    root = cache_dir or default_cache_dir()
    search = search_dirs(search_path)
    memo_key = memo.request_key(paths, search, _build_seed(use_native))
    if reuse_front_end:
        recalled = _recall(root, memo_key, paths, search)
        if recalled is not None:
            return recalled
    prog, checked, diags = front_end(paths, search_path)
    result = BuildResult(diags, prog.sources())
    if not result.ok:
        return result
    store = _Store.open(root, result.diagnostics)
    keys = _unit_keys(prog, use_native)
    files = [f for f in prog.files if _concepts_of(prog, f)]
    found = {f: store.find(keys[f]) for f in files}
    missing = [f for f in files if found[f] is None]
    result.cache_dir = store.root
    if store.write is not None:
        _clean_tmp(store.write / "tmp")
    if missing:
        target = store.writable(result.diagnostics, len(missing))
        result.cache_dir = target

        def work(f: str, cancelled: native.Cancelled) -> None:
            unit_dir = target / "units" / keys[f]
            _write_unit(unit_dir, prog, checked, f, keys[f], use_native, cancelled)

        _run(missing, work, progress)
        for f in missing:
            found[f] = load_unit(target / "units" / keys[f])
    result.rebuilt = missing
    result.units = [u for u in found.values() if u is not None]
    if not result.diagnostics and store.write is not None and len(result.units) == len(files):
        memo.record(store.write / "memo", memo_key, prog, keys, files)
    return result


def _recall(
    root: Path, key: str, paths: Sequence[str | Path], search: list[Path]
) -> BuildResult | None:
    """The memo's build, when the cache is private and every unit it names is intact and was
    built from the text read now."""
    if not root.is_dir() or untrusted_reason(root) is not None:
        return None
    recalled = memo.recall(root / "memo", key, paths, search)
    if recalled is None:
        return None
    units = []
    for file, unit_key in recalled.unit_keys.items():
        unit_dir = root / "units" / unit_key
        if not unit_dir.is_dir() or verify(unit_dir) is not None:
            return None
        try:
            unit = read_verified(unit_dir)
        except UnitError:
            return None
        if unit.file != file or unit.source_sha256 != _sha(recalled.sources[file]):
            return None
        units.append(unit)
    return BuildResult([], recalled.sources, units, [], root)


@dataclass(frozen=True)
class _Store:
    """Where units are read from and written to, decided once per build."""

    root: Path
    read: tuple[Path, ...]
    write: Path | None  # None: the root is read-only, build into a private fallback

    @staticmethod
    def open(root: Path, diags: list[Diagnostic]) -> _Store:
        with contextlib.suppress(OSError):
            root.mkdir(mode=0o700, parents=True, exist_ok=True)
        reason = untrusted_reason(root) if root.exists() else None
        if reason is not None:
            fallback = private_dir("build")
            diags.append(
                _cache_warning(
                    "E302",
                    root,
                    f"the cache directory {root} is not private ({reason}); nothing in it is "
                    f"loaded, building in {fallback}",
                    "make it yours alone (chown, chmod go-w) or set GRACE_CACHE_DIR",
                )
            )
            return _Store(fallback, (fallback,), fallback if _writable(fallback) else None)
        if _writable(root):
            return _Store(root, (root,), root)
        earlier = existing_private_dir("build")
        return _Store(root, (root,) if earlier is None else (root, earlier), None)

    def find(self, key: str) -> Unit | None:
        """The intact unit ``key``; a broken one in a writable place is moved aside."""
        for place in self.read:
            unit_dir = place / "units" / key
            if not unit_dir.exists():
                continue
            reason = verify(unit_dir)
            if reason is None:
                with contextlib.suppress(UnitError):
                    return read_verified(unit_dir)
                reason = "unit.json is incomplete"
            logger.warning("rebuilding the cached unit %s: %s", unit_dir, reason)
            if place == self.write or place != self.root:
                _discard(unit_dir, place / "tmp")
        return None

    def writable(self, diags: list[Diagnostic], n: int) -> Path:
        if self.write is not None:
            return self.write
        fallback = private_dir("build")
        _writable(fallback)
        diags.append(
            _cache_warning(
                "E301",
                self.root,
                f"the cache directory {self.root} is not writable; its units are used and the "
                f"{n} missing ones are built in {fallback}",
                "set GRACE_CACHE_DIR to a writable directory",
            )
        )
        return fallback


def _writable(cache: Path) -> bool:
    try:
        (cache / "units").mkdir(mode=0o700, parents=True, exist_ok=True)
        (cache / "tmp").mkdir(mode=0o700, parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=cache / "tmp"):
            pass  # proves the cache is writable
        return True
    except OSError:
        return False


def _cache_warning(code: str, where: Path, message: str, hint: str) -> Diagnostic:
    return Diagnostic(code, message, ast.Span(str(where), 0, 0, 0, 0), hint, "warning")


def _run(
    missing: list[str], work: Callable[[str, native.Cancelled], None], progress: Progress | None
) -> None:
    """Build the missing units on a thread per core; any exception (Ctrl-C included) cancels
    the pending ones and tells the running ones to stop, instead of waiting for all of them."""
    # Lowering holds the GIL but the C compiler runs in a subprocess, so a thread per core
    # overlaps one unit's compilation with the next one's lowering.
    stop = threading.Event()
    pool = ThreadPoolExecutor(max_workers=max(1, min(len(missing), os.cpu_count() or 1)))
    try:
        jobs = {pool.submit(work, f, stop.is_set): f for f in missing}
        for done, job in enumerate(as_completed(jobs)):
            job.result()  # re-raise a failure here
            if progress is not None:
                progress(jobs[job], done + 1, len(missing))
    except BaseException:
        stop.set()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()


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


def _build_seed(use_native: bool) -> str:
    """The compiler and the code generator: what every unit key starts from."""
    tool = "native\0" + native.toolchain_fingerprint() if use_native else "vm"
    return f"{compiler_fingerprint()}\0{tool}"


def _unit_keys(prog: Program, use_native: bool) -> dict[str, str]:
    """Per file, the hash of everything its unit depends on, its path included: the unit
    records the path, so the same text at two places is two units."""
    seed = hashlib.sha256(_build_seed(use_native).encode())
    keys: dict[str, str] = {}

    def key(f: str, stack: tuple[str, ...] = ()) -> str:
        if f not in keys:
            h = seed.copy()
            h.update(f.encode() + b"\0" + prog.files[f].text.encode())
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
    unit_dir: Path,
    prog: Program,
    checked: Checked,
    file: str,
    key: str,
    use_native: bool,
    cancelled: native.Cancelled,
) -> None:
    from grace_dsl.compiler.functions import casadi_functions, sympy_model
    from grace_dsl.compiler.manifest import concept_entry

    with _claim(unit_dir.parent.parent / "tmp", key) as tmp:
        entries: dict[str, dict[str, Any]] = {}
        serialized: dict[str, str] = {}
        all_functions = {}
        for ci, name in enumerate(_concepts_of(prog, file)):
            if cancelled():
                raise native.BuildCancelled(file)
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
        lib = _native_library(all_functions, tmp, cancelled) if use_native else None
        unit = {
            "format": UNIT_FORMAT,
            "file": file,
            "key": key,
            "source_sha256": _sha(prog.files[file].text),
            "concepts": entries,
            "native": lib.name if lib is not None else None,
        }
        (tmp / "functions.json").write_text(json.dumps(serialized))
        (tmp / "unit.json").write_text(json.dumps(unit, indent=1))
        seal(tmp, key)
        _place(tmp, unit_dir)


@contextlib.contextmanager
def _claim(tmp_root: Path, key: str) -> Iterator[Path]:
    """A fresh directory under ``tmp_root``, locked (``<dir>.lock``) while this build uses it.

    The kernel drops the lock when the process dies, however it dies, so :func:`_clean_tmp`
    can tell a live build's directory from a killed one's.
    """
    fd, lock = tempfile.mkstemp(prefix=f"{key}-", suffix=".lock", dir=tmp_root)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        tmp = Path(lock[: -len(".lock")])
        tmp.mkdir(mode=0o700)
        try:
            yield tmp
        finally:
            shutil.rmtree(tmp, ignore_errors=True)  # gone already when the unit was placed
    finally:
        Path(lock).unlink(missing_ok=True)
        os.close(fd)


def _place(tmp: Path, unit_dir: Path) -> None:
    """Rename the finished unit into place; a broken unit already there is moved aside first,
    an intact one (another build won the race) is kept and ours dropped."""
    for _ in range(3):
        try:
            os.rename(tmp, unit_dir)
            return
        except OSError:
            if not unit_dir.exists():
                raise
            if verify(unit_dir) is None:
                return
            _discard(unit_dir, tmp.parent)
    os.rename(tmp, unit_dir)


def _discard(unit_dir: Path, tmp_root: Path) -> None:
    """Move a unit aside (one rename, so no reader sees it half-deleted), then delete it."""
    aside = tmp_root / f"discard-{unit_dir.name}-{secrets.token_hex(4)}"
    try:
        os.rename(unit_dir, aside)
    except FileNotFoundError:
        return  # another build moved it already
    except OSError:
        aside = unit_dir
    shutil.rmtree(aside, ignore_errors=True)


def _clean_tmp(tmp_root: Path) -> None:
    """Remove what interrupted builds left in ``tmp_root``: directories whose lock is free,
    and anything without a lock that is older than :data:`ORPHAN_AGE_S`."""
    try:
        entries = list(tmp_root.iterdir())
    except OSError:
        return
    now = time.time()
    for entry in entries:
        with contextlib.suppress(OSError):
            if entry.name.endswith(".lock"):
                _reap(entry)
            elif not Path(f"{entry}.lock").exists() and now - entry.lstat().st_mtime > ORPHAN_AGE_S:
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink()


def _reap(lock: Path) -> None:
    fd = os.open(lock, os.O_RDWR)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return  # a live build holds it
        shutil.rmtree(lock.with_name(lock.name[: -len(".lock")]), ignore_errors=True)
        lock.unlink(missing_ok=True)
    finally:
        os.close(fd)


def _native_library(
    functions: dict[str, Any], out_dir: Path, cancelled: native.Cancelled
) -> Path | None:
    """Compile the unit's functions to C once, at build time; None keeps CasADi's VM."""
    try:
        return native.build_native_library(functions, out_dir, cancelled)
    except native.NativeUnsupportedError:
        return None


def export_library(result: BuildResult, out_dir: Path) -> list[Diagnostic]:
    """Write a self-contained artifact: ``manifest.json`` plus a copy of every unit."""
    try:
        out_dir.mkdir(mode=0o755, parents=True, exist_ok=True)
        (out_dir / "units").mkdir(mode=0o755, exist_ok=True)
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
        os.chmod(tmp_name, 0o644)
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
        "units": {u.key: {"file": u.file, "source_sha256": u.source_sha256} for u in result.units},
        "concepts": {
            name: {**entry, "unit": u.key}
            for u in result.units
            for name, entry in u.concepts.items()
        },
    }


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()
