"""Parse pass: source text -> ``ast.Module`` plus diagnostics; never raises on bad input.

The LALR parser builds the tree bottom-up through an inline transformer, so even absurdly deep
input costs no Python recursion; a depth limit then keeps later (recursive) passes safe.
After a syntax error the broken declaration is blanked out and the file parsed again, so one run
reports the errors of many declarations and still hands the rest of the file to the checker.
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

from lark import Lark, Token, Transformer
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken
from lark.lark import PostLex

from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, error
from grace_dsl.lang.grammar_cache import cached_lark

MAX_DEPTH = 64
MAX_RECOVERIES = 25
UNITS = ("mm", "cm", "m", "deg", "rad")
KEYWORDS = frozenset(
    "use concept primitive param require let shape part link joint grasp action in at if then "
    "else and or not true false choice for match".split()
)
SYNC_KEYWORDS = frozenset(
    [
        "param",
        "require",
        "let",
        "shape",
        "part",
        "link",
        "joint",
        "grasp",
        "action",
        "concept",
        "primitive",
        "use",
        "for",
    ]
)


@dataclass(frozen=True)
class ParseResult:
    module: ast.Module | None
    diagnostics: tuple[Diagnostic, ...]
    # Names of declarations dropped by error recovery: later passes stay quiet about them.
    dropped: frozenset[str] = frozenset()


def parse(source: str, path: str = "<string>") -> ParseResult:
    """Parse a whole file, recovering from syntax errors declaration by declaration."""
    diags: list[Diagnostic] = []
    dropped: set[str] = set()
    text = source
    for _ in range(MAX_RECOVERIES):
        try:
            module, notes = _parse_once(text, path)
        except UnexpectedInput as exc:
            stray = _stray_doc(exc, text, path)
            if stray is not None:  # report it once, at the comment, and parse on without it
                diag, text = stray
                diags.append(diag)
                continue
            diags.append(_syntax_diagnostic(exc, text, path))
            blanked = _blank_declaration(text, exc)
            if blanked is None:
                return ParseResult(None, tuple(diags), frozenset(dropped))
            text, name = blanked
            if name:
                dropped.add(name)
            continue
        except _TooDeep as exc:
            diags.append(exc.diagnostic)
            return ParseResult(None, tuple(diags), frozenset(dropped))
        except _BadNumber as exc:
            diags.append(exc.diagnostic)
            return ParseResult(None, tuple(diags), frozenset(dropped))
        return ParseResult(module, tuple(diags + notes), frozenset(dropped))
    return ParseResult(None, tuple(diags), frozenset(dropped))


# ---- lark setup ---------------------------------------------------------------------------------


class DocPostLex(PostLex):
    """Turns a ``///`` comment that ends a line of code into a trailing doc (TDOC)."""

    always_accept = ("DOC",)

    def process(self, stream: Iterator[Token]) -> Iterator[Token]:
        prev_line, prev_type = -1, ""
        for tok in stream:
            if tok.type == "DOC" and tok.line == prev_line:
                tok = Token.new_borrow_pos("TDOC", tok.value, tok)
            elif tok.type == "NAME" and tok.value in KEYWORDS and prev_type not in ("DOT", "USE"):
                # The contextual lexer reads a keyword as a name where no keyword fits; keep it
                # a keyword, so `let x = a +` followed by `let y` ends at the right place.
                # Module paths (`use a.b`) and members (`h.part`) may still use any word.
                tok = Token.new_borrow_pos(tok.value.upper(), tok.value, tok)
            prev_type = tok.type
            prev_line = tok.end_line if tok.end_line is not None else -1
            yield tok


@lru_cache(maxsize=1)
def grammar() -> str:
    return resources.files("grace_dsl.lang").joinpath("eac.lark").read_text(encoding="utf-8")


class _TooDeep(Exception):
    def __init__(self, diagnostic: Diagnostic):
        self.diagnostic = diagnostic


class _BadNumber(Exception):
    def __init__(self, diagnostic: Diagnostic):
        self.diagnostic = diagnostic


@lru_cache(maxsize=1)
def _parser() -> tuple[Lark, _Builder]:
    builder = _Builder("<string>")
    lark = cached_lark(
        grammar(),
        {"postlex": DocPostLex(), "transformer": builder},
        parser="lalr",
        lexer="contextual",
        maybe_placeholders=True,
    )
    return lark, builder


_PARSE_LOCK = threading.Lock()


