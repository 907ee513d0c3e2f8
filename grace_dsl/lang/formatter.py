"""Canonical layout of .eac source, for ``eacc fmt`` and for printing formulas in manifests.

The code is printed from the syntax tree, so the layout is canonical by construction.  What the
tree does not hold (``//`` comments and the author's blank lines) comes from a second parse of
the same grammar that keeps token positions; each comment is attached to the declaration it sits
before, inside or after, and re-emitted there.  For every valid input the tests check that the
tree is unchanged, that formatting is idempotent and that every comment survives, in order.
"""

from __future__ import annotations

import re
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

from lark import Lark, Token, Tree

from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, has_errors

# The formatter must lex exactly as the parser does (same grammar, same doc-comment rule).
from grace_dsl.lang.parser import DocPostLex, grammar, parse

WIDTH = 100
INDENT = 4

Pos = tuple[int, int]  # (line, column), both 1-based as lark reports them
Part = str | ast.Expr  # a piece of a declaration: fixed text or an expression
Segment = list[Part]  # a clause that may move to a continuation line as a whole
Decl = ast.Use | ast.Concept | ast.Member_


@dataclass(frozen=True)
class FormatResult:
    """The formatted text, or None (and the parser's diagnostics) when the source is invalid."""

    text: str | None
    diagnostics: tuple[Diagnostic, ...] = ()


def format_source(source: str, path: str = "<string>") -> FormatResult:
    """Format a whole file, keeping its comments; never raises on bad input."""
    result = parse(source, path)
    if result.module is None or has_errors(result.diagnostics):
        return FormatResult(None, result.diagnostics)
    tree, comments = _positions(source)
    items = [_node(t) for t in tree.children if isinstance(t, Tree)]
    root = _Node("start", (0, 0), (sys.maxsize, 0), None, items)
    _distribute(root, comments)
    decls = _source_order(root, result.module)
    return FormatResult(_Printer(source).module(root, decls), result.diagnostics)


def check_formatted(source: str, path: str = "<string>") -> bool:
    """True when the source is valid and already in canonical layout (``eacc fmt --check``)."""
    return format_source(source, path).text == source


def format_module(module: ast.Module) -> str:
    """Print a tree without a source: no comments, no blank lines inside blocks, uses first."""
    decls: list[Decl] = [*module.uses, *module.concepts]
    root = _Node("start", (0, 0), (0, 0), None, [_bare_node(d) for d in decls])
    return _Printer(None).module(root, decls)


# ---- expressions on one line -------------------------------------------------------------------

# Binding strength, loosest first, following the grammar's levels.  An operand is parenthesised
# exactly when it binds more loosely than its slot accepts, which gives minimal parentheses.
_IF, _OR, _AND, _NOT, _CMP, _SUM, _TERM, _SIGN, _POW, _POSTFIX, _ATOM = range(11)
_BINARY = {
    "or": _OR, "and": _AND, **dict.fromkeys(ast.COMPARISONS, _CMP),
    "+": _SUM, "-": _SUM, "*": _TERM, "/": _TERM, "^": _POW,
}  # fmt: skip
# The loosest operand each side of a binary operator takes without parentheses: `a - (b - c)`,
# comparisons do not chain, and `^` takes a signed right operand (`a^-b`) but not a signed left.
_SLOTS = {
    _OR: (_OR, _AND), _AND: (_AND, _NOT), _CMP: (_SUM, _SUM), _SUM: (_SUM, _TERM),
    _TERM: (_TERM, _SIGN), _POW: (_POSTFIX, _SIGN),
}  # fmt: skip
_CHAINS = frozenset({_OR, _AND, _CMP, _SUM, _TERM})  # operators a long line may break at
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t"}


