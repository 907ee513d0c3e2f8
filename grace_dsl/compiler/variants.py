"""Variant pass: what a host reads, binds and uses of a variant part, made concrete.

Expand turns ``part handle = match kind { "bar" => ..., "knob" => ... }`` into one masked part per
option (``handle@bar``, ``handle@knob``), file by file.  This pass runs once every concept of the
program is known, and rewrites in each concept the three ways a host reaches into a variant part
by its plain name:

- **reads**: ``handle.standoff`` in an expression is the chosen option's parameter, compiled as
  ``if kind == "bar" then handle@bar.standoff else ...`` over the options that can be chosen
  there (an ``if kind == "bar"``, ``and`` or ``or`` around the read narrows them).  An option
  that may be chosen there without that parameter is E129.
- **pass-through arguments**: ``Drawer(handle.length: 120mm)`` binds ``length`` in every option
  of the drawer's variant ``handle`` that has it unbound (``handle@bar.length``); none is E116.
- **grasps**: an action's ``using drawer.handle.pull, drawer.handle.pinch`` lists the grasps of
  every option of the (nested) variant part; together they are the action's *grasp family* for
  that part.  Each option keeps the ones it has and must have at least one, unless the action
  also lists a grasp outside the variant part (a door's edge), which serves every option (E127).

Why a pass of its own: expand sees one file, and these rewrites need the option concepts'
parameters and grasps, which may live in other files.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import Any

from grace_dsl.compiler.expand import EXPR_FIELDS, VARIANT_SEP, facts_of
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, error

_EXPR_FIELDS = EXPR_FIELDS

Variants = dict[str, tuple[str, tuple[tuple[str, str], ...]]]  # part -> (choice, (option, alt))

_MAX_DEPTH = 8  # how deep parts nest before the pass stops looking (the library nests 3)


@dataclass(frozen=True)
class Scope:
    """What the pass needs of the program: a concept by name (None when unknown)."""

    concept: Callable[[str], ast.Concept | None]


def rewrite_concept(c: ast.Concept, scope: Scope) -> tuple[ast.Concept, list[Diagnostic]]:
    """``c`` with its reads, pass-through arguments and grasps of variant parts made concrete."""
    r = _Rewriter(c, scope)
    members = tuple(r.member(m) for m in c.members)
    return replace(c, members=members), r.diags


def uses_variants(c: ast.Concept, scope: Scope, depth: int = 0) -> bool:
    """Whether ``c`` or a concept it places, at any depth, has a variant part (else the pass
    leaves it): ``BoardCabinet(door.handle.standoff: 22mm)`` reaches the door's variant handle
    through a part that has none of its own."""
    if c.variants:
        return True
    if depth >= _MAX_DEPTH:  # a cycle of placements is resolve's error, not a reason to loop
        return False
    return any(
        isinstance(m, ast.Part)
        and (sub := scope.concept(m.concept)) is not None
        and uses_variants(sub, scope, depth + 1)
        for m in _flat(c.members)
    )


def _flat(members: Iterable[Any]) -> Iterable[Any]:
    for m in members:
        yield m
        if isinstance(m, ast.Link):
            yield from m.members


def _parts(c: ast.Concept) -> dict[str, ast.Part]:
    return {m.name: m for m in _flat(c.members) if isinstance(m, ast.Part)}


def _params(c: ast.Concept) -> set[str]:
    return {m.name for m in c.members if isinstance(m, ast.Param)}


class _Rewriter:
    def __init__(self, c: ast.Concept, scope: Scope):
        self.c = c
        self.scope = scope
        self.variants: Variants = dict(c.variants)
        self.parts = _parts(c)
        self.diags: list[Diagnostic] = []
        self.reported: set[tuple[str, ast.Span]] = set()

    def err(self, code: str, msg: str, span: ast.Span, hint: str | None = None) -> None:
        if (code, span) not in self.reported:  # copies of a loop share their source
            self.reported.add((code, span))
            self.diags.append(error(code, msg, span, hint))

    # ---- members --------------------------------------------------------------------------------
    def member(self, m: Any) -> Any:
        if isinstance(m, ast.Link):
            return replace(m, members=tuple(self.member(x) for x in m.members))
        changes: dict[str, Any] = {}
        for f in _EXPR_FIELDS:
            e = getattr(m, f, None)
            if e is not None:
                changes[f] = self.expr(e, ())
        if isinstance(m, ast.Part):
            args = tuple(replace(a, value=self.expr(a.value, ())) for a in m.args)
            changes["args"] = self.through(m, args)
        if isinstance(m, ast.Joint) and m.limits is not None:
            lim = m.limits
            changes["limits"] = replace(lim, lo=self.expr(lim.lo, ()), hi=self.expr(lim.hi, ()))
        if isinstance(m, ast.Grasp):
            changes["free"] = tuple(
                replace(
                    fp,
                    lo=self.expr(fp.lo, ()),
                    hi=self.expr(fp.hi, ()),
                    default=self.expr(fp.default, ()) if fp.default is not None else None,
                )
                for fp in m.free
            )
        if isinstance(m, ast.Action) and m.using:
            changes["using"] = self.family(m)
        return replace(m, **changes) if changes else m

    # ---- reads ----------------------------------------------------------------------------------
    def expr(self, e: ast.Expr, facts: tuple[tuple[str, int | str], ...]) -> ast.Expr:
        """``e`` with ``handle.x`` of a variant part made the chosen option's ``x``."""
        if isinstance(e, ast.Member) and isinstance(e.obj, ast.Name) and e.obj.id in self.variants:
            return self.read(e, facts)
        if isinstance(e, ast.IfExpr):
            cond = self.expr(e.cond, facts)
            then = self.expr(e.then, facts + _facts(e.cond, True))
            orelse = self.expr(e.orelse, facts + _facts(e.cond, False))
            return replace(e, cond=cond, then=then, orelse=orelse)
        if isinstance(e, ast.Binary) and e.op in ("and", "or"):
            left = self.expr(e.left, facts)
            right = self.expr(e.right, facts + _facts(e.left, e.op == "and"))
            return replace(e, left=left, right=right)
        kids = ast._children(e)
        new = [self.expr(k, facts) for k in kids]
        if all(a is b for a, b in zip(new, kids, strict=True)):
            return e
        return ast.rebuild(e, new)

    def read(self, e: ast.Member, facts: tuple[tuple[str, int | str], ...]) -> ast.Expr:
        assert isinstance(e.obj, ast.Name)
        name = e.obj.id
        choice, options = self.variants[name]
        chosen = {v for p, v in facts if p == choice}
        ruled_out = {v for p, v in facts if p == "!" + choice}
        possible = [
            (o, alt) for o, alt in options if (not chosen or o in chosen) and o not in ruled_out
        ]
        having = []
        for option, alt in possible:
            part = self.parts.get(alt)
            sub = self.scope.concept(part.concept) if part is not None else None
            if sub is None:
                return e  # an unknown concept: resolve reports it
            if e.field in _params(sub):
                having.append((option, alt))
            else:
                self.err(
                    "E129",
                    f'option "{option}" of part `{name}` ({sub.name}) has no parameter `{e.field}`',
                    e.span,
                    _read_hint(choice, name, e.field, sub, [o for o, _ in options if o != option]),
                )
        if not having:
            return e if not possible else ast.Number("0", None, e.span)
        out: ast.Expr = ast.Member(ast.Name(having[-1][1], e.obj.span), e.field, e.span)
        for option, alt in reversed(having[:-1]):
            test = ast.Binary("==", ast.Name(choice, e.span), ast.String(option, e.span), e.span)
            value = ast.Member(ast.Name(alt, e.obj.span), e.field, e.span)
            out = ast.IfExpr(test, value, out, e.span)
        return out

    # ---- pass-through arguments ---------------------------------------------------------------
    def through(self, m: ast.Part, args: tuple[ast.Arg, ...]) -> tuple[ast.Arg, ...]:
        target = self.scope.concept(m.concept)
        if target is None or not any(a.name and "." in a.name for a in args):
            return args
        out: list[ast.Arg] = []
        for a in args:
            if not a.name or "." not in a.name:
                out.append(a)
                continue
            names, variant = _bind(target, a.name, self.scope)
            if not variant:
                out.append(a)
            elif names:
                out += [replace(a, name=n) for n in names]
            else:
                head = a.name.split(".")[0]
                self.err(
                    "E116",
                    f"no option of the variant part `{variant}` in `{m.concept}` takes "
                    f"`{a.name.split('.')[-1]}` unbound",
                    a.span,
                    f"`{head}` is chosen by a choice; bind an option's own parameter as "
                    f"`{variant}{VARIANT_SEP}OPTION.{a.name.split('.')[-1]}`, or drop the argument",
                )
        return tuple(out)

    # ---- grasps ---------------------------------------------------------------------------------
    def family(self, a: ast.Action) -> tuple[str, ...]:
        """The action's grasps, each variant option keeping the ones it has (E127: none)."""
        kept: list[str] = []
        families: dict[str, dict[str, list[str]]] = {}  # variant path -> option -> grasps
        others = False  # a grasp outside every variant part: the action always has one
        for u in a.using:
            expanded = _expand_grasp(self.c, u, self.scope)
            if expanded is None:  # no variant on the way: resolve checks it
                kept.append(u)
                others = True
                continue
            for name, options in expanded:
                for path, option in options:
                    families.setdefault(path, {}).setdefault(option, [])
                if _grasp_exists(self.c, name, self.scope):
                    kept.append(name)
                    for path, option in options:
                        families[path][option].append(name)
        for path, by_option in families.items():
            for option, grasps in by_option.items():
                if grasps or others:
                    continue
                alt = f"{path}{VARIANT_SEP}{option}"
                sub = _part_concept(self.c, alt, self.scope)
                has = sorted(_grasps(sub, self.scope)) if sub is not None else []
                wanted = sorted({u.rsplit(".", 1)[-1] for u in a.using})
                self.err(
                    "E127",
                    f'option "{option}" of part `{path}`'
                    + (f" ({sub.name})" if sub is not None else "")
                    + f" has none of the grasps action `{a.name}` uses: "
                    + ", ".join(f"`{w}`" for w in wanted),
                    a.span,
                    (
                        f"{sub.name} has "
                        + (", ".join(f"`{x}`" for x in has) or "no grasps")
                        + "; list one of them in `using` too"
                    )
                    if sub is not None
                    else None,
                )
        return tuple(dict.fromkeys(kept))