def _parse_once(text: str, path: str) -> tuple[ast.Module, list[Diagnostic]]:
    lark, builder = _parser()
    with _PARSE_LOCK:  # the inline builder holds per-parse state
        builder.path, builder.depth, builder.notes, builder.indices = path, {}, [], {}
        try:
            items: list[Any] = lark.parse(text)  # type: ignore[assignment]  # inline builder
            notes = builder.notes
        finally:
            builder.depth, builder.notes, builder.indices = {}, [], {}
    uses = tuple(i for i in items if isinstance(i, ast.Use))
    concepts = tuple(i for i in items if isinstance(i, ast.Concept))
    return ast.Module(path, uses, concepts), notes


# ---- tree building ------------------------------------------------------------------------------


def _tok_span(path: str, tok: Token) -> ast.Span:
    return ast.Span(path, tok.line or 0, tok.column or 0, tok.end_line or 0, tok.end_column or 0)


@dataclass(frozen=True)
class _Clause:
    """A tagged piece of a declaration (range, default, placement, ...), resolved by its parent."""

    tag: str
    value: Any
    span: ast.Span = ast.NO_SPAN


def _doc_text(tokens: list[Token]) -> str:
    return "\n".join(t.value[3:].strip() for t in tokens)


def _string_value(tok: Token) -> str:
    """Unescape a double-quoted literal without evaluating it as Python."""
    body = tok.value[1:-1]
    return re.sub(r"\\(.)", lambda m: {"n": "\n", "t": "\t"}.get(m.group(1), m.group(1)), body)