def format_expr(e: ast.Expr) -> str:
    """An expression on one line with minimal parentheses; it parses back to the same tree."""
    if isinstance(e, ast.Number):
        return e.text + (e.unit or "")
    if isinstance(e, ast.Name):
        return e.id
    if isinstance(e, ast.String):
        return quote(e.value)
    if isinstance(e, ast.Bool):
        return "true" if e.value else "false"
    if isinstance(e, ast.Unary):
        return _unary_prefix(e) + _sub(e.operand, _prec(e))
    if isinstance(e, ast.Binary):
        left, right = _SLOTS[_BINARY[e.op]]
        op = e.op if e.op == "^" else f" {e.op} "
        return _sub(e.left, left) + op + _sub(e.right, right)
    if isinstance(e, ast.Call):
        return f"{e.func}({', '.join(_arg_prefix(a.name) + format_expr(a.value) for a in e.args)})"
    if isinstance(e, ast.Vector):
        return f"({', '.join(format_expr(item) for item in e.items)})"
    if isinstance(e, ast.Member):
        # `1.x` would lex as the number `1.` and a name (`1.e5` as one number): keep `(1).x`.
        obj = format_expr(e.obj)
        digits = isinstance(e.obj, ast.Number) and e.obj.unit is None and e.obj.text.isdigit()
        wrap = digits or _prec(e.obj) < _POSTFIX
        return f"({obj}).{e.field}" if wrap else f"{obj}.{e.field}"
    if isinstance(e, ast.IfExpr):
        return f"if {format_expr(e.cond)} then {format_expr(e.then)} else {format_expr(e.orelse)}"
    if isinstance(e, ast.Index):
        return f"{_sub(e.obj, _POSTFIX)}[{format_expr(e.index)}]"
    raise TypeError(f"not an expression: {e!r}")


def quote(value: str) -> str:
    """A string literal that the parser reads back as ``value``."""
    return '"' + "".join(_ESCAPES.get(ch, ch) for ch in value) + '"'


def _prec(e: ast.Expr) -> int:
    if isinstance(e, ast.IfExpr):
        return _IF
    if isinstance(e, ast.Binary):
        return _BINARY[e.op]
    if isinstance(e, ast.Unary):
        return _NOT if e.op == "not" else _SIGN
    if isinstance(e, (ast.Member, ast.Index)):
        return _POSTFIX
    return _ATOM


def _sub(e: ast.Expr, slot: int) -> str:
    text = format_expr(e)
    return f"({text})" if _prec(e) < slot else text


def _unary_prefix(e: ast.Unary) -> str:
    return "not " if e.op == "not" else e.op


def _arg_prefix(name: str | None) -> str:
    return f"{arg_name(name)}: " if name else ""


def arg_name(name: str) -> str:
    """``handle@bar.length`` (one option's parameter) as written: ``handle["bar"].length``."""
    return re.sub(r"@([^.]+)", lambda m: f'["{m.group(1)}"]', name)


# ---- expressions over several lines ------------------------------------------------------------
# A layout is a list of lines: the first continues the current line, the others are whole lines.
# ``col`` is where the expression starts, ``indent`` the indentation of the line it starts on.


def _layout(e: ast.Expr, col: int, indent: int) -> list[str]:
    """Break an expression that does not fit: calls and vectors one item per line, long
    chains of operators before an operator, `if` with `then` and `else` on their own lines."""
    flat = format_expr(e)
    if col + len(flat) <= WIDTH:
        return [flat]
    if isinstance(e, ast.Call) and e.args:
        return _layout_items(f"{e.func}(", [(a.name, a.value) for a in e.args], indent)
    if isinstance(e, ast.Vector):
        return _layout_items("(", [(None, item) for item in e.items], indent)
    if isinstance(e, ast.IfExpr):
        return _layout_if(e, col, indent)
    if isinstance(e, ast.Binary) and _BINARY[e.op] in _CHAINS:
        return _layout_chain(e, col, indent)
    if isinstance(e, ast.Unary):
        return _prefixed(_unary_prefix(e), e.operand, _prec(e), col, indent)
    return [flat]


