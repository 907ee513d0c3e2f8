"""A grasp's ``when`` clause: parsed, formatted back, type-checked with located diagnostics."""

from __future__ import annotations

import pytest
from hypothesis import given, settings

from grace_dsl.compiler.check import check
from grace_dsl.compiler.resolve import resolve
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import render_all
from grace_dsl.lang.formatter import format_module, format_source
from grace_dsl.lang.parser import parse
from tests.lang.test_formatter import EXPRS, assert_guarantees, tree

DRAWER = """use primitives.{Cuboid}

/// A drawer hooked behind its front once it is out.
concept Tray {
    param width : length in [200mm, 600mm] = 400mm
    link drawer {
        shape front = Cuboid(size: (width, 120mm, 18mm))
        /// Hook behind the front, from above.
        grasp hook_top(s in [-width / 2 + 20mm, width / 2 - 20mm]) =
            trans(s, 40mm, -18.75mm) * rotx(90deg) * rotz(90deg)
            by hook
            when WHEN
    }
    joint slide : prismatic(base -> drawer) axis (0, 0, 1) range [0, 300mm]
    action open = pull along slide using hook_top
}
"""


def _grasp(text: str) -> ast.Grasp:
    result = parse(text, "t.eac")
    assert result.module is not None and not result.diagnostics, result.diagnostics
    link = next(m for m in result.module.concepts[0].members if isinstance(m, ast.Link))
    return next(m for m in link.members if isinstance(m, ast.Grasp))


def _diagnostics(tmp_path, when: str) -> str:  # type: ignore[no-untyped-def]
    return _render(tmp_path, DRAWER.replace("WHEN", when))


def _render(tmp_path, text: str) -> str:  # type: ignore[no-untyped-def]
    path = tmp_path / "tray.eac"
    path.write_text(text)
    prog, diags = resolve([path])
    _, more = check(prog)
    return render_all([*diags, *more], prog.sources()).replace(str(tmp_path) + "/", "")


def test_when_is_parsed_with_its_span_and_formatted_back() -> None:
    g = _grasp(DRAWER.replace("WHEN", "slide > 19mm and width > 250mm"))
    assert isinstance(g.when, ast.Binary) and g.when.op == "and"
    assert g.when.left == ast.Binary(">", ast.Name("slide"), ast.Number("19", "mm"))
    assert g.when.span.line == 12 and g.when.span.col == 18
    assert g.mode == "hook"
    out = assert_guarantees(DRAWER.replace("WHEN", "slide > 19mm and width > 250mm"))
    assert "            when slide > 19mm and width > 250mm\n" in out


def test_when_is_a_soft_keyword_and_given_once() -> None:
    """`when` stays usable as a name; a second `when` is E007 like any repeated clause."""
    g = _grasp(DRAWER.replace("WHEN", "when > 19mm").replace("400mm\n", "400mm\n let when = 1m\n"))
    assert g.when == ast.Binary(">", ast.Name("when"), ast.Number("19", "mm"))
    twice = parse(DRAWER.replace("WHEN", "slide > 1mm when slide > 2mm"), "t.eac")
    assert [d.code for d in twice.diagnostics] == ["E007"]


def test_the_shipped_conditional_families_type_check(tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert _diagnostics(tmp_path, "slide > 19mm") == ""
    assert _diagnostics(tmp_path, "slide >= 19mm or width < 1m and not (slide == 0mm)") == ""


@pytest.mark.parametrize(
    ("when", "code", "where", "hint"),
    [
        ("s > 19mm", "E238", "tray.eac:12:18", "narrow the range of `s` instead"),
        ("slide + 1mm", "E214", "tray.eac:12:18", "compare it"),
        ("slide > 19deg", "E203", "tray.eac:12:18", None),
        ("slid > 19mm", "E106", "tray.eac:12:18", "did you mean `slide`?"),
    ],
)
def test_a_malformed_when_is_located(  # type: ignore[no-untyped-def]
    tmp_path, when: str, code: str, where: str, hint: str | None
) -> None:
    text = _diagnostics(tmp_path, when)
    assert f"{where}: error[{code}]" in text, text
    assert f"  12 |             when {when}\n" in text  # the source line, then the caret
    caret = text.split(f"when {when}\n", 1)[1].splitlines()[0]
    assert caret.strip().startswith("^") and caret.index("^") == len("  12 |             when ")
    if hint:
        assert hint in text


def test_a_joint_value_outside_when_is_e202_with_a_hint(tmp_path) -> None:  # type: ignore[no-untyped-def]
    source = DRAWER.replace("WHEN", "slide > 1mm").replace("trans(s, 40mm", "trans(slide, 40mm")
    text = _render(tmp_path, source)
    assert "error[E202]: `slide` is a joint, not a value" in text
    assert "may be read only in a grasp's `when` condition" in text


@pytest.mark.slow
@settings(max_examples=80, derandomize=True, deadline=None)
@given(EXPRS)
def test_random_conditions_round_trip(cond: ast.Expr) -> None:
    """fmt(parse(x)) == x and parse(fmt(tree)) == tree for a grasp with a random `when`."""
    grasp = ast.Grasp("g", (), ast.Name("p"), mode="hook", when=cond)
    module = ast.Module("<string>", (), (ast.Concept("A", "concept", (grasp,)),))
    text = format_module(module)
    assert tree(text) == ((), module.concepts)
    assert format_source(text).text == text