class _Builder(Transformer):
    """Inline (bottom-up) construction of the AST while the LALR parser reduces."""

    def __init__(self, path: str):
        super().__init__(visit_tokens=False)
        self.path = path
        self.depth: dict[int, int] = {}
        self.notes: list[Diagnostic] = []  # problems that do not stop the parse
        # the index expressions of an indexed name's token (``drawer[]``), by the token's id
        self.indices: dict[int, tuple[Token, tuple[Any, ...]]] = {}

    # -- helpers
    def _span(self, first: Any, last: Any) -> ast.Span:
        return self._start(first).to(self._end(last))

    def _start(self, node: Any) -> ast.Span:
        if isinstance(node, Token):
            return _tok_span(self.path, node)
        span = getattr(node, "span", ast.NO_SPAN)
        return span if isinstance(span, ast.Span) else ast.NO_SPAN

    _end = _start

    def _expr(self, node: Any, *children: Any) -> Any:
        depth = 1 + max((self.depth.get(id(c), 0) for c in children), default=0)
        self.depth[id(node)] = depth
        if depth > MAX_DEPTH:
            raise _TooDeep(
                error(
                    "E004",
                    f"expression nested more than {MAX_DEPTH} levels deep (each operator of a "
                    "chain such as `a + b + c` counts as a level)",
                    node.span,
                    "split it with `let` definitions",
                )
            )
        return node

    # -- top level
    def start(self, items: list[Any]) -> list[Any]:
        return items

    def module_path(self, c: list[Any]) -> list[Token]:
        return [c[0]] if len(c) == 1 else [*c[0], c[1]]

    def name_list(self, c: list[Token]) -> list[Token]:
        return [t for t in c if t is not None]

    def use_some(self, c: list[Any]) -> ast.Use:
        path, names = c
        return ast.Use(
            tuple(t.value for t in path),
            tuple(t.value for t in names),
            self._span(path[0], names[-1]),
            tuple(_tok_span(self.path, t) for t in names),
            self._span(path[0], path[-1]),
        )

    def use_all(self, c: list[Any]) -> ast.Use:
        (path,) = c
        span = self._span(path[0], path[-1])
        return ast.Use(tuple(t.value for t in path), None, span, (), span)

    def docs(self, c: list[Token]) -> list[Token]:
        return c

    def tdoc(self, c: list[Token | None]) -> list[Token]:
        return [t for t in c if t is not None]

    def concept_kind(self, _: list[Any]) -> str:
        return "concept"

    def primitive_kind(self, _: list[Any]) -> str:
        return "primitive"

    def concept_decl(self, c: list[Any]) -> ast.Concept:
        docs, kind, name, *members = c
        span = _tok_span(self.path, name)
        return ast.Concept(
            name.value, kind, tuple(members), _doc_text(docs), span, _tok_span(self.path, name)
        )

    # -- indexed names and repetition
    def decl_name(self, c: list[Any]) -> Token:
        """``drawer[i]`` as one token ``drawer[]`` spanning the whole name; its index
        expressions are kept aside (``_ix``)."""
        first, *indices = c
        if not indices:
            return first
        last = self._end(indices[-1])
        tok = Token(
            "NAME",
            first.value + ast.HOLE * len(indices),
            first.start_pos,
            first.line,
            first.column,
            last.end_line,
            last.end_col + 1,  # the closing `]`
            first.end_pos,
        )
        self.indices[id(tok)] = (tok, tuple(indices))  # the token kept alive: ids stay unique
        return tok

    def index(self, c: list[Any]) -> Any:
        return c[0]

    def _ix(self, tok: Token | None) -> tuple[Any, ...]:
        kept, indices = self.indices.get(id(tok), (None, ()))
        return indices if tok is not None and kept is tok else ()

    def for_decl(self, c: list[Any]) -> ast.For:
        var, lo, _dots, hi, *members = c
        return ast.For(
            var.value, lo, hi, tuple(members), self._span(var, hi), _tok_span(self.path, var)
        )

    def index_expr(self, c: list[Any]) -> ast.Index:
        obj, index = c
        span = self._start(obj).to(self._end(index))
        span = ast.Span(span.file, span.line, span.col, span.end_line, span.end_col + 1)
        return self._expr(ast.Index(obj, index, span), obj, index)

    def variant(self, c: list[Any]) -> ast.Variant:
        value, concept, args, *rest = c
        at = rest[0].value if rest and isinstance(rest[0], _Clause) else None
        return ast.Variant(
            _string_value(value),
            concept.value,
            tuple(args or ()),
            self._span(value, at or concept),
            _tok_span(self.path, concept),
            at,
        )

    def variant_part_decl(self, c: list[Any]) -> ast.Part:
        docs, name, selector, *rest = c
        trailing = rest.pop()
        at = rest.pop().value if rest and isinstance(rest[-1], _Clause) else None
        if rest and rest[-1] is None:
            rest.pop()
        variants = tuple(v for v in rest if isinstance(v, ast.Variant))
        return ast.Part(
            name.value,
            "",
            (),
            at,
            self._docs(docs, trailing),
            self._span(name, at or selector),
            _tok_span(self.path, name),
            self._start(selector),
            self._ix(name),
            selector,
            variants,
        )

    # -- members
    def _docs(self, leading: list[Token], trailing: list[Token]) -> str:
        return _doc_text(leading + trailing)

    def param_decl(self, c: list[Any]) -> ast.Param:
        docs, name, type_ref, *rest = c
        trailing = rest.pop()
        bounds = next((x.value for x in rest if isinstance(x, _Clause) and x.tag == "range"), None)
        default = next(
            (x.value for x in rest if isinstance(x, _Clause) and x.tag == "default"), None
        )
        help_tok = next((x for x in rest if isinstance(x, Token)), None)
        last = help_tok or default or (bounds and bounds.hi) or type_ref
        return ast.Param(
            name.value,
            type_ref,
            bounds,
            default,
            _string_value(help_tok) if help_tok else None,
            self._docs(docs, trailing),
            self._span(name, last),
            _tok_span(self.path, name),
        )

    def type_named(self, c: list[Token | None]) -> ast.TypeRef:
        name, unit = c[0], c[1] if len(c) > 1 else None
        assert name is not None
        return ast.TypeRef(
            name.value, unit.value if unit else None, None, self._span(name, unit or name)
        )

    def type_choice(self, c: list[Token | None]) -> ast.TypeRef:
        toks = [t for t in c if t is not None]
        return ast.TypeRef(
            "choice", None, tuple(_string_value(t) for t in toks), self._span(toks[0], toks[-1])
        )

    def param_range(self, c: list[Any]) -> _Clause:
        lo, hi = c
        return _Clause("range", ast.Bounds(lo, hi, self._span(lo, hi)))

    def param_default(self, c: list[Any]) -> _Clause:
        return _Clause("default", c[0])

    def placement(self, c: list[Any]) -> _Clause:
        return _Clause("at", c[0])

    def require_decl(self, c: list[Any]) -> ast.Require:
        docs, cond, *rest = c
        trailing = rest.pop()
        msg = _string_value(rest[0]) if rest and rest[0] is not None else None
        return ast.Require(cond, msg, self._docs(docs, trailing), self._start(cond))

    def let_decl(self, c: list[Any]) -> ast.Let:
        docs, name, value, trailing = c
        return ast.Let(
            name.value,
            value,
            self._docs(docs, trailing),
            self._span(name, value),
            _tok_span(self.path, name),
            self._ix(name),
        )

    def shape_decl(self, c: list[Any]) -> ast.Shape:
        docs, name, value, *rest = c
        trailing = rest.pop()
        at = rest[0].value if rest and rest[0] is not None else None
        return ast.Shape(
            name.value,
            value,
            at,
            self._docs(docs, trailing),
            self._span(name, at or value),
            _tok_span(self.path, name),
            self._ix(name),
        )

    def part_decl(self, c: list[Any]) -> ast.Part:
        docs, name, concept, args, *rest = c
        trailing = rest.pop()
        at = rest[0].value if rest and rest[0] is not None else None
        return ast.Part(
            name.value,
            concept.value,
            tuple(args or ()),
            at,
            self._docs(docs, trailing),
            self._span(name, at or concept),
            _tok_span(self.path, name),
            _tok_span(self.path, concept),
            self._ix(name),
        )

    def link_decl(self, c: list[Any]) -> ast.Link:
        docs, name, *members = c
        trailing = members.pop()
        return ast.Link(
            name.value,
            tuple(members),
            self._docs(docs, trailing),
            _tok_span(self.path, name),
            _tok_span(self.path, name),
            self._ix(name),
        )

    def joint_decl(self, c: list[Any]) -> ast.Joint:
        docs, name, kind, parent, child, *clauses = c
        trailing = clauses.pop()
        found = self._once(clauses, f"joint `{name.value}`")
        return ast.Joint(
            name.value,
            kind.value,
            parent.value,
            child.value,
            found["axis"].value if "axis" in found else None,
            found["origin"].value if "origin" in found else None,
            found["range"].value if "range" in found else None,
            found["opens"].value if "opens" in found else None,
            self._docs(docs, trailing),
            _tok_span(self.path, name),
            _tok_span(self.path, name),
            _tok_span(self.path, kind),
            _tok_span(self.path, parent),
            _tok_span(self.path, child),
            self._ix(name),
            self._ix(parent),
            self._ix(child),
        )

    def joint_axis(self, c: list[Any]) -> _Clause:
        return _Clause("axis", c[0], self._start(c[0]))

    def joint_origin(self, c: list[Any]) -> _Clause:
        return _Clause("origin", c[0], self._start(c[0]))

    def joint_range(self, c: list[Any]) -> _Clause:
        lo, hi = c
        return _Clause("range", ast.Bounds(lo, hi, self._span(lo, hi)), self._span(lo, hi))

    def joint_opens(self, c: list[Token]) -> _Clause:
        return _Clause("opens", 1 if c[0].value == "+" else -1, _tok_span(self.path, c[0]))

    def grasp_decl(self, c: list[Any]) -> ast.Grasp:
        docs, name, *rest = c
        trailing = rest.pop()
        free: tuple[ast.FreeParam, ...] = ()
        if rest and isinstance(rest[0], _Clause) and rest[0].tag == "free":
            free = rest.pop(0).value
        elif rest and rest[0] is None:
            rest.pop(0)
        pose, clauses = rest[0], rest[1:]
        found = self._once(clauses, f"grasp `{name.value}`")
        width = found["width"].value if "width" in found else None
        mode = found.get("by")
        symmetric = found.get("symmetric")
        when = found.get("when")
        last = clauses[-1].span if clauses else self._end(pose)
        return ast.Grasp(
            name.value,
            free,
            pose,
            width,
            self._docs(docs, trailing),
            self._start(name).to(last),
            _tok_span(self.path, name),
            mode.value.value if mode else None,
            symmetric is not None,
            symmetric.value if symmetric else None,
            _tok_span(self.path, mode.value) if mode else ast.NO_SPAN,
            self._ix(name),
            when.value if when else None,
        )

    def _once(self, clauses: list[_Clause], owner: str) -> dict[str, _Clause]:
        """Clauses by tag; a clause given twice is E007 (the declaration would depend on order)."""
        found: dict[str, _Clause] = {}
        for cl in clauses:
            if cl.tag in found:
                word = {"origin": "at"}.get(cl.tag, cl.tag)
                self.notes.append(
                    error(
                        "E007",
                        f"{owner} gives `{word}` twice",
                        cl.span,
                        "keep one; the declaration would otherwise depend on the order",
                    )
                )
            found[cl.tag] = cl
        return found

    def grasp_free(self, c: list[Any]) -> _Clause:
        return _Clause("free", tuple(x for x in c if x is not None))

    def free_param(self, c: list[Any]) -> ast.FreeParam:
        name, lo, hi, *rest = c
        default = rest[0].value if rest and rest[0] is not None else None
        return ast.FreeParam(name.value, lo, hi, default, self._span(name, default or hi))

    def grasp_width(self, c: list[Any]) -> _Clause:
        return _Clause("width", c[0], self._start(c[0]))

    def grasp_mode(self, c: list[Token]) -> _Clause:
        return _Clause("by", c[0], _tok_span(self.path, c[0]))

    def grasp_symmetric(self, c: list[Any]) -> _Clause:
        word, *about = c
        span = self._span(word, about[-1]) if about else _tok_span(self.path, word)
        return _Clause("symmetric", about[0] if about else None, span)

    def grasp_when(self, c: list[Any]) -> _Clause:
        return _Clause("when", c[0], self._span(c[0], c[0]))

    def action_decl(self, c: list[Any]) -> ast.Action:
        docs, name, verb, rule, *rest = c
        trailing = rest.pop()
        refs = list(rest[0]) if rest and rest[0] is not None else []
        using = tuple(text for text, _ in refs)
        using_index = tuple(ix for _, ix in refs) if any(ix for _, ix in refs) else ()
        joint_tok, sense, direction = rule
        return ast.Action(
            name.value,
            verb.value,
            joint_tok.value if joint_tok else None,
            sense,
            direction,
            using,
            self._docs(docs, trailing),
            self._span(name, verb),
            _tok_span(self.path, name),
            _tok_span(self.path, verb),
            _tok_span(self.path, joint_tok) if joint_tok else ast.NO_SPAN,
            self._ix(name),
            self._ix(joint_tok),
            using_index,
        )

    def along_rule(self, c: list[Any]) -> tuple[Token, str | None, None]:
        joint = c[0]
        sense = c[1] if len(c) > 1 else None
        return joint, sense, None

    def opening(self, _: list[Any]) -> str:
        return "opening"

    def closing(self, _: list[Any]) -> str:
        return "closing"

    def toward_rule(self, c: list[Any]) -> tuple[None, None, Any]:
        return None, None, c[0]

    def action_using(self, c: list[Any]) -> list[Any]:
        return c

    def joint_ref(self, c: list[Token]) -> Token:
        """``hinge``, a part's joint ``knob.spin`` or ``drawer[i].slide``, as one token spanning
        the whole name (its indices kept aside like a declaration's)."""
        first, last = c[0], c[-1]
        tok = Token(
            "NAME",
            ".".join(t.value for t in c),
            first.start_pos,
            first.line,
            first.column,
            last.end_line,
            last.end_column,
            last.end_pos,
        )
        indices = tuple(i for t in c for i in self._ix(t))
        if indices:
            self.indices[id(tok)] = (tok, indices)
        return tok

    def grasp_ref(self, c: list[Token]) -> tuple[str, tuple[Any, ...]]:
        return ".".join(t.value for t in c), tuple(i for t in c for i in self._ix(t))

    # -- expressions
    def if_expr(self, c: list[Any]) -> ast.IfExpr:
        cond, then, orelse = c
        return self._expr(ast.IfExpr(cond, then, orelse, self._span(cond, orelse)), *c)

    def _binop(self, op: str, left: Any, right: Any) -> ast.Binary:
        return self._expr(ast.Binary(op, left, right, self._span(left, right)), left, right)

    def or_op(self, c: list[Any]) -> ast.Binary:
        return self._binop("or", c[0], c[1])

    def and_op(self, c: list[Any]) -> ast.Binary:
        return self._binop("and", c[0], c[1])

    def not_op(self, c: list[Any]) -> ast.Unary:
        return self._expr(ast.Unary("not", c[0], self._start(c[0])), c[0])

    def compare(self, c: list[Any]) -> ast.Binary:
        return self._binop(c[1].value, c[0], c[2])

    def binary(self, c: list[Any]) -> ast.Binary:
        return self._binop(c[1].value, c[0], c[2])

    def unary(self, c: list[Any]) -> ast.Unary:
        op, operand = c
        return self._expr(ast.Unary(op.value, operand, self._span(op, operand)), operand)

    def member(self, c: list[Any]) -> ast.Member:
        obj, name = c
        return self._expr(ast.Member(obj, name.value, self._span(obj, name)), obj)

    def number(self, c: list[Token]) -> ast.Number:
        return self._literal(c[0].value, None, c[0])

    def quantity(self, c: list[Token]) -> ast.Number:
        text = c[0].value
        unit = next(u for u in sorted(UNITS, key=len, reverse=True) if text.endswith(u))
        return self._literal(text[: -len(unit)], unit, c[0])

    def _literal(self, digits: str, unit: str | None, tok: Token) -> ast.Number:
        span = _tok_span(self.path, tok)
        if not math.isfinite(float(digits)):
            raise _BadNumber(
                error(
                    "E005",
                    f"number `{tok.value}` is too large to represent",
                    span,
                    "numbers must stay below about 1e308",
                )
            )
        return ast.Number(digits, unit, span)

    def string(self, c: list[Token]) -> ast.String:
        return ast.String(_string_value(c[0]), _tok_span(self.path, c[0]))

    def true(self, c: list[Token]) -> ast.Bool:
        return ast.Bool(True, _tok_span(self.path, c[0]))

    def false(self, c: list[Token]) -> ast.Bool:
        return ast.Bool(False, _tok_span(self.path, c[0]))

    def name(self, c: list[Token]) -> ast.Name:
        return ast.Name(c[0].value, _tok_span(self.path, c[0]))

    def call(self, c: list[Any]) -> ast.Call:
        func, args, close = c
        args = tuple(args or ())
        span = self._span(func, close)
        node = ast.Call(func.value, args, span, _tok_span(self.path, func))
        return self._expr(node, *(a.value for a in args))

    def vector(self, c: list[Any]) -> ast.Vector:
        open_, *inner, close = c
        items = tuple(x for x in inner if x is not None)
        return self._expr(ast.Vector(items, self._span(open_, close)), *items)

    def arg_list(self, c: list[Any]) -> list[ast.Arg]:
        return [a for a in c if a is not None]

    def pos_arg(self, c: list[Any]) -> ast.Arg:
        return ast.Arg(None, c[0], self._start(c[0]))

    def named_arg(self, c: list[Any]) -> ast.Arg:
        """``length: 120mm``, or ``handle.length: 120mm`` for a parameter of a nested part."""
        target, value = c
        name = _dotted(target)
        if name is None:
            raise _BadNumber(
                error(
                    "E002",
                    "an argument's name must be a name, such as `length`, `handle.length` or "
                    '`handle["bar"].length`',
                    target.span,
                    "write `name: value`",
                )
            )
        return ast.Arg(name, value, self._span(target, value))