def _layout_sub(e: ast.Expr, slot: int, col: int, indent: int) -> list[str]:
    if _prec(e) >= slot:
        return _layout(e, col, indent)
    lines = _layout(e, col + 1, indent)
    lines[0] = "(" + lines[0]
    lines[-1] += ")"
    return lines


def _prefixed(prefix: str, e: ast.Expr, slot: int, col: int, indent: int) -> list[str]:
    lines = _layout_sub(e, slot, col + len(prefix), indent)
    lines[0] = prefix + lines[0]
    return lines


def _layout_items(opener: str, items: list[tuple[str | None, ast.Expr]], indent: int) -> list[str]:
    """``f(`` / one argument per line with a trailing comma / ``)``: the grammar allows it."""
    inner = indent + INDENT
    lines = [opener]
    for name, value in items:
        head = " " * inner + _arg_prefix(name)
        sub = _layout(value, len(head), inner)
        lines += [head + sub[0], *sub[1:]]
        lines[-1] += ","
    lines.append(" " * indent + ")")
    return lines


def _layout_if(e: ast.IfExpr, col: int, indent: int) -> list[str]:
    lines = _prefixed("if ", e.cond, _IF, col, indent)
    inner = indent + INDENT
    for word, branch in (("then ", e.then), ("else ", e.orelse)):
        sub = _prefixed(word, branch, _IF, inner, inner)
        lines += [" " * inner + sub[0], *sub[1:]]
    return lines


def _layout_chain(e: ast.Binary, col: int, indent: int) -> list[str]:
    """``a + b + c ...`` filled up to the width; continuation lines start with the operator."""
    level = _BINARY[e.op]
    left_slot, right_slot = _SLOTS[level]
    chains = left_slot <= level  # comparisons do not chain: `(a < b) < c`
    rest: list[tuple[str, ast.Expr]] = []
    node = e
    while True:
        rest.append((node.op, node.right))
        if not (chains and isinstance(node.left, ast.Binary) and _BINARY[node.left.op] == level):
            break
        node = node.left
    first = node.left
    lines = _layout_sub(first, left_slot, col, indent)
    cont = indent + INDENT
    for op, operand in reversed(rest):
        piece = f"{op} {_sub(operand, right_slot)}"
        end = len(lines[-1]) if len(lines) > 1 else col + len(lines[0])
        if end + 1 + len(piece) <= WIDTH:
            lines[-1] += " " + piece
        else:
            sub = _prefixed(f"{op} ", operand, right_slot, cont, cont)
            lines += [" " * cont + sub[0], *sub[1:]]
    return lines


# ---- declarations ------------------------------------------------------------------------------


def indexed(template: str, index: ast.Indices) -> str:
    """A name or reference with its indices written back: ``drawer[i + 1].handle.pull``."""
    return ast.fill(template, [format_expr(e) for e in index]) if index else template


