"""The parse pass: the tree it builds, where it says things are, and how it fails."""

from __future__ import annotations

from grace_dsl.lang import ast
from grace_dsl.lang.parser import MAX_DEPTH, parse


def one_concept(src: str) -> ast.Concept:
    result = parse(src, "t.eac")
    assert result.diagnostics == (), [d.render(src) for d in result.diagnostics]
    assert result.module is not None
    (concept,) = result.module.concepts
    return concept


def test_param_with_units_range_default_help_and_docs() -> None:
    c = one_concept(
        "/// A thing.\nconcept A {\n"
        "    /// leading\n"
        '    param r : length in [1mm, 2.5cm] = 1.5mm "help"  /// trailing\n'
        "}\n"
    )
    (p,) = c.members
    assert isinstance(p, ast.Param)
    assert c.doc == "A thing."
    assert p.type == ast.TypeRef("length")
    assert p.bounds == ast.Bounds(ast.Number("1", "mm"), ast.Number("2.5", "cm"))
    assert p.default == ast.Number("1.5", "mm")
    assert (p.help, p.doc) == ("help", "leading\ntrailing")
    assert (p.name_span.line, p.name_span.col) == (4, 11)


def test_vector_and_choice_types() -> None:
    c = one_concept(
        "concept A { param v : vec3 length = (1mm, 2mm, 3mm)\n"
        ' param s : choice{"left", "right"} = "left" }'
    )
    v, s = c.members
    assert isinstance(v, ast.Param) and isinstance(s, ast.Param)
    assert v.type == ast.TypeRef("vec3", "length")
    assert isinstance(v.default, ast.Vector) and len(v.default.items) == 3
    assert s.type.choices == ("left", "right") and s.default == ast.String("left")


def test_soft_keywords_are_names_outside_their_clause() -> None:
    c = one_concept(
        "concept A { param width : length = 1mm  param range : scalar = 1\n"
        "  param axis : scalar = 2  let along = width * range * axis }"
    )
    assert [m.name for m in c.members] == ["width", "range", "axis", "along"]  # type: ignore[union-attr]


def test_operator_precedence_and_associativity() -> None:
    c = one_concept("concept A { let x = -a^2 * b + c / d - e  let y = a - b - c }")
    x, y = c.members
    assert isinstance(x, ast.Let) and isinstance(y, ast.Let)
    # ((-(a^2)) * b + c / d) - e
    assert x.value == ast.Binary(
        "-",
        ast.Binary(
            "+",
            ast.Binary(
                "*", ast.Unary("-", ast.Binary("^", ast.Name("a"), ast.Number("2"))), ast.Name("b")
            ),
            ast.Binary("/", ast.Name("c"), ast.Name("d")),
        ),
        ast.Name("e"),
    )
    assert y.value == ast.Binary("-", ast.Binary("-", ast.Name("a"), ast.Name("b")), ast.Name("c"))


def test_if_and_boolean_operators() -> None:
    c = one_concept('concept A { let x = if a > 1 and not b or c == "k" then 1 else 2 }')
    (x,) = c.members
    assert isinstance(x, ast.Let) and isinstance(x.value, ast.IfExpr)
    cond = x.value.cond
    assert isinstance(cond, ast.Binary) and cond.op == "or"
    assert isinstance(cond.left, ast.Binary) and cond.left.op == "and"


def test_joint_grasp_and_action() -> None:
    c = one_concept(
        "concept D { link leaf { grasp g(t in [0, 1] = 0.5, u in [0, 2]) = trans(t, u, 0) "
        "width 3mm }\n joint h : revolute(base -> leaf) axis (0, 1, 0) at (1mm, 0, 0) "
        "range [0, 90deg] opens -\n action open = pull along h opening using g, handle.g2\n"
        " action press = press toward (0, 0, -1) }"
    )
    link, joint, open_, press = c.members
    assert isinstance(link, ast.Link) and isinstance(link.members[0], ast.Grasp)
    grasp = link.members[0]
    assert [f.name for f in grasp.free] == ["t", "u"] and grasp.free[1].default is None
    assert isinstance(joint, ast.Joint)
    assert (joint.kind, joint.parent, joint.child, joint.opens) == ("revolute", "base", "leaf", -1)
    assert isinstance(open_, ast.Action) and open_.using == ("g", "handle.g2")
    assert (open_.verb, open_.joint, open_.sense) == ("pull", "h", "opening")
    assert isinstance(press, ast.Action) and press.direction is not None and press.joint is None


