"""The build memo skips parsing and checking only when nothing the front end read has changed."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from grace_dsl.compiler import build as build_module
from grace_dsl.compiler.build import BuildResult, build
from tests.compiler.test_build import BASE, library_dir
from tests.conftest import write


@pytest.fixture
def front_ends(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the front-end runs of the builds in a test."""
    calls: list[int] = []
    real = build_module.front_end

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(build_module, "front_end", counting)
    return calls


def memo_build(src: Path, cache: Path, search: list[Path] | None = None) -> BuildResult:
    return build([src], cache, search or [], use_native=False, reuse_front_end=True)


def summary(result: BuildResult) -> list[tuple[str, str, list[str]]]:
    return [(Path(u.file).name, u.key, sorted(u.concepts)) for u in result.units]


def test_an_unchanged_request_loads_the_same_units_without_the_front_end(
    tmp_path: Path, front_ends: list[int]
) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    first = memo_build(src, cache)
    again = memo_build(src, cache)
    assert first.ok and again.ok and len(front_ends) == 1
    assert summary(again) == summary(first)
    assert again.sources == first.sources and again.rebuilt == []
    assert (cache / "memo").is_dir()


def test_an_edited_file_runs_the_front_end_and_rebuilds_its_unit(
    tmp_path: Path, front_ends: list[int]
) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    memo_build(src, cache)
    write(src, "base.eac", BASE.replace("A plain block.", "A block."))
    edited = memo_build(src, cache)
    assert len(front_ends) == 2
    assert {Path(f).name for f in edited.rebuilt} == {"base.eac", "user.eac"}
    assert "A block." in edited.sources[str((src / "base.eac").resolve())]
    memo_build(src, cache)
    assert len(front_ends) == 2  # the new memo holds


def test_a_new_file_in_the_request_is_seen(tmp_path: Path, front_ends: list[int]) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    memo_build(src, cache)
    write(
        src, "more.eac", "use primitives.{Sphere}\nconcept More { shape s = Sphere(radius: 1mm) }"
    )
    assert "More" in {c for u in memo_build(src, cache).units for c in u.concepts}
    assert len(front_ends) == 2


def test_a_module_that_now_shadows_an_import_is_seen(tmp_path: Path, front_ends: list[int]) -> None:
    """`use primitives` found the standard library's file; a primitives.eac added earlier on
    the search path is what the front end would read now, so the memo must not answer."""
    src, cache, search = library_dir(tmp_path), tmp_path / "cache", tmp_path / "search"
    search.mkdir()
    memo_build(src, cache, [search])
    write(search, "primitives.eac", "concept Nothing { }")
    result = memo_build(src, cache, [search])
    assert len(front_ends) == 2 and not result.ok  # the shadowing file lacks Cuboid


@pytest.mark.parametrize(
    "damage",
    [
        lambda memo: memo.write_text("{not json"),
        lambda memo: memo.write_text(json.dumps({**json.loads(memo.read_text()), "format": 99})),
        lambda memo: memo.write_text(
            json.dumps({**json.loads(memo.read_text()), "units": {"/etc/passwd": "0" * 32}})
        ),
        lambda memo: memo.write_text(json.dumps(_swap_units(json.loads(memo.read_text())))),
    ],
    ids=["garbage", "format", "foreign-file", "swapped-units"],
)
def test_a_damaged_memo_costs_a_front_end_run_never_a_wrong_library(
    tmp_path: Path, front_ends: list[int], damage: Any
) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    first = memo_build(src, cache)
    (memo,) = (cache / "memo").glob("*.json")
    damage(memo)
    again = memo_build(src, cache)
    assert len(front_ends) == 2 and summary(again) == summary(first)


def _swap_units(data: dict[str, Any]) -> dict[str, Any]:
    """Each file pointed at another file's unit: the units say which file they were built from."""
    files = list(data["units"])
    keys = [data["units"][f] for f in files]
    return {**data, "units": dict(zip(files, keys[1:] + keys[:1], strict=True))}


def test_a_cache_others_can_write_is_not_recalled(tmp_path: Path, front_ends: list[int]) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    memo_build(src, cache)
    cache.chmod(0o777)
    try:
        result = memo_build(src, cache)
    finally:
        cache.chmod(0o700)
    assert len(front_ends) == 2 and result.ok
    assert any(d.code == "E302" for d in result.diagnostics)


def test_builds_that_show_diagnostics_do_not_use_the_memo(
    tmp_path: Path, front_ends: list[int]
) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    memo_build(src, cache)
    build([src], cache, use_native=False)
    assert len(front_ends) == 2