def _segments(d: Decl) -> tuple[list[Segment], bool]:
    """A declaration as clauses, and whether a long one fills continuation lines greedily
    (params, like the shipped files) rather than one clause per line (joints, grasps)."""
    if isinstance(d, ast.Param):
        segs: list[Segment] = [[f"param {d.name} : {_type(d.type)}"]]
        if d.bounds is not None:
            segs.append(["in [", d.bounds.lo, ", ", d.bounds.hi, "]"])
        if d.default is not None:
            segs.append(["= ", d.default])
        if d.help is not None:
            segs.append([quote(d.help)])
        return segs, True
    if isinstance(d, ast.Require):
        message: list[Segment] = [[quote(d.message)]] if d.message is not None else []
        return [["require ", d.cond], *message], False
    if isinstance(d, ast.Let):
        return [[f"let {indexed(d.name, d.index)} ="], [d.value]], False
    if isinstance(d, ast.Shape):
        return [[f"shape {indexed(d.name, d.index)} = ", d.value], *_placement(d.at)], False
    if isinstance(d, ast.Part) and d.selector is not None:
        return _variant_segments(d), False
    if isinstance(d, ast.Part):
        call = ast.Call(d.concept, d.args)
        return [[f"part {indexed(d.name, d.index)} = ", call], *_placement(d.at)], False
    if isinstance(d, ast.Joint):
        return _joint_segments(d), False
    if isinstance(d, ast.Grasp):
        width: list[Segment] = [["width ", d.width]] if d.width is not None else []
        mode: list[Segment] = [[f"by {d.mode}"]] if d.mode is not None else []
        about: list[Segment] = [["symmetric about ", d.about]] if d.about is not None else []
        symmetric = about or ([["symmetric"]] if d.symmetric else [])
        when: list[Segment] = [["when ", d.when]] if d.when is not None else []
        return [_grasp_head(d), [d.pose], *width, *mode, *symmetric, *when], False
    if isinstance(d, ast.Action):
        return _action_segments(d), False
    if isinstance(d, ast.Use):
        names = f".{{{', '.join(d.names)}}}" if d.names is not None else ""
        return [[f"use {'.'.join(d.module)}{names}"]], False
    raise TypeError(f"not a one-line declaration: {d!r}")


def _type(t: ast.TypeRef) -> str:
    if t.choices is not None:
        return f"choice{{{', '.join(quote(c) for c in t.choices)}}}"
    return f"{t.name} {t.unit}" if t.unit else t.name


def _placement(at: ast.Expr | None) -> list[Segment]:
    return [["at ", at]] if at is not None else []


def _variant_segments(d: ast.Part) -> list[Segment]:
    """``part h = match kind { "bar" => Bar(), ... }``; a long one puts each option on a line."""
    assert d.selector is not None
    head: Segment = [f"part {indexed(d.name, d.index)} = match ", d.selector, " {"]
    arms: list[Segment] = []
    for i, v in enumerate(d.variants):
        last = i == len(d.variants) - 1
        mount: Segment = [" at ", v.at] if v.at is not None else []
        arms.append(
            [f"{quote(v.value)} => ", ast.Call(v.concept, v.args), *mount, "" if last else ","]
        )
    return [head, *arms, ["}"], *_placement(d.at)]


def _joint_segments(d: ast.Joint) -> list[Segment]:
    parent, child = indexed(d.parent, d.parent_index), indexed(d.child, d.child_index)
    segs: list[Segment] = [[f"joint {indexed(d.name, d.index)} : {d.kind}({parent} -> {child})"]]
    if d.axis is not None:
        segs.append(["axis ", d.axis])
    segs += _placement(d.origin)
    if d.limits is not None:
        segs.append(["range [", d.limits.lo, ", ", d.limits.hi, "]"])
    if d.opens is not None:
        segs.append([f"opens {'+' if d.opens > 0 else '-'}"])
    return segs


def _grasp_head(d: ast.Grasp) -> Segment:
    head: Segment = [f"grasp {indexed(d.name, d.index)}"]
    for i, fp in enumerate(d.free):
        head += [("(" if i == 0 else ", ") + f"{fp.name} in [", fp.lo, ", ", fp.hi, "]"]
        if fp.default is not None:
            head += [" = ", fp.default]
    head.append(") =" if d.free else " =")
    return head


def _action_segments(d: ast.Action) -> list[Segment]:
    head: Segment = [f"action {indexed(d.name, d.index)} = {d.verb}"]
    if d.joint is not None:
        joint = indexed(d.joint, d.joint_index)
        head.append(f" along {joint}" + (f" {d.sense}" if d.sense else ""))
    elif d.direction is not None:
        head += [" toward ", d.direction]
    ixs = d.using_index or tuple(() for _ in d.using)
    refs = ", ".join(indexed(u, ix) for u, ix in zip(d.using, ixs, strict=True))
    using: list[Segment] = [[f"using {refs}"]] if d.using else []
    return [head, *using]