def test_use_forms() -> None:
    r = parse("use primitives.{Ring, Cuboid}\nuse shapes.more\n", "t.eac")
    assert r.module is not None
    a, b = r.module.uses
    assert (a.module, a.names) == (("primitives",), ("Ring", "Cuboid"))
    assert (b.module, b.names) == (("shapes", "more"), None)


def test_spans_exclude_from_equality_but_locate() -> None:
    a = parse("concept A { let x = 1 }", "a.eac").module
    b = parse("concept A {\n\n   let   x =\n 1\n}", "b.eac").module
    assert a is not None and b is not None
    assert a.concepts == b.concepts
    let = b.concepts[0].members[0]
    assert isinstance(let, ast.Let) and (let.name_span.line, let.name_span.col) == (3, 10)


def test_several_syntax_errors_in_one_run_keep_the_rest() -> None:
    src = (
        "concept A {\n"
        "    param r : length = 1.5 mm\n"
        "    param t = 4\n"
        "    param ok : length = 2mm\n"
        "    grasp g = rotz(0\n"
        "    param u : angle = 1deg\n"
        "}\n"
    )
    r = parse(src, "t.eac")
    assert [d.code for d in r.diagnostics] == ["E002", "E002", "E002"]
    assert [d.span.line for d in r.diagnostics] == [2, 3, 5]
    assert "1.5mm" in (r.diagnostics[0].hint or "")
    assert r.module is not None
    assert [m.name for m in r.module.concepts[0].members] == ["ok", "u"]  # type: ignore[union-attr]
    assert r.dropped == {"r", "t", "g"}


def test_render_has_location_caret_and_hint() -> None:
    src = "concept A {\n    param t = 4\n}\n"
    (d,) = parse(src, "t.eac").diagnostics
    text = d.render(src)
    assert text.splitlines()[0] == "t.eac:2:13: error[E002]: unexpected `=`; expected `:`"
    assert text.splitlines()[2].index("^") == text.splitlines()[1].index("=")
    assert "hint" in text


def test_unterminated_string_and_stray_characters() -> None:
    r = parse('concept A {\n param x : length = "abc\n}', "t.eac")
    assert r.diagnostics[0].code == "E001"
    r = parse("concept A { let x = 1; }", "t.eac")
    assert r.diagnostics[0].code == "E001" and "`;`" in (r.diagnostics[0].hint or "")


def test_end_of_file_inside_a_block() -> None:
    r = parse("concept A { let x = (1 + ", "t.eac")
    assert r.module is None and r.diagnostics[0].code == "E003"


def test_deep_nesting_is_a_diagnostic_not_a_crash() -> None:
    depth = 20_000
    src = "concept A { let x = " + "-" * depth + "1 }"
    r = parse(src, "t.eac")
    assert [d.code for d in r.diagnostics] == ["E004"]
    ok = "concept A { let x = " + "-(" * (MAX_DEPTH - 1) + "1" + ")" * (MAX_DEPTH - 1) + " }"
    assert parse(ok, "t.eac").diagnostics == ()


def test_number_too_large() -> None:
    r = parse("concept A { let x = 1e400mm }", "t.eac")
    assert [d.code for d in r.diagnostics] == ["E005"]


def test_the_standard_library_is_formatted() -> None:
    """`eacc fmt --check` passes on the shipped concepts (they are the style reference)."""
    from grace_dsl.compiler.resolve import stdlib_dir
    from grace_dsl.lang.formatter import check_formatted

    for path in sorted(stdlib_dir().glob("*.eac")):
        assert check_formatted(path.read_text(), str(path)), path.name


