"""An instance whose parameters, inside their ranges, give a shape arguments no solid has: its
geometry raises ``ShapeError`` (a ``GraceError``) naming the concept, the shape, its file:line
and the values, where a bare ``GeometryError`` escaped before."""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import grace_dsl as eac
from grace_dsl.geometry import GeometryError
from grace_dsl.runtime.errors import GraceError, ParameterError
from grace_dsl.runtime.shapes import ShapeError
from tests.conftest import write
from tests.runtime.test_verify_invalid import FRAME

QUERIES: dict[str, Callable[[eac.Instance], Any]] = {
    "mesh": lambda inst: inst.mesh(),
    "link_mesh": lambda inst: inst.link_mesh(inst.concept.links[0]),
    "sdf": lambda inst: inst.sdf(np.zeros((4, 3))),
    "sample_surface": lambda inst: inst.sample_surface(10, seed=0),
}


@pytest.fixture(scope="module")
def frame(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    return eac.compile_paths([write(tmp_path_factory.mktemp("frame"), "frame.eac", FRAME)])["Frame"]


@pytest.mark.parametrize("query", sorted(QUERIES))
def test_invalid_shape_raises_a_typed_error(frame: eac.Concept, query: str) -> None:
    inst = frame.instantiate(size=0.2, border=0.1)  # inner = 200 - 2 * 100 = 0 mm
    with pytest.raises(ShapeError) as info:
        QUERIES[query](inst)
    err = info.value
    assert isinstance(err, GraceError) and isinstance(err, ParameterError)
    assert not isinstance(err, GeometryError)
    assert (err.concept, err.shape, err.primitive, err.where) == (
        "Frame",
        "ring",
        "RectRing",
        "frame.eac:8",
    )
    assert "RectRing.inner must be > 0" in err.problem
    assert err.values == "size = 200mm, border = 100mm"
    assert str(err).startswith("Frame: shape ring (RectRing, frame.eac:8) cannot be built")


def test_valid_values_of_the_same_concept_still_work(frame: eac.Concept) -> None:
    inst = frame.instantiate(size=0.2, border=0.03)
    mesh = inst.mesh()
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx((0.2**2 - 0.14**2) * 0.02, rel=1e-9)
    assert inst.sdf(np.zeros((1, 3)))[0] == pytest.approx(0.07, abs=1e-12)  # in the opening


def test_the_manifest_gives_each_shape_and_grasp_its_line(
    frame: eac.Concept, lib: eac.Library
) -> None:
    assert [s["where"] for s in frame.entry["shapes"]] == ["frame.eac:8"]
    assert frame.grasps["top"]["where"] == "frame.eac:11"
    for name in lib:
        for s in lib[name].entry["shapes"]:
            assert re.fullmatch(r"\w+\.eac:\d+", s["where"]), (name, s)