def _flat(seg: Segment) -> str:
    return "".join(p if isinstance(p, str) else format_expr(p) for p in seg)


def _code_lines(d: Decl, indent: int) -> list[str]:
    """One line when it fits in WIDTH, else the first clause and continuation lines."""
    segs, fill = _segments(d)
    flat = " ".join(_flat(s) for s in segs)
    if indent + len(flat) <= WIDTH:
        return [" " * indent + flat]
    if isinstance(d, ast.Part) and d.selector is not None:  # one option per line, `}` below
        arms = len(d.variants)
        lines = _layout_parts(segs[0], indent)
        for seg in segs[1 : 1 + arms]:
            lines += _layout_parts(seg, indent + INDENT)
        close = " " * indent + "}" + "".join(" " + _flat(seg) for seg in segs[2 + arms :])
        if len(close) <= WIDTH:
            return [*lines, close]
        lines.append(" " * indent + "}")  # a long placement continues below the brace
        for seg in segs[2 + arms :]:
            lines += _layout_parts(seg, indent + INDENT)
        return lines
    lines = _layout_parts(segs[0], indent)
    for seg in segs[1:]:
        text = _flat(seg)
        if fill and len(lines[-1]) + 1 + len(text) <= WIDTH:
            lines[-1] += " " + text
        else:
            lines += _layout_parts(seg, indent + INDENT)
    return lines


def _layout_parts(seg: Segment, indent: int) -> list[str]:
    lines = [" " * indent]
    for part in seg:
        if isinstance(part, str):
            lines[-1] += part
            continue
        current = lines[-1]
        sub = _layout(part, len(current), len(current) - len(current.lstrip(" ")))
        lines[-1] += sub[0]
        lines += sub[1:]
    return lines


def _doc_lines(doc: str) -> list[str]:
    """Docs print as leading ``///`` lines; a trailing one would only join them anyway."""
    return [f"/// {line}" if line else "///" for line in doc.split("\n")] if doc else []


# ---- where comments and declarations are in the source -----------------------------------------


@dataclass(frozen=True)
class _Comment:
    line: int
    col: int
    text: str
    eol: bool  # code precedes it on its line

    @property
    def pos(self) -> Pos:
        return (self.line, self.col)


@dataclass
class _Node:
    """A declaration's extent in the source and the comments attached to it."""

    rule: str
    start: Pos  # its first token, doc comments included
    end: Pos  # just after its last token
    open: Pos | None  # the `{` of a concept or link
    children: list[_Node]
    lead: list[_Comment] = field(default_factory=list)  # own-line comments before it
    inner: list[_Comment] = field(default_factory=list)  # among its tokens (before `{`)
    header: _Comment | None = None  # after `{`, on its line
    trail: _Comment | None = None  # after its last token, on that line
    close: list[_Comment] = field(default_factory=list)  # after the last member, before `}`


_DECL_RULES = frozenset({
    "use_some", "use_all", "concept_decl", "param_decl", "require_decl", "let_decl",
    "shape_decl", "part_decl", "link_decl", "joint_decl", "grasp_decl", "action_decl",
    "for_decl", "variant_part_decl",
})  # fmt: skip
_BLOCK_RULES = frozenset({"concept_decl", "link_decl", "for_decl"})


class _CommentSink:
    """Collects the COMMENT tokens the lexer skips, for the parse that holds the lock."""

    def __init__(self) -> None:
        self.tokens: list[Token] = []

    def __call__(self, tok: Token) -> Token:
        self.tokens.append(tok)
        return tok


