"""Parameters of nested parts (``left.handle.length``, as ``explain`` lists them) can be read in
a host's expressions and bound in its part arguments (``Door(handle.length: 120mm)``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from grace_dsl.compiler.build import front_end
from grace_dsl.runtime.errors import RequirementError
from grace_dsl.runtime.library import compile_paths
from tests.conftest import write

PARTS = """\
concept Handle {
    param length : length in [50mm, 300mm] = 100mm
    grasp g = trans(0mm, 0mm, length) width 10mm
}
concept Door {
    param width : length in [200mm, 1m] = 500mm
    part handle = Handle()
}
concept FixedDoor {
    param width : length in [200mm, 1m] = 500mm
    part handle = Handle(length: width / 4)
}
"""


def test_nested_parameters_read_and_bound(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "c.eac",
        PARTS
        + """\
concept Reads {
    part left = Door()
    let reach = left.handle.length + 10mm
    require left.handle.length < left.width / 2 "the handle fits"
    grasp far = trans(0mm, reach, 0mm) width 10mm
}
concept Binds {
    param h : length in [60mm, 200mm] = 120mm
    part left = Door(handle.length: h)
    part right = FixedDoor()
    let r = right.handle.length
    grasp rg = trans(0mm, r, 0mm) width 10mm
}
""",
    )
    lib = compile_paths([path])
    reads = lib["Reads"]
    assert [p["name"] for p in reads.entry["params"]] == ["left.width", "left.handle.length"]
    require = next(r for r in reads.entry["requires"] if "fits" in r["message"])
    assert set(require["params"]) == {"left.handle.length", "left.width"}
    inst = reads.instantiate(**{"left.handle.length": 0.2})
    assert np.isclose(inst.grasp("far")[1, 3], 0.21)
    assert np.isclose(inst.grasp("left.handle.g")[2, 3], 0.2)
    with pytest.raises(RequirementError):
        reads.instantiate(**{"left.handle.length": 0.3, "left.width": 0.4})
    binds = lib["Binds"]
    names = [p["name"] for p in binds.entry["params"]]
    assert names == ["h", "left.width", "right.width"]  # left.handle.length is bound
    inst = binds.instantiate(h=0.15, **{"right.width": 0.8})
    assert np.isclose(inst.grasp("left.handle.g")[2, 3], 0.15)
    assert np.isclose(inst.grasp("rg")[1, 3], 0.2)  # read through FixedDoor's own binding


@pytest.mark.parametrize(
    ("body", "code", "words"),
    [
        ("part left = Door()\nlet x = left.handle.lenght", "E212", "did you mean `length`"),
        ("part left = Door()\nlet x = left.handle", "E212", "is a part"),
        ("part left = Door(knob.length: 1mm)", "E116", "no part `knob`"),
        ("part left = Door(handle.size: 1mm)", "E116", "no parameter `size`"),
        ("part left = FixedDoor(handle.length: 90mm)", "E116", "already given by FixedDoor"),
        ("part left = Door(handle.length: 5)", "E204", "bare number"),
        ("part left = Door(handle.length: 20mm)", "E209", "Handle.length is in [50mm, 300mm]"),
    ],
)
def test_nested_parameter_errors(tmp_path: Path, body: str, code: str, words: str) -> None:
    path = write(tmp_path, "c.eac", PARTS + "concept T {\n" + body + "\n}\n")
    diags = front_end([path])[2]
    assert [d.code for d in diags] == [code]
    assert words in diags[0].message + (diags[0].hint or "")


def test_the_interval_pass_ranges_over_nested_parameters(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "c.eac",
        PARTS + "concept T {\n    part left = Door()\n"
        "    let k = 1mm * 1mm / (left.handle.length - 120mm)\n}\n",
    )
    diags = front_end([path])[2]
    assert [(d.code, d.severity) for d in diags] == [("E233", "warning")]
    assert "crosses 0" in (diags[0].hint or "") and "left.handle.length = " in (diags[0].hint or "")


def test_arguments_read_nested_parameters_of_sibling_parts(tmp_path: Path) -> None:
    """``Door(handle.length: a.handle.length)``: a part's argument reads a parameter of a part
    of another part, declared before or after it, lifted or bound there."""
    path = write(
        tmp_path,
        "c.eac",
        PARTS
        + """\
concept Row {
    part a = Door()
    part b = Door(handle.length: a.handle.length)
    part c = Door(handle.length: d.handle.length + 10mm, width: a.handle.length * 4)
    part d = FixedDoor()
    grasp cw = trans(0mm, c.width, 0mm) width 10mm
}
""",
    )
    row = compile_paths([path])["Row"]
    names = [p["name"] for p in row.entry["params"]]
    # the layout is that of the parts' declarations, whatever the arguments read
    assert names == ["a.width", "b.width", "d.width", "a.handle.length"]
    inst = row.instantiate(**{"a.handle.length": 0.12, "d.width": 0.6})
    assert np.isclose(inst.grasp("a.handle.g")[2, 3], 0.12)
    assert np.isclose(inst.grasp("b.handle.g")[2, 3], 0.12)
    assert np.isclose(inst.grasp("c.handle.g")[2, 3], 0.6 / 4 + 0.01)  # FixedDoor binds width/4
    assert np.isclose(inst.grasp("cw")[1, 3], 0.48)


def test_sibling_arguments_reading_each_other_are_a_cycle(tmp_path: Path) -> None:
    body = (
        "part a = Door(handle.length: b.handle.length)\n"
        "part b = Door(handle.length: a.handle.length)"
    )
    path = write(tmp_path, "c.eac", PARTS + "concept T {\n" + body + "\n}\n")
    diags = front_end([path])[2]
    assert [d.code for d in diags] == ["E119"]
    assert "a.handle.length -> b.handle.length -> a.handle.length" in diags[0].message
