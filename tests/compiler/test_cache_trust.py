"""The cache cannot be turned against the user, and a broken cache repairs itself.

Every test builds a real cache in a temp dir and poisons it the way an attacker or a crash would:
a pickle where the grammar tables were, a ``.so`` with a constructor, a ``.so`` rebuilt from the
kept ``.c`` with another constant, truncated or edited JSON, ``../`` in an artifact's manifest.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest

from grace_dsl import cache
from grace_dsl.compiler import build as build_mod
from grace_dsl.compiler import native
from grace_dsl.compiler.build import build, export_library
from grace_dsl.compiler.unit import UNIT_FORMAT, UnitError
from grace_dsl.runtime.errors import GraceError
from grace_dsl.runtime.library import Library, load_artifact
from tests.conftest import write

ROOT = Path(__file__).resolve().parents[2]
BLOCK = """
use primitives.{Cuboid}
/// A plain block.
concept Block {
    param size : vec3 length in [(1mm, 1mm, 1mm), (1m, 1m, 1m)] = (10mm, 20mm, 30mm)
    shape body = Cuboid(size: size)
    grasp top(t in [-size.x / 2, size.x / 2] = 0) = trans(t, 0, size.z / 2) width size.y
}
"""
needs_cc = pytest.mark.skipif(native.find_compiler() is None, reason="no C compiler")


def source(tmp: Path, name: str = "block.eac") -> Path:
    return write(tmp / "src", name, BLOCK)


def unit_of(result: build_mod.BuildResult, name: str) -> Path:
    return next(u.dir for u in result.units if Path(u.file).name == name)


def top_grasps(units: list[build_mod.Unit]) -> np.ndarray:
    inst = Library(units)["Block"].instantiate(size=(0.1, 0.2, 0.3))
    return np.asarray(inst.grasps("top", 5))


def rebuilt(result: build_mod.BuildResult) -> set[str]:
    return {Path(f).name for f in result.rebuilt}


def subprocess_env(cache_dir: Path, **extra: str) -> dict[str, str]:
    return {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "GRACE_CACHE_DIR": str(cache_dir),
        "PYTHONDONTWRITEBYTECODE": "1",
        **extra,
    }


# ---- 1. nothing executable or unpickled from the cache ------------------------------------------


class _Evil:
    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self) -> tuple[object, tuple[str]]:
        return (os.system, (f"touch {self.marker}",))


def test_a_pickle_in_the_grammar_cache_never_runs(tmp_path: Path) -> None:
    """Before: lark's cache file was unpickled on every run, `eacc check` included."""
    from lark import Lark

    from grace_dsl.lang import parser

    cache_root, marker = tmp_path / "cache", tmp_path / "PWNED"
    cache_root.mkdir()
    old = cache_root / "eac-grammar.lark-cache"
    Lark(
        parser.grammar(),
        parser="lalr",
        lexer="contextual",
        postlex=parser.DocPostLex(),
        transformer=parser._Builder("x"),
        maybe_placeholders=True,
        cache=str(old),
    )
    header = old.read_bytes().split(b"\n", 1)[0]  # lark's grammar hash: the pickle is trusted
    old.write_bytes(header + b"\n" + pickle.dumps(_Evil(marker)) + pickle.dumps(_Evil(marker)))
    (cache_root / "grammar").mkdir()
    for name in ("eac-grammar.lark-cache", "evil.json"):
        (cache_root / "grammar" / name).write_bytes(pickle.dumps(_Evil(marker)))
    code = "from grace_dsl.lang.parser import parse; print(len(parse('concept A {}').diagnostics))"
    for _ in range(2):  # the second run reads the tables the first one stored
        proc = subprocess.run(
            [sys.executable, "-c", code],
            env=subprocess_env(cache_root),
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.strip() == "0"
    assert not marker.exists()
    (stored,) = (cache_root / "grammar").glob("eac-*.json")
    assert json.loads(stored.read_text())["sha256"]  # JSON, not a pickle


def test_corrupted_grammar_tables_are_rebuilt(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from grace_dsl.lang import grammar_cache, parser

    monkeypatch.setenv("GRACE_CACHE_DIR", str(tmp_path))
    options = {"parser": "lalr", "lexer": "contextual", "maybe_placeholders": True}

    def runtime() -> dict[str, object]:
        return {"postlex": parser.DocPostLex(), "transformer": parser._Builder("x")}

    grammar_cache.cached_lark(parser.grammar(), runtime(), **options)
    (stored,) = (tmp_path / "grammar").glob("eac-*.json")
    good = stored.read_text()
    data = json.loads(good)
    data["tables"] = data["tables"].replace('"NAME"', '"NAMX"', 1)  # sha256 no longer matches
    for bad in (good[: len(good) // 2], json.dumps(data), "[]"):
        stored.write_text(bad)
        parts = runtime()
        lark = grammar_cache.cached_lark(parser.grammar(), parts, **options)
        builder = parts["transformer"]
        builder.path, builder.depth, builder.notes = "x", {}, []  # type: ignore[attr-defined]
        (concept,) = cast(Any, lark.parse("concept A {}"))
        assert concept.name == "A"
        rewritten = json.loads(stored.read_text())
        assert rewritten["sha256"] == hashlib.sha256(rewritten["tables"].encode()).hexdigest()


def test_stored_grammar_tables_parse_like_fresh_ones(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from grace_dsl.compiler.resolve import stdlib_dir
    from grace_dsl.lang import grammar_cache, parser

    monkeypatch.setenv("GRACE_CACHE_DIR", str(tmp_path))
    options = {"parser": "lalr", "lexer": "contextual", "maybe_placeholders": True}

    def parse_all() -> list[object]:
        builder = parser._Builder("x")
        lark = grammar_cache.cached_lark(
            parser.grammar(), {"postlex": parser.DocPostLex(), "transformer": builder}, **options
        )
        trees = []
        for path in sorted(stdlib_dir().glob("*.eac")):
            builder.path, builder.depth, builder.notes = str(path), {}, []
            trees.append(lark.parse(path.read_text()))
        return trees

    fresh = parse_all()
    (stored,) = (tmp_path / "grammar").glob("*.json")
    inode = stored.stat().st_ino
    assert parse_all() == fresh
    assert stored.stat().st_ino == inode  # read, not rebuilt and replaced


@needs_cc
@pytest.mark.parametrize("poison", ["constructor", "changed_constant", "garbage"])
def test_a_replaced_so_is_never_loaded(tmp_path: Path, poison: str) -> None:
    """Before: the .so was dlopened before its digest was checked (its constructor ran), and a
    .so rebuilt from the kept .c with another constant loaded and returned wrong poses."""
    cache_root, marker = tmp_path / "cache", tmp_path / "PWNED"
    # The reference comes from CasADi's VM: this process must not have mapped the unit's .so
    # (glibc would hand back the old mapping for the same path instead of opening the new one).
    expected = top_grasps(build([source(tmp_path)], tmp_path / "vm", use_native=False).units)
    first = build([source(tmp_path)], cache_root)
    unit = unit_of(first, "block.eac")
    (so,) = unit.glob("grace_*.so")
    if poison == "constructor":
        c = tmp_path / "evil.c"
        c.write_text(
            "#include <stdio.h>\n__attribute__((constructor)) static void evil(void) {\n"
            f'  FILE* f = fopen("{marker}", "w"); if (f) fclose(f);\n}}\n'
        )
        evil_so = tmp_path / "evil.so"
    elif poison == "changed_constant":
        text = (so.with_suffix(".c")).read_text()
        consts = re.findall(r"\((-?0x[0-9a-f.]+p[-+]\d+)\)", text)
        assert consts
        c = tmp_path / "changed.c"
        c.write_text(text.replace(f"({consts[0]})", "(0x1.8p+3)"))
        evil_so = tmp_path / "changed.so"
    if poison == "garbage":
        evil_so = tmp_path / "garbage.so"
        evil_so.write_bytes(b"\x7fELF garbage")
    else:
        cc = native.find_compiler()
        assert cc is not None
        subprocess.run([*cc, "-shared", "-fPIC", "-o", str(evil_so), str(c), "-lm"], check=True)
    os.replace(evil_so, so)

    # the runtime, holding units verified at build time, checks again before dlopen
    with pytest.raises(UnitError, match="does not match its digest"):
        top_grasps(first.units)
    # the next build finds the unit broken, rebuilds it, and its poses are right
    second = build([source(tmp_path)], cache_root)
    assert rebuilt(second) == {"block.eac"}
    np.testing.assert_allclose(top_grasps(second.units), expected, rtol=0, atol=1e-12)
    assert Library(second.units)["Block"].function("grasp", "top").backend == "native"
    assert not marker.exists()


@needs_cc
def test_standalone_native_cache_checks_the_so_bytes(tmp_path: Path) -> None:
    import casadi as ca

    x = ca.SX.sym("x")
    fn = ca.Function("twice", [x], [2 * x])
    (so,) = [native.build_native_library({"twice": fn}, tmp_path)]
    assert so is not None
    tampered = tmp_path / "tampered"
    tampered.write_bytes(so.read_bytes() + b"tampered")
    os.replace(tampered, so)
    ev = native.fast_function(fn, tmp_path)  # rebuilt, not loaded
    assert ev.backend == "native" and ev(3.0) == 6.0
    assert (tmp_path / f"{so.name}.sha256").read_text().strip() == native.file_sha256(so)


def test_standalone_native_cache_others_can_write_stays_on_the_vm(tmp_path: Path) -> None:
    import casadi as ca

    x = ca.SX.sym("x")
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    shared.chmod(0o777)
    ev = native.fast_function(ca.Function("thrice", [x], [3 * x]), shared)
    assert ev.backend == "casadi" and np.asarray(ev(2.0)).item() == 6.0
    assert list(shared.iterdir()) == []


# ---- 2. a corrupted or stale unit is rebuilt, never half-used -----------------------------------


def _truncate(path: Path) -> None:
    text = path.read_text()
    path.write_text(text[: len(text) // 2])


def _edit_unit(unit: Path, change: str) -> None:
    data = json.loads((unit / "unit.json").read_text())
    if change == "format":
        data["format"] = 999
    else:
        data["concepts"]["Block"]["params"][0]["hi"] = [5.0, 5.0, 5.0]
    (unit / "unit.json").write_text(json.dumps(data))


CORRUPTIONS = {
    "truncated unit.json": lambda u: _truncate(u / "unit.json"),
    "no unit.json": lambda u: (u / "unit.json").unlink(),
    "truncated functions.json": lambda u: _truncate(u / "functions.json"),
    "unit.json format 999": lambda u: _edit_unit(u, "format"),
    "range bound edited": lambda u: _edit_unit(u, "range"),
    "no digest": lambda u: (u / "digest.json").unlink(),
    "stray file": lambda u: (u / "extra.so").write_bytes(b"x"),
    "empty directory": lambda u: [p.unlink() for p in u.iterdir()],
}


@pytest.mark.parametrize("corruption", sorted(CORRUPTIONS))
def test_a_corrupted_unit_is_rebuilt(tmp_path: Path, corruption: str) -> None:
    """Before: JSONDecodeError on every run, `Directory not empty` on every build, an edited
    unit used silently, a truncated functions.json reported cached and failing later."""
    cache_root = tmp_path / "cache"
    first = build([source(tmp_path)], cache_root, use_native=False)
    expected = top_grasps(first.units)
    CORRUPTIONS[corruption](unit_of(first, "block.eac"))
    with pytest.raises(GraceError):  # the runtime refuses, one line, typed
        Library(first.units)["Block"].instantiate().grasps("top", 2)
    second = build([source(tmp_path)], cache_root, use_native=False)
    assert second.ok and not second.diagnostics
    assert rebuilt(second) == {"block.eac"}
    (block,) = [u for u in second.units if "Block" in u.concepts]
    assert block.concepts["Block"]["params"][0]["hi"] == [1.0, 1.0, 1.0]
    np.testing.assert_array_equal(top_grasps(second.units), expected)
    assert rebuilt(build([source(tmp_path)], cache_root, use_native=False)) == set()
    assert sorted(p.name for p in (cache_root / "tmp").iterdir()) == []


def test_a_broken_unit_error_is_one_line(tmp_path: Path) -> None:
    first = build([source(tmp_path)], tmp_path / "cache", use_native=False)
    _truncate(unit_of(first, "block.eac") / "functions.json")
    with pytest.raises(UnitError) as info:
        Library(first.units)["Block"].instantiate()
    assert "\n" not in str(info.value) and "functions.json" in str(info.value)


# ---- key and recorded metadata agree ------------------------------------------------------------


def test_the_same_source_at_two_paths_records_each_path(tmp_path: Path) -> None:
    """Before: the second place got the first place's path and an empty source_sha256."""
    cache_root = tmp_path / "cache"
    a = write(tmp_path / "one", "a.eac", BLOCK)
    b = write(tmp_path / "two", "b.eac", BLOCK)
    build([a], cache_root, use_native=False)
    for warm in (False, True):
        result = build([b], cache_root, use_native=False)
        assert rebuilt(result) == (set() if warm else {"b.eac"})
        (unit,) = [u for u in result.units if "Block" in u.concepts]
        assert unit.file == str(b.resolve())
        assert unit.concepts["Block"]["file"] == "b.eac"
        manifest = build_mod.library_manifest(result)
        sha = hashlib.sha256(BLOCK.encode()).hexdigest()
        assert manifest["units"][unit.key] == {"file": str(b.resolve()), "source_sha256": sha}


# ---- artifacts ----------------------------------------------------------------------------------


def _artifact(tmp_path: Path, native_code: bool = False) -> Path:
    result = build([source(tmp_path)], tmp_path / "cache", use_native=native_code)
    out = tmp_path / "art"
    assert export_library(result, out) == []
    return out


def _edit_manifest(out: Path, edit: Callable[[dict[str, Any]], object]) -> None:
    manifest = json.loads((out / "manifest.json").read_text())
    edit(manifest)
    (out / "manifest.json").write_text(json.dumps(manifest))


def test_artifact_unit_keys_cannot_leave_the_directory(tmp_path: Path) -> None:
    """Before: `../` in a manifest's unit keys loaded a unit from outside the artifact."""
    out = _artifact(tmp_path)
    key = next(iter(json.loads((out / "manifest.json").read_text())["units"]))
    outside = tmp_path / "outside" / key
    shutil.copytree(out / "units" / key, outside)

    def escape(m: dict[str, Any]) -> None:
        m["units"] = {f"../../outside/{key}": m["units"].pop(key), **m["units"]}

    _edit_manifest(out, escape)
    with pytest.raises(UnitError, match="not a unit key"):
        load_artifact(out)
    _edit_manifest(out, lambda m: m.update(units={key: {}}))
    shutil.rmtree(out / "units" / key)
    (out / "units" / key).symlink_to(outside)
    with pytest.raises(UnitError, match="outside the artifact"):
        load_artifact(out)


def test_artifact_schema_and_digests_are_checked(tmp_path: Path) -> None:
    out = _artifact(tmp_path)
    assert json.loads((out / "manifest.json").read_text())["format"] == UNIT_FORMAT
    assert len(load_artifact(out)) >= 2
    unit = next((out / "units").iterdir())
    _truncate(unit / "functions.json")
    with pytest.raises(UnitError, match="digest"):
        load_artifact(out)
    _edit_manifest(out, lambda m: m.update(format=999))
    with pytest.raises(UnitError, match="format 999"):
        load_artifact(out)
    (out / "manifest.json").write_text("{")
    with pytest.raises(UnitError, match="manifest.json"):
        load_artifact(out)


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to give files to another user")
def test_artifact_owned_by_someone_else_is_refused(tmp_path: Path) -> None:
    out = _artifact(tmp_path)
    unit = next((out / "units").iterdir())
    os.chown(unit / "functions.json", 12345, 12345)
    with pytest.raises(UnitError, match="writable by someone else"):
        load_artifact(out)


def test_group_writable_artifact_is_refused(tmp_path: Path) -> None:
    out = _artifact(tmp_path)
    (out / "units").chmod(0o777)
    with pytest.raises(UnitError, match="writable by others"):
        load_artifact(out)


# ---- the cache directory ------------------------------------------------------------------------


def test_one_cache_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("GRACE_CACHE_DIR", str(tmp_path))
    assert cache.cache_dir() == tmp_path
    assert build_mod.default_cache_dir() == tmp_path / "build"
    assert native.default_cache_dir() == tmp_path / "native"
    monkeypatch.delenv("GRACE_CACHE_DIR")
    assert build_mod.default_cache_dir().parent == cache.cache_dir()


def test_a_cache_others_can_write_is_not_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "private"))
    (tmp_path / "private").mkdir()
    cache_root = tmp_path / "cache"
    build([source(tmp_path)], cache_root, use_native=False)
    cache_root.chmod(0o777)
    result = build([source(tmp_path)], cache_root, use_native=False)
    assert [d.code for d in result.diagnostics] == ["E302"]
    assert "writable by others" in result.diagnostics[0].message
    assert rebuilt(result) == {"block.eac", "primitives.eac"}  # nothing read from it
    assert result.cache_dir == tmp_path / "private" / f"grace-dsl-{os.geteuid()}" / "build"
    assert all(u.dir.is_relative_to(result.cache_dir) for u in result.units)


def test_orphans_of_killed_builds_are_removed(tmp_path: Path) -> None:
    """Before: SIGKILL left directories in cache/tmp that no later build removed."""
    cache_root = tmp_path / "cache"
    tmp_root = cache_root / "tmp"
    tmp_root.mkdir(parents=True)
    code = (
        "import sys, time; from pathlib import Path; from grace_dsl.compiler.build import _claim\n"
        f"with _claim(Path({str(tmp_root)!r}), 'k' * 32) as d:\n"
        "    (d / 'functions.json').write_text('half'); print('claimed', flush=True)\n"
        "    time.sleep(300)\n"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], env=subprocess_env(cache_root), stdout=subprocess.PIPE
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"claimed"
    old = tmp_root / "crashed-before-lock"
    old.mkdir()
    os.utime(old, (0, 0))
    fresh = tmp_root / "just-created"
    fresh.mkdir()
    with build_mod._claim(tmp_root, "f" * 32) as live:  # a build running right now
        build_mod._clean_tmp(tmp_root)
        assert live.exists()  # held
        assert len([p for p in tmp_root.iterdir() if p.name.startswith("k")]) == 2
        proc.kill()
        proc.wait()
        build([source(tmp_path)], cache_root, use_native=False)
        assert live.exists()
        left = sorted(p.name for p in tmp_root.iterdir())
        assert left == sorted([fresh.name, live.name, f"{live.name}.lock"])
    assert sorted(p.name for p in tmp_root.iterdir()) == [fresh.name]


@pytest.mark.slow
@needs_cc
def test_ctrl_c_stops_a_build_promptly(tmp_path: Path) -> None:
    """Before: SIGINT finished every unit, then exited 130."""
    import signal
    import time

    from grace_dsl.compiler.resolve import stdlib_dir

    cache_root = tmp_path / "cache"
    proc = subprocess.Popen(
        [sys.executable, "-m", "grace_dsl.cli.eacc", "build", str(stdlib_dir())],
        env=subprocess_env(cache_root),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        # a pytest-xdist worker ignores SIGINT, and an ignored signal stays ignored in a child:
        # give the build the default disposition, as in a terminal
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    tmp_root = cache_root / "build" / "tmp"
    deadline = time.monotonic() + 120
    while not list(tmp_root.glob("*.lock")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(3)  # into lowering and compiling (a compiler is running by now)
    proc.send_signal(signal.SIGINT)
    # no bound on seconds (a loaded machine stretches them): the build stops with units left
    # unbuilt, where before it finished every unit and then exited
    assert proc.wait(timeout=120) == 130
    built = list((cache_root / "build" / "units").iterdir())
    assert len(built) < len(list(stdlib_dir().glob("*.eac")))
    assert list(tmp_root.iterdir()) == []  # the interrupted units cleaned up after themselves


READ_ONLY_BUILD = """
import json, sys
from pathlib import Path
from grace_dsl.compiler.build import build
from grace_dsl.runtime.library import Library
r = build([Path(sys.argv[1])], Path(sys.argv[2]), use_native=False)
inst = Library(r.units)["Block"].instantiate(size=(0.1, 0.2, 0.3))
print(json.dumps({
    "rebuilt": sorted(Path(f).name for f in r.rebuilt),
    "codes": [d.code for d in r.diagnostics],
    "dirs": sorted(str(u.dir.parent.parent) for u in r.units),
    "grasp": inst.grasp("top", t=0.01).tolist(),
}))
"""


def _without_dac_override() -> None:
    """Root writes through file modes; without CAP_DAC_OVERRIDE it obeys them like anyone."""
    import ctypes

    if os.geteuid() == 0:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(24, 1, 0, 0, 0) != 0:  # PR_CAPBSET_DROP, CAP_DAC_OVERRIDE
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP)")


def test_a_read_only_cache_is_read(tmp_path: Path) -> None:
    """Before: a read-only populated cache was never read, and every run built everything in a
    new /tmp/grace-dsl-cache-* directory that stayed behind."""
    import tempfile

    shared = Path(tempfile.mkdtemp(prefix="grace-ro-"))  # others may traverse it
    try:
        shared.chmod(0o755)
        src, cache_root = source(shared), shared / "cache"
        first = build([src], cache_root, use_native=False)
        expected = Library(first.units)["Block"].instantiate(size=(0.1, 0.2, 0.3))
        scratch = shared / "scratch"  # the reader's TMPDIR: sticky, like /tmp
        scratch.mkdir()
        scratch.chmod(0o1777)
        for p in [shared / "src", *shared.glob("src/*")]:
            p.chmod(0o755 if p.is_dir() else 0o644)
        for p in [cache_root, *cache_root.rglob("*")]:
            p.chmod(p.stat().st_mode & ~0o222)
        fallback = scratch / f"grace-dsl-{os.geteuid()}" / "build"

        def run() -> dict[str, Any]:
            proc = subprocess.run(
                [sys.executable, "-c", READ_ONLY_BUILD, str(src), str(cache_root)],
                env=subprocess_env(cache_root, TMPDIR=str(scratch), HOME=str(scratch)),
                capture_output=True,
                text=True,
                timeout=300,
                preexec_fn=_without_dac_override,
            )
            assert proc.returncode == 0, proc.stderr
            return json.loads(proc.stdout)

        warm = run()
        assert warm["rebuilt"] == [] and warm["codes"] == []
        assert warm["dirs"] == [str(cache_root)] * 2
        np.testing.assert_array_equal(warm["grasp"], expected.grasp("top", t=0.01))
        assert sorted(p.name for p in scratch.iterdir()) == []  # nothing left behind

        src.write_text(BLOCK.replace("A plain block.", "A plain block, edited."))
        changed = run()
        assert changed["rebuilt"] == ["block.eac"] and changed["codes"] == ["E301"]
        assert changed["dirs"] == sorted([str(cache_root), str(fallback)])
        again = run()  # the private fallback is reused, not rebuilt
        assert again["rebuilt"] == [] and again["codes"] == []
        assert sorted(p.name for p in scratch.iterdir()) == [fallback.parent.name]
    finally:
        for p in [shared, *shared.rglob("*")]:
            if p.is_dir() and not p.is_symlink():
                p.chmod(0o755)
        shutil.rmtree(shared, ignore_errors=True)