def _dotted(e: Any) -> str | None:
    """``a.b.c`` for a name or a chain of member accesses on a name; None for anything else."""
    fields: list[str] = []
    while isinstance(e, (ast.Member, ast.Index)):
        if isinstance(e, ast.Index):  # `handle["bar"].length`: one option of a variant part
            if not (isinstance(e.index, ast.String) and fields):
                return None
            inner = _dotted(e.obj)
            if inner is None:
                return None
            return ".".join([f"{inner}@{e.index.value}", *reversed(fields)])
        fields.append(e.field)
        e = e.obj
    if not isinstance(e, ast.Name):
        return None
    return ".".join([e.id, *reversed(fields)])


# ---- syntax errors ------------------------------------------------------------------------------

_TOKEN_NAMES = {
    "NAME": "a name",
    "NUMBER": "a number",
    "QUANTITY": "a number with a unit",
    "STRING": "a string",
    "DOC": "a `///` doc comment",
    "TDOC": "a `///` doc comment",
    "LBRACE": "`{`",
    "RBRACE": "`}`",
    "LPAR": "`(`",
    "RPAR": "`)`",
    "LSQB": "`[`",
    "RSQB": "`]`",
    "COMMA": "`,`",
    "COLON": "`:`",
    "EQUAL": "`=`",
    "DOT": "`.`",
    "CMP_OP": "a comparison",
    "ADD_OP": "`+` or `-`",
    "MUL_OP": "`*` or `/`",
    "POW_OP": "`^`",
    "SIGN": "`+` or `-`",
    "$END": "end of file",
    "MORETHAN": "`>`",
}