@lru_cache(maxsize=1)
def _position_parser() -> tuple[Lark, _CommentSink]:
    sink = _CommentSink()
    lark = Lark(
        grammar(),
        parser="lalr",
        lexer="contextual",
        postlex=DocPostLex(),
        propagate_positions=True,
        keep_all_tokens=True,
        maybe_placeholders=False,
        lexer_callbacks={"COMMENT": sink},
    )
    return lark, sink


_POSITIONS_LOCK = threading.Lock()


def _positions(source: str) -> tuple[Tree[Token], list[_Comment]]:
    """The positioned parse tree and the comments, found by the parser's own lexer (so a ``//``
    inside a string or a ``///`` doc is never taken for a comment)."""
    lark, sink = _position_parser()
    with _POSITIONS_LOCK:
        sink.tokens = []
        tree = lark.parse(source)
        tokens, sink.tokens = sink.tokens, []
    lines = source.split("\n")
    comments = [
        _Comment(
            t.line or 0,
            t.column or 0,
            t.value.rstrip(),
            bool(lines[(t.line or 1) - 1][: (t.column or 1) - 1].strip()),
        )
        for t in tokens
    ]
    return tree, sorted(comments, key=lambda c: c.pos)


def _node(tree: Tree[Token]) -> _Node:
    meta = tree.meta
    kids = [_node(ch) for ch in tree.children if isinstance(ch, Tree) and ch.data in _DECL_RULES]
    brace = None
    if tree.data in _BLOCK_RULES:
        tok = next(ch for ch in tree.children if isinstance(ch, Token) and ch.value == "{")
        brace = (tok.line or 0, tok.column or 0)
    start, end = (meta.line, meta.column), (meta.end_line, meta.end_column)
    return _Node(str(tree.data), start, end, brace, kids)


def _bare_node(d: Decl) -> _Node:
    block = isinstance(d, (ast.Concept, ast.Link, ast.For))
    members: Sequence[Decl] = d.members if isinstance(d, (ast.Concept, ast.Link, ast.For)) else ()
    brace = (0, 0) if block else None
    return _Node(type(d).__name__, (0, 0), (0, 0), brace, [_bare_node(m) for m in members])


def _distribute(node: _Node, comments: Sequence[_Comment]) -> None:
    """Attach each comment of a block's body (or of the file) to the member it belongs to."""
    kids = node.children
    inside: list[list[_Comment]] = [[] for _ in kids]
    i = 0
    for c in comments:
        while i < len(kids) and kids[i].end <= c.pos:
            i += 1
        if i < len(kids) and kids[i].start <= c.pos:
            inside[i].append(c)
        elif i > 0 and kids[i - 1].end[0] == c.line:
            kids[i - 1].trail = c
        elif i == 0 and node.open is not None and node.open[0] == c.line:
            node.header = c
        elif i < len(kids):
            kids[i].lead.append(c)
        else:
            node.close.append(c)
    for kid, found in zip(kids, inside, strict=True):
        if kid.open is None:
            kid.inner = found
            continue
        kid.inner = [c for c in found if c.pos < kid.open]
        _distribute(kid, [c for c in found if c.pos > kid.open])


def _source_order(root: _Node, module: ast.Module) -> list[Decl]:
    """Uses and concepts in the order of the file, so comments between them keep their order."""
    uses, concepts = iter(module.uses), iter(module.concepts)
    return [next(uses) if n.rule.startswith("use") else next(concepts) for n in root.children]


# ---- printing ----------------------------------------------------------------------------------