def _facts(cond: ast.Expr, holds: bool) -> tuple[tuple[str, int | str], ...]:
    """What ``cond`` being ``holds`` says: expand's facts (``kind == "bar"``) and the options it
    rules out, as ``("!kind", "bar")`` (the ``else`` of ``if kind == "bar"``)."""
    out = facts_of(cond, holds)
    if isinstance(cond, ast.Unary) and cond.op == "not":
        return out + _ruled_out(cond.operand, not holds)
    return out + _ruled_out(cond, holds)


def _ruled_out(cond: ast.Expr, holds: bool) -> tuple[tuple[str, int | str], ...]:
    if isinstance(cond, ast.Binary) and cond.op in ("and", "or"):
        if (cond.op == "and") == holds:
            return _ruled_out(cond.left, holds) + _ruled_out(cond.right, holds)
        return ()
    if not (isinstance(cond, ast.Binary) and cond.op in ("==", "!=")):
        return ()
    left, right = cond.left, cond.right
    if isinstance(right, ast.Name):
        left, right = right, left
    if not (isinstance(left, ast.Name) and isinstance(right, ast.String)):
        return ()
    return (("!" + left.id, right.value),) if (cond.op == "==") != holds else ()


def _read_hint(choice: str, name: str, field: str, sub: ast.Concept, others: list[str]) -> str:
    guard = f'`if {choice} == "{others[0]}" then {name}.{field} else ...`' if others else ""
    has = ", ".join(f"`{p}`" for p in sorted(_params(sub))) or "no parameters"
    where = f"; read it only where another option is chosen: {guard}" if guard else ""
    return f"{sub.name} has {has}{where}"


