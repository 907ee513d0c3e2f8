"""Builds are cached by content, incremental, atomic and safe when two run at once."""

from __future__ import annotations

import json
import multiprocessing as mp
from pathlib import Path

import numpy as np
import pytest

from grace_dsl.compiler.build import build, export_library
from grace_dsl.runtime.library import Library, load_artifact
from tests.conftest import write

BASE = """
use primitives.{Cuboid}
/// A plain block.
concept Block {
    param size : vec3 length in [(1mm, 1mm, 1mm), (1m, 1m, 1m)] = (10mm, 20mm, 30mm)
    shape body = Cuboid(size: size)
    grasp top(t in [-size.x / 2, size.x / 2] = 0) = trans(t, 0, size.z / 2) width size.y
}
"""
USER = """
use base.{Block}
/// A block on a slide.
concept Slider {
    param travel : length in [1mm, 500mm] = 100mm
    link carriage { part block = Block() }
    joint slide : prismatic(base -> carriage) axis (1, 0, 0) range [0, travel]
    action push_out = push along slide opening using block.top
}
"""
OTHER = """
use primitives.{Sphere}
/// A ball.
concept Ball { param r : length in [1mm, 1m] = 5mm  shape s = Sphere(radius: r) }
"""


def library_dir(tmp: Path) -> Path:
    src = tmp / "src"
    write(src, "base.eac", BASE)
    write(src, "user.eac", USER)
    write(src, "other.eac", OTHER)
    return src


def rebuilt_names(result) -> set[str]:  # type: ignore[no-untyped-def]
    return {Path(f).name for f in result.rebuilt}


def test_incremental_rebuilds_only_dependents(tmp_path: Path) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    first = build([src], cache, use_native=False)
    assert first.ok and rebuilt_names(first) == {
        "base.eac",
        "user.eac",
        "other.eac",
        "primitives.eac",
    }
    assert rebuilt_names(build([src], cache, use_native=False)) == set()
    write(src, "user.eac", USER.replace("500mm", "600mm"))
    assert rebuilt_names(build([src], cache, use_native=False)) == {"user.eac"}
    write(src, "base.eac", BASE.replace("A plain block.", "A plain block, edited."))
    assert rebuilt_names(build([src], cache, use_native=False)) == {"base.eac", "user.eac"}


def test_errors_build_nothing(tmp_path: Path) -> None:
    src = library_dir(tmp_path)
    write(src, "other.eac", OTHER.replace("5mm", "5"))
    result = build([src], tmp_path / "cache", use_native=False)
    assert not result.ok and result.units == []
    assert [d.code for d in result.diagnostics] == ["E204"]


def _build_in_process(args: tuple[str, str]) -> list[str]:
    src, cache = args
    result = build([src], Path(cache))
    assert result.ok
    return sorted(u.key for u in result.units)


@pytest.mark.slow
def test_two_processes_building_the_same_cache(tmp_path: Path) -> None:
    src, cache = library_dir(tmp_path), tmp_path / "cache"
    ctx = mp.get_context("spawn")
    with ctx.Pool(2) as pool:
        keys = pool.map(_build_in_process, [(str(src), str(cache))] * 4)
    assert all(k == keys[0] for k in keys)
    units = sorted(p.name for p in (cache / "units").iterdir())
    assert units == keys[0]
    assert list((cache / "tmp").iterdir()) == []  # no leftovers from the losers
    for unit in (cache / "units").iterdir():
        json.loads((unit / "unit.json").read_text())  # every unit complete and readable
    lib = Library(build([src], cache).units)
    slider = lib["Slider"].instantiate(joints={"slide": 0.05})
    np.testing.assert_allclose(slider.link_pose("carriage")[:3, 3], [0.05, 0, 0])


def test_artifact_round_trip(tmp_path: Path) -> None:
    src = library_dir(tmp_path)
    result = build([src], tmp_path / "cache")
    assert export_library(result, tmp_path / "out") == []
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert set(manifest["concepts"]) >= {"Block", "Slider", "Ball", "Cuboid"}
    slider = manifest["concepts"]["Slider"]
    assert [p["name"] for p in slider["params"]] == ["travel", "block.size"]
    assert slider["params"][1]["lo"] == [0.001, 0.001, 0.001]
    assert slider["grasps"][0]["name"] == "block.top"
    action = dict(slider["actions"][0])
    assert action.pop("formula")["text"] == "[1, 0, 0]"  # the slide's axis, opening
    assert action == {
        "name": "push_out",
        "verb": "push",
        "joint": "slide",
        "sense": "opening",
        "direction": False,
        "using": ["block.top"],
        "doc": "",
        "where": "user.eac:8",
    }
    loaded = load_artifact(tmp_path / "out")
    fresh = Library(result.units)
    for name in ("Block", "Slider"):
        a = loaded[name].instantiate(
            **{"block.size" if name == "Slider" else "size": (0.1, 0.2, 0.3)}
        )
        b = fresh[name].instantiate(
            **{"block.size" if name == "Slider" else "size": (0.1, 0.2, 0.3)}
        )
        grasp = next(iter(loaded[name].grasps))
        np.testing.assert_array_equal(a.grasps(grasp, 5), b.grasps(grasp, 5))


def test_unwritable_output_is_a_diagnostic(tmp_path: Path) -> None:
    src = library_dir(tmp_path)
    result = build([src], tmp_path / "cache", use_native=False)
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    (d,) = export_library(result, blocker / "out")
    assert d.code == "E301"