class _Printer:
    """Emits declarations with their comments and the author's blank lines (at most one)."""

    def __init__(self, source: str | None) -> None:
        self.out: list[str] = []
        self._fresh = True  # at the start of the file or of a block: no blank line here
        self._blanks = [0]  # _blanks[k]: how many of source lines 1..k are blank
        for line in source.split("\n") if source is not None else ():
            self._blanks.append(self._blanks[-1] + (not line.strip()))

    def module(self, root: _Node, decls: Sequence[Decl]) -> str:
        self._members(root, decls, 0, top=True)
        return "\n".join(self.out) + "\n" if self.out else ""

    def _line(self, text: str, blank: bool = False) -> None:
        if blank and not self._fresh:
            self.out.append("")
        self.out.append(text)
        self._fresh = False

    def _gap(self, after: int, before: int) -> bool:
        """Whether the source has a blank line strictly between two lines."""
        if not 0 <= after < before - 1 < len(self._blanks):
            return False
        return self._blanks[before - 1] > self._blanks[after]

    def _members(self, node: _Node, decls: Sequence[Decl], depth: int, top: bool = False) -> None:
        prev_line = node.open[0] if node.open is not None else 0
        prev: Decl | None = None
        for kid, decl in zip(node.children, decls, strict=True):
            # Top-level declarations stand apart, except consecutive `use` lines.
            force = (
                top
                and prev is not None
                and not (isinstance(prev, ast.Use) and isinstance(decl, ast.Use))
            )
            self._group(kid, decl, depth, prev_line, force)
            prev_line, prev = kid.end[0], decl
        self._comments(node.close, depth, prev_line)

    def _comments(
        self, comments: Sequence[_Comment], depth: int, prev_line: int, force: bool = False
    ) -> int:
        """Own-line comments; ``force`` puts a blank line before the first one."""
        for c in comments:
            self._line(" " * (INDENT * depth) + c.text, force or self._gap(prev_line, c.line))
            prev_line, force = c.line, False
        return prev_line

    def _group(self, kid: _Node, decl: Decl, depth: int, prev_line: int, force: bool) -> None:
        """A declaration with the comments that go before it and on its first line."""
        prev_line = self._comments(kid.lead, depth, prev_line, force)
        blank = (force and not kid.lead) or self._gap(prev_line, kid.start[0])
        if kid.open is not None:  # a block keeps its trailing comment after its `}`
            attached, eol = kid.inner, None
        else:  # a lone end-of-line comment stays on the first line, several go before it
            attached = [*kid.inner, *([kid.trail] if kid.trail else [])]
            eol = attached[0] if len(attached) == 1 and attached[0].eol else None
        for c in [] if eol else attached:
            self._line(" " * (INDENT * depth) + c.text, blank)
            blank = False
        self._declaration(kid, decl, depth, blank, eol)

    def _declaration(
        self, kid: _Node, decl: Decl, depth: int, blank: bool, eol: _Comment | None
    ) -> None:
        indent = " " * (INDENT * depth)
        if not isinstance(decl, (ast.Use, ast.For)):
            for line in _doc_lines(decl.doc):
                self._line(indent + line, blank)
                blank = False
        if isinstance(decl, (ast.Concept, ast.Link, ast.For)):
            self._block(kid, decl, depth, blank)
            return
        lines = _code_lines(decl, INDENT * depth)
        if eol is not None:
            lines[0] += "  " + eol.text
        for line in lines:
            self._line(line, blank)
            blank = False

    def _block(
        self, kid: _Node, decl: ast.Concept | ast.Link | ast.For, depth: int, blank: bool
    ) -> None:
        if isinstance(decl, ast.For):
            lo, hi = _sub(decl.lo, _SUM), _sub(decl.hi, _SUM)
            title = f"for {decl.var} in {lo}..{hi}"
        elif isinstance(decl, ast.Concept):
            title = f"{decl.kind} {decl.name}"
        else:
            title = f"link {indexed(decl.name, decl.index)}"
        head = f"{' ' * (INDENT * depth)}{title} {{"
        trail = f"  {kid.trail.text}" if kid.trail else ""
        if not decl.members and not kid.close and kid.header is None:
            self._line(head + "}" + trail, blank)
            return
        self._line(head + (f"  {kid.header.text}" if kid.header else ""), blank)
        self._fresh = True
        self._members(kid, decl.members, depth + 1)
        self._line(" " * (INDENT * depth) + "}" + trail)
