"""Syntax of a variant part's interface: an option's own mounting (``"knob" => RoundKnob() at
POSE``) and one option's parameter by name (``handle["bar"].length``), parsed and formatted back
unchanged."""

from __future__ import annotations

from grace_dsl.lang import ast
from grace_dsl.lang.formatter import format_expr, format_source
from grace_dsl.lang.parser import parse
from tests.lang.test_formatter import assert_guarantees

SOURCE = """concept C {
    param kind : choice{"bar", "knob"} = "bar"
    part handle = match kind {
        "bar" => StraightHandle() at trans(0, 0, handle.standoff),
        "knob" => RoundKnob(radius: 20mm)
    } at trans(0, 0, 18mm)
    part front = Front(handle["bar"].length: 120mm, handle.radius: 12mm)
    let s = handle["bar"].standoff
}
"""


def _concept(text: str) -> ast.Concept:
    result = parse(text, "t.eac")
    assert result.module is not None and not result.diagnostics, result.diagnostics
    return result.module.concepts[0]


def test_an_option_has_its_own_placement() -> None:
    part = _concept(SOURCE).members[1]
    assert isinstance(part, ast.Part)
    bar, knob = part.variants
    assert bar.at is not None and format_expr(bar.at) == "trans(0, 0, handle.standoff)"
    assert knob.at is None and knob.args == (ast.Arg("radius", ast.Number("20", "mm")),)
    assert part.at is not None and format_expr(part.at) == "trans(0, 0, 18mm)"
    assert bar.span.line == 4 and bar.span.end_line == 4  # the option's span covers its `at`


def test_one_options_parameter_by_name() -> None:
    c = _concept(SOURCE)
    front, let = c.members[2], c.members[3]
    assert isinstance(front, ast.Part) and isinstance(let, ast.Let)
    assert [a.name for a in front.args] == ["handle@bar.length", "handle.radius"]
    assert format_expr(let.value) == 'handle["bar"].standoff'


def test_formatting_keeps_both_forms() -> None:
    assert format_source(SOURCE).text == SOURCE
    out = assert_guarantees(SOURCE.replace("\n    ", " ").replace("\n", " "))
    assert '"bar" => StraightHandle() at trans(0, 0, handle.standoff),' in out
    assert 'Front(handle["bar"].length: 120mm, handle.radius: 12mm)' in out


def test_a_string_index_names_only_an_option() -> None:
    result = parse('concept C { part p = P(h[1 + 1].x: 1, h["a"]["b"].x: 2) }', "t.eac")
    assert [d.code for d in result.diagnostics] == ["E002"]
