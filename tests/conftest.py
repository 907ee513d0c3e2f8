"""Shared fixtures: the checked standard library and a private build cache per session."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from grace_dsl.compiler.build import front_end
from grace_dsl.compiler.resolve import stdlib_dir

os.environ.setdefault("MUJOCO_GL", "osmesa")  # headless MuJoCo rendering (tests/render)


@pytest.fixture(scope="session")
def stdlib_front_end():  # type: ignore[no-untyped-def]
    prog, checked, diags = front_end([stdlib_dir()])
    assert not diags, diags
    return prog, checked


@pytest.fixture(scope="session", autouse=True)
def private_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Builds in tests never touch the user's cache."""
    import os

    cache = tmp_path_factory.mktemp("grace-cache")
    os.environ["GRACE_CACHE_DIR"] = str(cache)
    return cache


def write(dir_: Path, name: str, text: str) -> Path:
    path = dir_ / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path