def _bind(target: ast.Concept, dotted: str, scope: Scope) -> tuple[list[str], str | None]:
    """The concrete argument names ``dotted`` binds in ``target`` and the first variant part on
    the way (None: no variant, the argument is left as written)."""
    head, _, rest = dotted.partition(".")
    variants: Variants = dict(target.variants)
    parts = _parts(target)
    base, sep, _ = head.partition(VARIANT_SEP)
    if sep and base in variants:  # `handle["bar"].length`: that option only
        part = parts.get(head)
        sub = scope.concept(part.concept) if part is not None else None
        if part is None or sub is None:
            return [], base
        if "." in rest:
            inner, _ = _bind(sub, rest, scope)
            return [f"{head}.{n}" for n in inner], base
        free = rest in _params(sub) and all(x.name != rest for x in part.args)
        return ([dotted] if free else []), base
    if head in variants:
        names: list[str] = []
        for _, alt in variants[head][1]:
            part = parts.get(alt)
            sub = scope.concept(part.concept) if part is not None else None
            if part is None or sub is None:
                continue
            if "." in rest:
                inner, _ = _bind(sub, rest, scope)
                names += [f"{alt}.{n}" for n in inner]
            elif rest in _params(sub) and all(x.name != rest for x in part.args):
                names.append(f"{alt}.{rest}")
        return names, head
    part = parts.get(head)
    sub = scope.concept(part.concept) if part is not None else None
    if sub is None or "." not in rest:
        return [dotted], None
    inner, variant = _bind(sub, rest, scope)
    if variant is None:
        return [dotted], None
    return [f"{head}.{n}" for n in inner], f"{head}.{variant}"


