"""Syntax of repetition and variants: ``for`` blocks, indexed names, ``match`` parts.

Parsing builds name templates (``drawer[]``) with their index expressions beside them; the
formatter writes them back, and ``fmt(parse(x))`` is stable and keeps the tree (a hypothesis
property over generated loops, indices and variant parts).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from grace_dsl.lang import ast
from grace_dsl.lang.formatter import format_expr, format_module, format_source
from grace_dsl.lang.parser import parse
from tests.lang.test_formatter import EXPRS, assert_guarantees, tree

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "chest_of_drawers.eac"


def _concept(text: str) -> ast.Concept:
    result = parse(text, "t.eac")
    assert result.module is not None and not result.diagnostics, result.diagnostics
    return result.module.concepts[0]


def test_for_block_and_indexed_names() -> None:
    c = _concept(
        "concept C {\n param n : int in [1, 4] = 2\n for i in 0..n {\n"
        "  link d[i] { shape f[i] = Cuboid() }\n"
        "  joint s[i] : prismatic(base -> d[i]) axis (0, 0, 1) range [0, 1]\n"
        "  action open[i] = pull along s[i] using d[i].h[i - 1].pull, g\n } }"
    )
    loop = c.members[1]
    assert isinstance(loop, ast.For) and loop.var == "i"
    assert loop.lo == ast.Number("0") and loop.hi == ast.Name("n")
    link, joint, action = loop.members
    assert isinstance(link, ast.Link) and link.name == "d[]" and link.index == (ast.Name("i"),)
    assert isinstance(joint, ast.Joint) and joint.child == "d[]" and joint.parent_index == ()
    assert isinstance(action, ast.Action)
    assert action.joint == "s[]" and action.using == ("d[].h[].pull", "g")
    minus = ast.Binary("-", ast.Name("i"), ast.Number("1"))
    assert action.using_index == ((ast.Name("i"), minus), ())


def test_numbers_before_dots() -> None:
    """``0..n`` is a range, ``1.5`` a number, ``1..5`` a range of two integers."""
    c = _concept("concept C { for i in 1..5 { let a[i] = 1.5 * i } }")
    loop = c.members[0]
    assert isinstance(loop, ast.For) and loop.lo == ast.Number("1") and loop.hi == ast.Number("5")


def test_index_expression_and_variant_part() -> None:
    c = _concept(
        'concept C { let a = d[i + 1].w\n part h = match k { "a" => A(x: 1), "b" => B(), } at p }'
    )
    let, part = c.members
    assert isinstance(let, ast.Let)
    assert format_expr(let.value) == "d[i + 1].w"
    assert isinstance(part, ast.Part) and part.selector == ast.Name("k")
    assert [(v.value, v.concept) for v in part.variants] == [("a", "A"), ("b", "B")]
    assert part.variants[0].args == (ast.Arg("x", ast.Number("1")),)


def test_the_example_is_formatted_and_keeps_comments() -> None:
    text = EXAMPLE.read_text(encoding="utf-8")
    assert format_source(text).text == text
    commented = text.replace(
        "    for i in 0..n {", "    // one drawer per i\n    for i in 0..n {  // top first"
    )
    out = assert_guarantees(commented)
    assert "// one drawer per i" in out and "for i in 0..n {  // top first" in out


def test_long_variant_parts_break_one_option_per_line() -> None:
    out = assert_guarantees(
        'concept C { part handle_of_the_front = match kind { "bar" => StraightHandle(length: '
        '160mm), "knob" => RoundKnob(radius: 20mm), "pull" => PocketHandle() } at trans(0, 0, 1) }'
    )
    assert out.splitlines()[2].strip() == '"bar" => StraightHandle(length: 160mm),'
    assert out.splitlines()[-2].strip() == "} at trans(0, 0, 1)"


# ---- the round-trip property -----------------------------------------------------------------

INDEX = st.one_of(
    st.sampled_from([ast.Name("i"), ast.Name("j"), ast.Number("0"), ast.Number("12")]),
    st.builds(ast.Binary, st.sampled_from(["+", "-", "*"]), st.just(ast.Name("i")),
              st.sampled_from([ast.Number("1"), ast.Name("j")])),
)  # fmt: skip
INDICES = st.lists(INDEX, max_size=2).map(tuple)
BASES = st.sampled_from(["d", "front", "x_1"])


@st.composite
def indexed_expr(draw: st.DrawFn) -> ast.Expr:
    """``d[i]``, ``d[i + 1].w`` or a random expression with an indexed name inside."""
    e: ast.Expr = ast.Name(draw(BASES))
    for ix in draw(st.lists(INDEX, min_size=1, max_size=2)):
        e = ast.Index(e, ix)
    if draw(st.booleans()):
        e = ast.Member(e, "w")
    other = draw(EXPRS)
    return draw(st.sampled_from([e, ast.Binary("+", e, other), ast.Call("f", (ast.Arg(None, e),))]))


@st.composite
def member(draw: st.DrawFn, depth: int = 0) -> ast.Member_:
    name, index = draw(BASES), draw(INDICES)
    template = name + ast.HOLE * len(index)
    kind = draw(st.sampled_from(["let", "shape", "link", "joint", "action", "variant", "for"]))
    if kind == "for" and depth < 2:
        body = tuple(draw(st.lists(member(depth + 1), min_size=0, max_size=3)))
        lo = draw(st.sampled_from([ast.Number("0"), ast.Number("1")]))
        hi = draw(st.sampled_from([ast.Name("n"), ast.Number("4")]))
        return ast.For(draw(st.sampled_from(["i", "j", "k"])), lo, hi, body)
    if kind == "shape":
        return ast.Shape(template, draw(indexed_expr()), None, index=index)
    if kind == "link":
        inner = ast.Shape("s" + ast.HOLE * len(index), ast.Call("Cuboid", ()), index=index)
        return ast.Link(template, (inner,), index=index)
    if kind == "joint":
        child_ix = draw(INDICES)
        child = "c" + ast.HOLE * len(child_ix)
        return ast.Joint(template, "revolute", "base", child, ast.Vector((ast.Number("0"),) * 3),
                         index=index, child_index=child_ix)  # fmt: skip
    if kind == "action":
        refs = draw(st.lists(st.tuples(BASES, INDICES), min_size=1, max_size=2))
        using = tuple(f"{b}{ast.HOLE * len(ix)}.pull" for b, ix in refs)
        using_index = tuple(ix for _, ix in refs) if any(ix for _, ix in refs) else ()
        j_ix = draw(INDICES)
        return ast.Action(template, "pull", "s" + ast.HOLE * len(j_ix), using=using, index=index,
                          joint_index=j_ix, using_index=using_index)  # fmt: skip
    if kind == "variant":
        options = draw(st.lists(st.sampled_from(["bar", "knob", "a b"]), min_size=1, max_size=3,
                                unique=True))  # fmt: skip
        variants = tuple(
            ast.Variant(
                o,
                "C" + str(k),
                draw(st.lists(st.builds(ast.Arg, st.just("x"), EXPRS), max_size=1).map(tuple)),
            )  # fmt: skip
            for k, o in enumerate(options)
        )
        at = draw(st.none() | indexed_expr())
        selector = draw(st.sampled_from([ast.Name("kind"), ast.String("bar")]) | indexed_expr())
        return ast.Part(template, "", (), at, index=index, selector=selector, variants=variants)
    return ast.Let(template, draw(indexed_expr()), index=index)


@pytest.mark.slow
@settings(max_examples=120, derandomize=True, deadline=None)
@given(st.lists(member(), min_size=1, max_size=4))
def test_random_loops_round_trip(members: list[ast.Member_]) -> None:
    """fmt(parse(x)) == x and parse(fmt(tree)) == tree for generated repetition syntax."""
    module = ast.Module("<string>", (), (ast.Concept("A", "concept", tuple(members)),))
    text = format_module(module)
    assert tree(text) == ((), module.concepts)
    assert format_source(text).text == text