def _describe(term: str) -> str:
    if term in _TOKEN_NAMES:
        return _TOKEN_NAMES[term]
    if term.isupper() and "__" not in term:
        return f"`{term.lower()}`"
    return term


_OPERATORS = {"ADD_OP", "MUL_OP", "POW_OP", "CMP_OP", "DOT", "AND", "OR"}


def _expected_list(expected: set[str]) -> str:
    """What the parser wanted, in words; the operators that could continue an expression
    are folded into one phrase, so the structural choices stay visible."""
    shown = expected - {"DOC", "TDOC"}
    words = sorted({_describe(t) for t in shown - _OPERATORS})
    if shown & _OPERATORS:
        words.append("an operator")
    if len(words) > 6:
        words = [*words[:6], "..."]
    return ", ".join(words) if len(words) < 2 else ", ".join(words[:-1]) + " or " + words[-1]


def _syntax_diagnostic(exc: UnexpectedInput, text: str, path: str) -> Diagnostic:
    line, col = exc.line if exc.line > 0 else 1, exc.column if exc.column > 0 else 1
    if isinstance(exc, UnexpectedCharacters):
        pos = exc.pos_in_stream or 0
        ch = text[pos] if pos < len(text) else ""
        span = ast.Span(path, line, col, line, col + 1)
        hint = {
            "'": "strings use double quotes",
            "#": "comments start with `//`",
            ";": "declarations need no `;`",
        }.get(ch)
        if ch == '"':
            hint = "a string must end on the line it starts"
        return error("E001", f"unexpected character {ch!r}", span, hint)
    if isinstance(exc, UnexpectedEOF) or (
        isinstance(exc, UnexpectedToken) and exc.token.type == "$END"
    ):
        last = text.rstrip().splitlines() or [""]
        span = ast.Span(path, len(last), len(last[-1]) + 1, len(last), len(last[-1]) + 2)
        open_lines = _open_braces(text, len(text))
        if open_lines:
            return error(
                "E003",
                f"unexpected end of file: the `{{` on line {open_lines[-1]} is never closed",
                span,
                "add the missing `}`",
            )
        expected = _expected_list(set(getattr(exc, "expected", ()) or ()))
        return error(
            "E003", f"unexpected end of file; expected {expected}", span, "is a `)` missing?"
        )
    assert isinstance(exc, UnexpectedToken)
    tok = exc.token
    span = _tok_span(path, tok)
    found = f"`{tok.value}`" if tok.type not in ("DOC", "TDOC") else "a doc comment"
    message = f"unexpected {found}; expected {_expected_list(set(exc.expected))}"
    before = exc.token_history[-1] if exc.token_history else None
    if (
        tok.type == "NAME"
        and tok.value in UNITS
        and before is not None
        and (before.type == "NUMBER")
    ):
        message = f"unexpected `{tok.value}` after the number `{before.value}`"
    if tok.type == "RBRACE" and not _open_braces(text, tok.start_pos or 0):
        return error("E002", "unexpected `}`: no block is open here", span, "one `}` too many?")
    prev = _unfinished_before(exc, text)
    if prev is not None:
        span = ast.Span(path, prev[0], prev[1], prev[0], prev[1] + 1)
        message = f"declaration ends too early, before `{tok.value}` on line {tok.line}; " + (
            f"expected {_expected_list(set(exc.expected))}"
        )
        hint = _token_hint(exc, text) if tok.value not in SYNC_KEYWORDS else None
        return error("E002", message, span, hint or "is something missing at the end of it?")
    return error("E002", message, span, _token_hint(exc, text))


