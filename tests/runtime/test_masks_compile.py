"""The compiler's side of masking: a read of a copy that may be absent is E128 unless the
reader lives in the same loop or guards the read with the count; dotted part arguments
(``handle.length``) are checked against the requirements they bind (E210)."""

from __future__ import annotations

from pathlib import Path

import pytest

from grace_dsl.compiler.build import front_end
from tests.conftest import write

HEAD = """use primitives.{Cuboid}
concept T {
    param n : int in [1, 4] = 2
    param kind : choice{"a", "b"} = "a"
    param h : length in [100mm, 200mm] = 150mm
    for i in 0..n { let w[i] = i * h }
"""


def diagnostics(tmp_path: Path, body: str, head: str = HEAD) -> list[tuple[str, str]]:
    path = write(tmp_path, "t.eac", head + body + "\n}\n")
    _, _, diags = front_end([path])
    return [(d.code, d.message) for d in diags]


@pytest.mark.parametrize(
    "body",
    [
        "let total = w[0] + w[2]",
        "let total = if n > 1 then w[2] else 0mm",  # guards a lower count than it reads
        'require n <= 2 or w[3] > 0mm "x"',  # n > 2 does not give n > 3
        "shape s = Cuboid(size: (w[3] + 1mm, 1mm, 1mm))",
        "for i in 0..n { let v[i] = w[i + 1] }",  # a later copy
    ],
)
def test_reading_a_possibly_absent_copy_is_e128(tmp_path: Path, body: str) -> None:
    found = diagnostics(tmp_path, body)
    assert [c for c, _ in found if c != "E122"] == ["E128"], found
    assert "which exists only when n > " in dict(found)["E128"]


@pytest.mark.parametrize(
    "body",
    [
        "let total = w[0] + (if n > 2 then w[2] else 0mm)",
        "let total = if n <= 2 then 0mm else w[2]",
        "let total = if 3 < n then w[3] else 0mm",
        "let total = if n >= 4 and h > 0mm then w[3] else 0mm",
        'require n <= 3 or w[3] > 0mm "the fourth is raised"',
        "for i in 1..n { let v[i] = w[i - 1] }",  # an earlier copy exists when this one does
        "for i in 0..n { let v[i] = w[i] + 1mm }",
        'for i in 0..n { require (i + 1) * h <= 450mm "fits" }',  # copy 3 fails at the defaults
    ],
)
def test_guarded_or_same_loop_reads_are_accepted(tmp_path: Path, body: str) -> None:
    assert diagnostics(tmp_path, body) == []


HOST = "use furniture.{Drawer, BoardCabinet}\nconcept T {\n"


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("part d = Drawer(handle.length: 590mm)", "Drawer fails its requirement (the handle fits"),
        (
            "part d = Drawer(handle.standoff: 22mm)",
            # the option whose requirement fails, by the name an argument binds it with
            "Drawer's part `handle@bar` (StraightHandle) fails its requirement (a finger fits",
        ),
        (
            "part c = BoardCabinet(door.handle.standoff: 22mm)",
            "BoardCabinet's part `door.handle@bar` (StraightHandle) fails",
        ),
    ],
)
def test_dotted_arguments_are_checked_against_requirements(
    tmp_path: Path, body: str, expected: str
) -> None:
    found = diagnostics(tmp_path, body, HOST)
    assert [c for c, _ in found] == ["E210"]
    assert expected in found[0][1]


def test_dotted_arguments_that_fit_pass(tmp_path: Path) -> None:
    assert diagnostics(tmp_path, "part d = Drawer(handle.length: 200mm)", HOST) == []
    assert diagnostics(tmp_path, "part c = BoardCabinet(door.handle.length: 300mm)", HOST) == []


@pytest.mark.slow
def test_dotted_arguments_reach_a_variant_part_two_levels_down(tmp_path: Path) -> None:
    """``c.door.handle.length`` passes through two parts without variants of their own (T places
    BoardCabinet, which places DoorLeaf, whose handle is the variant): the pass still binds it."""
    head = HOST + "part c = BoardCabinet(door.handle.length: 300mm)\n}\nconcept U {\n"
    assert diagnostics(tmp_path, "part t = T(c.door.handle.radius: 12mm)", head) == []
    found = diagnostics(tmp_path, "part t = T(c.door.handle.nope: 250mm)", head)
    assert [c for c, _ in found] == ["E116"], found
    assert "variant part `c.door.handle`" in found[0][1]
    found = diagnostics(tmp_path, "part t = T(c.door.handle.length: 250mm)", head)
    assert [c for c, _ in found] == ["E116"], found  # T binds it already
    assert "is already given by T" in found[0][1]
