"""Shared fixtures: the checked and the compiled standard library, and one private build cache
per test run (shared by the workers of a ``pytest -n`` run, so the library is compiled once)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from filelock import FileLock

import grace_dsl as eac
from grace_dsl.cache import private_dir
from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.resolve import stdlib_dir

os.environ.setdefault("MUJOCO_GL", "osmesa")  # headless MuJoCo rendering (tests/render)


#: The standard library each session loaded, by cache (loaded once: the front end takes seconds).
_loaded: dict[Path, eac.Library] = {}


@pytest.fixture(scope="session")
def stdlib_front_end():  # type: ignore[no-untyped-def]
    prog, checked, diags = front_end([stdlib_dir()])
    assert not diags, diags
    return prog, checked


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--reuse-build-cache",
        action="store_true",
        help="build into a private per-user test cache kept between runs (make test-fast) "
        "instead of a fresh one per run (make test, CI): the standard library is then compiled "
        "once per compiler change, not once per run",
    )


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory, pytestconfig: pytest.Config) -> Path:
    """Builds in tests never touch the user's cache, and the workers of one run share theirs.

    Under pytest-xdist each worker is its own session with its own temporary directory below the
    run's; the cache lives next to them, and the first worker to take the lock compiles the
    standard library (about 50 s of CPU) while the others wait and then load what it built (the
    build writes units atomically and verifies what it loads, so sharing is safe without the
    lock; the lock only avoids compiling the library once per worker). A unit's key hashes the
    compiler's source and the file's path and text, so a reused cache never serves stale code.
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if pytestconfig.getoption("--reuse-build-cache"):
        cache = private_dir("pytest-build")
    elif worker:
        cache = tmp_path_factory.getbasetemp().parent / "grace-cache"
        cache.mkdir(mode=0o700, exist_ok=True)
    else:
        cache = tmp_path_factory.mktemp("grace-cache")
    os.environ["GRACE_CACHE_DIR"] = str(cache)
    if worker:
        with _build_lock(cache):  # nearly every test file needs it: compile it once, up front
            _loaded[cache] = eac.load_library(cache / "build")
    return cache


@pytest.fixture(scope="session")
def stdlib(private_cache: Path) -> eac.Library:
    """The compiled standard library, loaded once per session (each load_library() call re-runs
    the front end over all of the library's files, seconds each): use this, not a call per
    module or per test."""
    if private_cache not in _loaded:
        with _build_lock(private_cache):  # the cache named here, whatever a test did to the env
            _loaded[private_cache] = eac.load_library(private_cache / "build")
    return _loaded[private_cache]


@pytest.fixture(scope="session")
def lib(stdlib: eac.Library) -> eac.Library:
    """The standard library under the name most test files use."""
    return stdlib


def _build_lock(cache: Path) -> FileLock:
    return FileLock(str(cache) + ".lock")


def write(dir_: Path, name: str, text: str) -> Path:
    path = dir_ / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


#: A test that takes longer than this is marked slow (pyproject.toml's markers, make test-fast).
SLOW_S = 3.0


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:  # type: ignore[no-untyped-def]
    """Name the tests over SLOW_S that are not marked slow, so the markers stay honest as tests
    are added (times on a busy machine are inflated: judge them with the machine's load)."""
    unmarked = sorted(
        (r.duration, r.nodeid)
        for r in terminalreporter.stats.get("passed", [])
        if r.when == "call" and r.duration > SLOW_S and "slow" not in r.keywords
    )
    if unmarked:
        terminalreporter.write_sep("-", f"{len(unmarked)} tests over {SLOW_S:g} s not marked slow")
        for duration, nodeid in unmarked[::-1][:15]:
            terminalreporter.write_line(f"{duration:6.1f}s {nodeid}")