def _token_hint(exc: UnexpectedToken, text: str) -> str | None:
    tok, expected = exc.token, set(exc.expected)
    prev = exc.token_history[-1] if exc.token_history else None
    if tok.type == "NAME" and tok.value in UNITS and prev is not None and prev.type == "NUMBER":
        return f"write the unit right after the number: `{prev.value}{tok.value}`"
    if tok.value in KEYWORDS and "NAME" in expected:
        return f"`{tok.value}` is a keyword and cannot be a name; try `{tok.value}_`"
    if tok.type == "EQUAL" and "COLON" in expected:
        return "a parameter needs a type: `param x : length = 5mm`"
    if "RPAR" in expected and "COMMA" in expected:
        return "is a `,` or `)` missing?"
    if tok.type == "NAME" and "EQUAL" in expected:
        return "is an `=` missing?"
    if tok.type == "NAME" and {"RBRACE"} & expected:
        return "a concept holds param, require, let, shape, part, link, joint, grasp and action"
    return None


def _blank_declaration(text: str, exc: UnexpectedInput) -> tuple[str, str | None] | None:
    """Blank the lines of the declaration that holds the error; None when recovery is hopeless."""
    if isinstance(exc, UnexpectedEOF) or getattr(getattr(exc, "token", None), "type", "") == "$END":
        return None
    tok = getattr(exc, "token", None)
    if tok is not None and tok.type == "RBRACE" and not _open_braces(text, tok.start_pos or 0):
        at = tok.start_pos or 0  # a stray `}`: drop just that character
        return text[:at] + " " + text[at + 1 :], None
    lines = text.split("\n")
    err = max(0, min(len(lines) - 1, _error_line(exc, text) - 1))
    start = err
    while start > 0 and not _starts_declaration(lines[start]):
        start -= 1
    end = err + 1
    while end < len(lines) and not _starts_declaration(lines[end]) and not _closes(lines[end]):
        end += 1
    words = lines[start].split()
    name = words[1].rstrip(":=({") if len(words) > 1 and words[0] in SYNC_KEYWORDS else None
    while start > 0 and lines[start - 1].strip().startswith("///"):
        start -= 1  # its doc comment goes too, or it would document nothing
    region = lines[start:end]
    joined = "\n".join(region)
    if joined.count("{") != joined.count("}") or not joined.strip():
        return None
    blanked = [" " * len(line) for line in region]
    return "\n".join(lines[:start] + blanked + lines[end:]), name