def test_a_joint_clause_given_twice() -> None:
    src = (
        "concept A { link l {}\n joint j : revolute(base -> l) axis (0, 1, 0) range [0, 1deg]"
        " axis (1, 0, 0) }"
    )
    r = parse(src, "t.eac")
    assert [(d.code, d.span.line, d.span.col) for d in r.diagnostics] == [("E007", 2, 68)]


def test_a_doc_comment_that_documents_nothing() -> None:
    (d,) = parse("concept A { let x = 1\n/// orphan\n}", "t.eac").diagnostics
    assert d.code == "E002" and "documents nothing" in d.message


def test_a_stray_doc_comment_is_reported_once_at_the_comment() -> None:
    """Regression: a `///` before `}` was reported N+1 times (N members), at the brace."""
    src = (
        "concept A {\n    param x : length = 1mm\n    let y = x\n    let z = y\n"
        "    link l {\n        /// first\n        /// second\n    }\n"
        "    /// orphan\n}\n"
    )
    r = parse(src, "t.eac")
    assert [(d.code, d.span.line, d.span.col) for d in r.diagnostics] == [
        ("E002", 6, 9),
        ("E002", 9, 5),
    ]
    assert r.module is not None and len(r.module.concepts[0].members) == 4  # nothing dropped


def test_an_unclosed_brace_names_its_line() -> None:
    (d,) = parse("concept A {\n    let x = 1\n", "t.eac").diagnostics
    assert d.code == "E003" and "line 1 is never closed" in d.message


def test_a_stray_closing_brace_is_dropped_alone() -> None:
    r = parse("concept A { let x = 1 }\n}\nconcept B { let y = 2 }\n", "t.eac")
    assert [(d.code, d.span.line) for d in r.diagnostics] == [("E002", 2)]
    assert r.module is not None and [c.name for c in r.module.concepts] == ["A", "B"]


def test_keywords_stay_keywords() -> None:
    """A keyword never becomes a name, so an unfinished expression ends at the next line."""
    src = "concept A {\n    let x = w +\n    let y = x * 2\n}\n"
    (d,) = parse(src, "t.eac").diagnostics
    assert (d.code, d.span.line) == ("E002", 2) and "before `let` on line 3" in d.message
    (d,) = parse("concept A { param if : scalar = 1 }", "t.eac").diagnostics
    assert "`if` is a keyword" in (d.hint or "")
    ok = parse("use primitive.shapes\nconcept A { let x = h.part }", "t.eac")
    assert ok.diagnostics == ()  # module paths and members may use any word


def test_grasp_clauses_in_any_order() -> None:
    """`width`, `by` and `symmetric [about v]` follow the pose in any order; the AST is the same."""
    base = "concept A { grasp g(t in [0, 1]) = trans(0, 0, t) %s }"
    orders = [
        "width 2mm by hook symmetric about (1, 0, 0)",
        "symmetric about (1, 0, 0) by hook width 2mm",
        "by hook symmetric about (1, 0, 0) width 2mm",
    ]
    grasps = [one_concept(base % o).members[0] for o in orders]
    assert grasps[0] == grasps[1] == grasps[2]
    g = grasps[0]
    assert isinstance(g, ast.Grasp)
    assert (g.mode, g.symmetric, g.about) == (
        "hook",
        True,
        ast.Vector((ast.Number("1"), ast.Number("0"), ast.Number("0"))),
    )
    plain = one_concept("concept A { grasp g = trans(0, 0, 1mm) symmetric }").members[0]
    assert isinstance(plain, ast.Grasp)
    assert (plain.mode, plain.symmetric, plain.about) == (None, True, None)


def test_grasp_clause_words_stay_names() -> None:
    c = one_concept(
        "concept A { param by : scalar = 1  param symmetric : scalar = 2\n"
        "  let about = by * symmetric  grasp g = trans(0, 0, about * 1mm) by push }"
    )
    assert [m.name for m in c.members] == ["by", "symmetric", "about", "g"]  # type: ignore[union-attr]


def test_a_grasp_clause_given_twice() -> None:
    r = parse("concept A { grasp g = trans(0, 0, 1mm) by hook by push }", "t.eac")
    assert [(d.code, d.span.col) for d in r.diagnostics] == [("E007", 51)]
    assert "gives `by` twice" in r.diagnostics[0].message