def _expand_grasp(
    c: ast.Concept, dotted: str, scope: Scope, prefix: str = ""
) -> list[tuple[str, list[tuple[str, str]]]] | None:
    """``drawer.handle.pull`` -> every option's grasp, each with the (variant path, option)
    pairs it belongs to; None when no variant part lies on the way."""
    head, dot, rest = dotted.partition(".")
    if not dot:
        return None
    variants: Variants = dict(c.variants)
    parts = _parts(c)
    base, sep, option = head.partition(VARIANT_SEP)
    if sep and base in variants:  # already an option (expand wrote the host's own)
        steps = [(option, head)]
        base_name = base
    elif head in variants:
        steps = list(variants[head][1])
        base_name = head
    else:
        part = parts.get(head)
        sub = scope.concept(part.concept) if part is not None else None
        if sub is None:
            return None
        inner = _expand_grasp(sub, rest, scope, f"{prefix}{head}.")
        if inner is None:
            return None
        return [(f"{head}.{n}", opts) for n, opts in inner]
    out: list[tuple[str, list[tuple[str, str]]]] = []
    for opt, alt in steps:
        part = parts.get(alt)
        sub = scope.concept(part.concept) if part is not None else None
        inner = _expand_grasp(sub, rest, scope, f"{prefix}{alt}.") if sub is not None else None
        here = (prefix + base_name, opt)
        if inner is None:
            out.append((f"{alt}.{rest}", [here]))
        else:
            out += [(f"{alt}.{n}", [here, *opts]) for n, opts in inner]
    return out


def _grasp_exists(c: ast.Concept, dotted: str, scope: Scope) -> bool:
    head, _, rest = dotted.partition(".")
    for m in _flat(c.members):
        if not rest and isinstance(m, ast.Grasp) and m.name == head:
            return True
        if rest and isinstance(m, ast.Part) and m.name == head:
            sub = scope.concept(m.concept)
            return sub is not None and _grasp_exists(sub, rest, scope)
    return False


def _part_concept(c: ast.Concept, dotted: str, scope: Scope) -> ast.Concept | None:
    head, _, rest = dotted.partition(".")
    part = _parts(c).get(head)
    sub = scope.concept(part.concept) if part is not None else None
    if sub is None or not rest:
        return sub
    return _part_concept(sub, rest, scope)


def _grasps(c: ast.Concept, scope: Scope, prefix: str = "", depth: int = 0) -> list[str]:
    out: list[str] = []
    for m in _flat(c.members):
        if isinstance(m, ast.Grasp):
            out.append(prefix + m.name)
        elif isinstance(m, ast.Part) and depth < _MAX_DEPTH:
            sub = scope.concept(m.concept)
            if sub is not None:
                out += _grasps(sub, scope, f"{prefix}{m.name}.", depth + 1)
    return out


__all__ = ["Scope", "rewrite_concept", "uses_variants"]
