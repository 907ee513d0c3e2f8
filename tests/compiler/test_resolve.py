"""The resolve pass: modules, the search path, visibility, cycles and duplicates."""

from __future__ import annotations

from pathlib import Path

from grace_dsl.compiler.resolve import resolve
from tests.conftest import write

LEAF = (
    "use primitives.{Sphere}\n"
    "concept Leaf { param r : length = 1mm  shape s = Sphere(radius: r) }\n"
)


def codes(diags: list) -> list[str]:  # type: ignore[type-arg]
    return [d.code for d in diags]


def test_imports_resolve_next_to_the_file_then_the_search_path(tmp_path: Path) -> None:
    write(tmp_path / "lib" / "parts", "leaf.eac", LEAF)
    main = write(
        tmp_path / "app", "main.eac", "use parts.leaf.{Leaf}\nconcept Tree { part a = Leaf() }\n"
    )
    prog, diags = resolve([main])
    assert codes(diags) == ["E101"]
    prog, diags = resolve([main], search_path=[tmp_path / "lib"])
    assert diags == []
    assert set(prog.visible[str(main.resolve())]) == {"Tree", "Leaf"}
    assert "Sphere" not in prog.visible[str(main.resolve())]  # only what `use` names


def test_use_all_imports_every_concept(tmp_path: Path) -> None:
    write(tmp_path, "leaf.eac", LEAF + "concept Twig { param n : int = 1 }\n")
    main = write(tmp_path, "main.eac", "use leaf\nconcept Tree { part a = Twig() }\n")
    prog, diags = resolve([main])
    assert diags == [] and {"Leaf", "Twig"} <= set(prog.visible[str(main.resolve())])


def test_unknown_imported_name_suggests(tmp_path: Path) -> None:
    write(tmp_path, "leaf.eac", LEAF)
    main = write(tmp_path, "main.eac", "use leaf.{Lef}\nconcept Tree { part a = Lef() }\n")
    _, diags = resolve([main])
    assert codes(diags) == ["E103"]  # no follow-on "unknown concept" for the same name
    assert diags[0].hint == "did you mean `Leaf`?"


def test_import_cycle(tmp_path: Path) -> None:
    write(tmp_path, "a.eac", "use b\nconcept A { param x : scalar = 1 }\n")
    write(tmp_path, "b.eac", "use a\nconcept B { param x : scalar = 1 }\n")
    _, diags = resolve([tmp_path])
    assert "E102" in codes(diags)
    assert (
        "a -> b -> a" in next(d for d in diags if d.code == "E102").message
        or "b -> a -> b" in next(d for d in diags if d.code == "E102").message
    )


def test_a_file_that_uses_itself_is_a_cycle(tmp_path: Path) -> None:
    """Regression: ``use`` of the file itself raised ValueError in resolve instead of E102."""
    me = write(tmp_path, "me.eac", "use me.{A}\nconcept A { param x : length = 1mm }\n")
    _, diags = resolve([me])
    assert codes(diags) == ["E102"]
    assert "me -> me" in diags[0].message and diags[0].span.line == 1


def test_duplicate_concepts_and_members(tmp_path: Path) -> None:
    write(tmp_path, "a.eac", "concept A { param x : scalar = 1  let x = 2 }\n")
    write(tmp_path, "b.eac", "concept A { param y : scalar = 1 }\n")
    _, diags = resolve([tmp_path])
    assert sorted(codes(diags)) == ["E104", "E105"]


def test_concept_containing_itself(tmp_path: Path) -> None:
    path = write(tmp_path, "a.eac", "concept A { part b = B() }\nconcept B { part a = A() }\n")
    _, diags = resolve([path])
    assert codes(diags) == ["E111", "E111"]
    assert "A -> B -> A" in diags[0].message


def test_link_tree_errors(tmp_path: Path) -> None:
    text = (
        "concept A {\n link l {}\n link m {}\n link n {}\n"
        " joint j1 : fixed(base -> l)\n joint j2 : fixed(base -> l)\n}\n"
    )
    _, diags = resolve([write(tmp_path, "a.eac", text)])
    messages = [d.message for d in diags]
    assert codes(diags).count("E112") == 3  # l has two parents; m and n hang from nothing
    assert any("already has a parent" in m for m in messages)


def test_a_misspelt_link_is_reported_once(tmp_path: Path) -> None:
    text = "concept A {\n link leaf {}\n joint j : fixed(base -> leef)\n}\n"
    _, diags = resolve([write(tmp_path, "a.eac", text)])
    assert codes(diags) == ["E108"] and diags[0].hint == "did you mean `leaf`?"


def test_a_joint_cycle_is_reported_once(tmp_path: Path) -> None:
    text = (
        "concept A {\n link a {}\n link b {}\n"
        " joint j1 : fixed(a -> b)\n joint j2 : fixed(b -> a)\n}\n"
    )
    _, diags = resolve([write(tmp_path, "a.eac", text)])
    assert codes(diags) == ["E112"] and "cycle" in diags[0].message


def test_unknown_joint_and_grasp_in_actions(tmp_path: Path) -> None:
    path = write(
        tmp_path,
        "a.eac",
        (
            "concept A { link l {}\n"
            " joint hinge : revolute(base -> l) axis (0, 1, 0) range [0, 1deg]\n"
            " grasp g = trans(0, 0, 0)\n action a = pull along hnige using g, gg }\n"
        ),
    )
    _, diags = resolve([path])
    assert codes(diags) == ["E109", "E110"]
    assert diags[0].hint == "did you mean `hinge`?"


def test_unreadable_files(tmp_path: Path) -> None:
    bad = tmp_path / "bad.eac"
    bad.write_bytes(b"concept \xff\xfe {}")
    _, diags = resolve([bad, tmp_path / "missing.eac"])
    assert codes(diags) == ["E006", "E006"]


def test_actions_may_move_a_part_joint(tmp_path: Path) -> None:
    text = (
        "use knobs.{RotaryDial}\nconcept H {\n    part dial = RotaryDial()\n"
        "    action turn_on = turn along dial.spin using dial.grip\n"
        "    action bad = turn along dial.spn\n}\n"
    )
    _, diags = resolve([write(tmp_path, "h.eac", text)])
    assert codes(diags) == ["E109"] and diags[0].hint == "did you mean `dial.spin`?"