def _error_line(exc: UnexpectedInput, text: str) -> int:
    """The line of the broken declaration: the one before, when the error is at a fresh start."""
    prev = _unfinished_before(exc, text)
    return prev[0] if prev is not None else exc.line


def _open_braces(text: str, upto: int) -> list[int]:
    """Lines of the `{` still open at offset ``upto`` (strings and comments skipped)."""
    stack: list[int] = []
    line, i = 1, 0
    while i < upto:
        ch = text[i]
        if ch == "\n":
            line += 1
        elif ch == "/" and text.startswith("//", i):
            end = text.find("\n", i)
            i = upto if end < 0 else end
            continue
        elif ch == '"':
            end = text.find('"', i + 1)
            newline = text.find("\n", i + 1)
            i = end + 1 if end >= 0 and (newline < 0 or end < newline) else i + 1
            continue
        elif ch == "{":
            stack.append(line)
        elif ch == "}" and stack:
            stack.pop()
        i += 1
    return stack


def _stray_doc(exc: UnexpectedInput, text: str, path: str) -> tuple[Diagnostic, str] | None:
    """A ``///`` comment (or several) right before a ``}``: it documents nothing.  The
    diagnostic at the first comment line, and the text with those comments blanked out."""
    tok = getattr(exc, "token", None)
    if not isinstance(exc, UnexpectedToken) or tok is None or tok.type != "RBRACE":
        return None
    lines = text.split("\n")
    docs: list[int] = []
    for index in range((tok.line or 1) - 2, -1, -1):
        stripped = lines[index].strip()
        if stripped.startswith("///"):
            docs.append(index)
        elif stripped:
            break
    if not docs:
        return None
    first = docs[-1]
    col = lines[first].index("///") + 1
    span = ast.Span(path, first + 1, col, first + 1, len(lines[first]) + 1)
    for index in docs:
        start = lines[index].index("///")
        lines[index] = lines[index][:start] + " " * (len(lines[index]) - start)
    diag = error(
        "E002",
        "a `///` doc comment here documents nothing",
        span,
        "put it right before the declaration it describes, or use `//`",
    )
    return diag, "\n".join(lines)


def _unfinished_before(exc: UnexpectedInput, text: str) -> tuple[int, int] | None:
    """(line, column after) of the last code before the error, if the error is that the
    previous declaration never finished: the unexpected token starts a new declaration line."""
    tok = getattr(exc, "token", None)
    if tok is None or tok.value not in SYNC_KEYWORDS | {"}"} or not tok.line:
        return None
    lines = text.split("\n")
    if lines[tok.line - 1][: (tok.column or 1) - 1].strip():
        return None
    for number in range(tok.line - 1, 0, -1):
        code = lines[number - 1].split("//")[0].rstrip()
        if code:
            return number, len(code) + 1
    return None


def _starts_declaration(line: str) -> bool:
    words = line.split()
    return bool(words) and (words[0] in SYNC_KEYWORDS or words[0].startswith("///"))


def _closes(line: str) -> bool:
    return line.strip() == "}"
