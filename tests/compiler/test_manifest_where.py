"""The manifest records where each formula comes from (``file.eac:line``), so the runtime and
``eacc verify`` can point a non-finite grasp, force, joint limit or shape back at its source."""

from __future__ import annotations

from pathlib import Path

from grace_dsl.compiler.build import build
from tests.conftest import write

SOURCE = """\
use primitives.{Cuboid}
use handle.{Knob}
concept Box {
    param w : length in [10mm, 100mm] = 50mm
    link lid {
        shape body = Cuboid(size: (w, w, w))
        grasp top(t in [-w / 2, w / 2] = 0) =
            trans(t, 0, w / 2)
            width w
        part knob = Knob()
    }
    joint hinge : revolute(base -> lid) axis (1, 0, 0)
        range [0, 90deg]
    action open = lift along hinge
    action poke = press toward (0, 0, -1)
}
"""
HANDLE = """\
use primitives.{Sphere}
concept Knob {
    param r : length in [5mm, 20mm] = 10mm
    shape ball = Sphere(radius: r)
    grasp pinch = trans(0, 0, r) width 2 * r
}
"""


def test_every_formula_has_its_source_line(tmp_path: Path) -> None:
    write(tmp_path, "handle.eac", HANDLE)
    path = write(tmp_path, "box.eac", SOURCE)
    result = build([path], tmp_path / "cache", use_native=False)
    assert result.ok, result.diagnostics
    entry = next(u for u in result.units if u.file == str(path.resolve())).concepts["Box"]
    grasps = {g["name"]: g for g in entry["grasps"]}
    assert grasps["top"]["where"] == "box.eac:8"
    assert grasps["top"]["width_where"] == "box.eac:9"
    assert grasps["knob.pinch"]["where"] == "handle.eac:5"  # a part's grasp: the part's file
    joint = next(j for j in entry["joints"] if j["name"] == "hinge")
    assert (joint["where"], joint["range_where"]) == ("box.eac:12", "box.eac:13")
    actions = {a["name"]: a["where"] for a in entry["actions"]}
    assert actions == {"open": "box.eac:14", "poke": "box.eac:15"}
    shapes = {s["name"]: s["where"] for s in entry["shapes"]}
    assert shapes == {"body": "box.eac:6", "knob.ball": "handle.eac:4"}
