"""Expand pass: repeated declarations and variant parts -> plain declarations.

``for i in 0..n { link drawer[i] { ... } }`` is unrolled here, before any other pass sees the
concept, so resolve, check and lower only ever meet plain, uniquely named declarations
(``drawer[2]``) and the compiled functions stay static.  A loop bounded by an ``int`` parameter
is unrolled to the parameter's upper bound and every copy past the lower bound is *masked*: the
concept records that ``drawer[k]`` exists only when ``n > k`` (``ast.Concept.masks``), which the
manifest carries to the runtime.  A ``part handle = match kind { "bar" => ..., ... }`` whose
selector is a choice parameter becomes one masked part per option (``handle@bar``); the host's
``using handle.pull`` lists every option's grasp, and the runtime reads ``handle.pull`` as the
grasp of the option the instance has chosen.  A selector that unrolling makes constant (an
expression of the loop variable) simply picks its option.

Index expressions are integer arithmetic on literals and loop variables, evaluated here; no
source text is ever evaluated as Python.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import Any

from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, did_you_mean, error

MAX_NESTING = 2  # loops inside loops
MAX_COUNT = 64  # the largest upper bound of a count parameter
MAX_COPIES = 1024  # declarations of one concept after unrolling
VARIANT_SEP = "@"  # ``handle@bar``: the part that option "bar" of variant part ``handle`` places

Cond = tuple[tuple[str, int | str], ...]  # (count parameter, k): n > k; (choice, option): ==
_INDEXED = re.compile(r"^(.*?)((?:\[-?\d+\])+)$")

# the fields of a declaration that hold an expression
EXPR_FIELDS = (
    "value",
    "at",
    "cond",
    "pose",
    "width",
    "about",
    "when",
    "axis",
    "origin",
    "direction",
)


def expand(module: ast.Module) -> tuple[ast.Module, list[Diagnostic], frozenset[str]]:
    """Unroll every concept of a module; returns it, diagnostics, and names to stay quiet on."""
    diags: list[Diagnostic] = []
    quiet: set[str] = set()
    concepts = []
    for c in module.concepts:
        if not _needs_expansion(c):
            concepts.append(c)
            continue
        x = _Expander(c)
        concepts.append(x.run())
        diags += x.diags
        quiet |= x.quiet
    # the copies of a loop share their source: each problem there is reported once
    return replace(module, concepts=tuple(concepts)), list(dict.fromkeys(diags)), frozenset(quiet)


def split_indexed(name: str) -> tuple[str, tuple[int, ...]] | None:
    """``"drawer[2]"`` -> ``("drawer", (2,))``; None for a name without indices."""
    m = _INDEXED.match(name)
    if m is None:
        return None
    return m.group(1), tuple(int(k) for k in re.findall(r"-?\d+", m.group(2)))


def _needs_expansion(c: ast.Concept) -> bool:
    for m in _walk_members(c.members):
        if isinstance(m, ast.For) or (isinstance(m, ast.Part) and m.variants):
            return True
        if any(isinstance(n, ast.Index) for e in _exprs(m) for n in _nodes(e)):
            return True
        if ast.HOLE in getattr(m, "name", ""):
            return True
    return False


def _walk_members(members: Iterable[Any]) -> Iterator[Any]:
    for m in members:
        yield m
        if isinstance(m, (ast.Link, ast.For)):
            yield from _walk_members(m.members)


def _exprs(m: Any) -> list[ast.Expr]:
    out: list[Any] = []
    for f in EXPR_FIELDS:
        out.append(getattr(m, f, None))
    if isinstance(m, ast.Part):
        out += [a.value for a in m.args] + [m.selector]
    if isinstance(m, ast.Joint) and m.limits is not None:
        out += [m.limits.lo, m.limits.hi]
    if isinstance(m, ast.Grasp):
        out += [x for fp in m.free for x in (fp.lo, fp.hi, fp.default)]
    return [e for e in out if e is not None]


def _nodes(e: ast.Expr) -> Iterator[Any]:
    stack: list[Any] = [e]
    while stack:
        node = stack.pop()
        yield node
        stack += ast._children(node)


def const_int(e: ast.Expr, env: dict[str, int]) -> int | None:
    """The value of integer arithmetic on literals and loop variables, else None."""
    if isinstance(e, ast.Number):
        return int(e.text) if e.unit is None and e.text.isdigit() else None
    if isinstance(e, ast.Name):
        return env.get(e.id)
    if isinstance(e, ast.Unary) and e.op in "+-":
        v = const_int(e.operand, env)
        return None if v is None else (-v if e.op == "-" else v)
    if isinstance(e, ast.Binary) and e.op in ("+", "-", "*"):
        a, b = const_int(e.left, env), const_int(e.right, env)
        if a is None or b is None:
            return None
        return a + b if e.op == "+" else a - b if e.op == "-" else a * b
    return None


class _Expander:
    def __init__(self, c: ast.Concept):
        self.c = c
        self.diags: list[Diagnostic] = []
        self.quiet: set[str] = set()
        self.masks: dict[str, Cond] = {}
        self.variants: dict[str, tuple[str, tuple[tuple[str, str], ...]]] = {}
        self.params = {m.name: m for m in c.members if isinstance(m, ast.Param)}
        self.copies = 0
        self.in_loop: set[str] = set()  # names declared by a loop body
        # indexed names read, with the declaration reading them, to check their range
        self.refs: list[tuple[str, ast.Span, str]] = []
        self.current = ""  # the declaration being unrolled
        self.bad: set[str] = set()  # declarations with a bad index: dropped after reporting

    def err(self, code: str, msg: str, span: ast.Span, hint: str | None = None) -> None:
        self.diags.append(error(code, msg, span, hint))

    def run(self) -> ast.Concept:
        members = self._members(self.c.members, {}, (), 0)
        members = self._unique(members)
        members = [self._using_variants(m) for m in members]
        self._check_ranges(members)
        members = self._drop_bad(members)
        self._inherit(members)
        self._check_reads(members)
        masks = tuple(sorted(self.masks.items()))
        variants = tuple(sorted(self.variants.items()))
        return replace(self.c, members=tuple(members), masks=masks, variants=variants)

    # ---- members --------------------------------------------------------------------------------
    def _members(self, members: Iterable[Any], env: dict[str, int], cond: Cond, depth: int) -> list:
        out: list[Any] = []
        for m in members:
            if isinstance(m, ast.For):
                out += self._loop(m, env, cond, depth)
            elif isinstance(m, ast.Param) and depth:
                self.err(
                    "E114",
                    f"parameter `{m.name}` is declared inside a `for` loop",
                    m.name_span,
                    "declare parameters once, before the loop; a loop repeats parts, links, "
                    "joints, shapes, grasps, actions, lets and requirements",
                )
            else:
                out += self._member(m, env, cond, depth)
        return out

    def _loop(self, f: ast.For, env: dict[str, int], cond: Cond, depth: int) -> list[Any]:
        if depth >= MAX_NESTING:
            self.err(
                "E124",
                f"`for` loops nest at most {MAX_NESTING} deep",
                f.span,
                "combine two indices into one, or move the inner repetition into a part",
            )
            return []
        if f.var in self.params or f.var in env:
            self.err(
                "E123",
                f"the loop variable `{f.var}` hides "
                + ("a parameter" if f.var in self.params else "an outer loop's variable"),
                f.var_span,
                "give the loop variable its own name",
            )
            return []
        lo = const_int(f.lo, env)
        if lo is None:
            self.err(
                "E120",
                "a loop starts at an integer constant",
                f.lo.span,
                "write `for i in 0..n`",
            )
            return []
        bound = self._bound(f.hi, env)
        if bound is None:
            return []
        top, count, always = bound
        out: list[Any] = []
        for k in range(lo, top):
            masked = count is not None and k >= always
            inner = (*cond, (count, k)) if masked and count is not None else cond
            body = self._members(f.members, {**env, f.var: k}, inner, depth + 1)
            for m in _walk_members(body):
                if hasattr(m, "name") and not isinstance(m, ast.For):
                    self.in_loop.add(m.name)
            out += body
        return out

    def _bound(self, e: ast.Expr, env: dict[str, int]) -> tuple[int, str | None, int] | None:
        """(unroll up to, the count parameter or None, the count's smallest value)."""
        k = const_int(e, env)
        if k is not None:
            return k, None, k
        p = self.params.get(e.id) if isinstance(e, ast.Name) else None
        if p is None or p.type.name != "int" or p.type.unit or p.type.choices is not None:
            what = f"`{e.id}` is not an int parameter" if isinstance(e, ast.Name) else None
            kind = "" if p is None else f" (it is declared `{p.type.name}`)"
            self.err(
                "E120",
                (what or "a loop's bound is an int parameter or an integer constant") + kind,
                e.span,
                "bound the loop by a count: `param n : int in [1, 6] = 3` and `for i in 0..n`",
            )
            return None
        lo = const_int(p.bounds.lo, {}) if p.bounds is not None else None
        hi = const_int(p.bounds.hi, {}) if p.bounds is not None else None
        if lo is None or hi is None:
            self.err(
                "E121",
                f"the count `{p.name}` needs a range of integer constants to bound the loop",
                p.name_span if p.bounds is None else p.bounds.span,
                f"write `param {p.name} : int in [1, 6] = 3`",
            )
            return None
        if hi > MAX_COUNT or lo < 0:
            self.err(
                "E121",
                f"the count `{p.name}` ranges over [{lo}, {hi}]; a loop repeats 0 to "
                f"{MAX_COUNT} times",
                p.bounds.span if p.bounds is not None else p.name_span,
                "narrow the range to what the object can have",
            )
            return None
        return hi, p.name, lo

    def _member(self, m: Any, env: dict[str, int], cond: Cond, depth: int) -> list[Any]:
        self.copies += 1
        if self.copies > MAX_COPIES:
            if self.copies == MAX_COPIES + 1:
                self.err(
                    "E124",
                    f"`{self.c.name}` unrolls to more than {MAX_COPIES} declarations",
                    m.span,
                    "narrow the counts' ranges or move repeated members into a part",
                )
            return []
        if isinstance(m, ast.Require):  # a copy's requirement holds only when it exists
            return [replace(m, cond=_when(cond, self._x(m.cond, env)))]
        if isinstance(m, ast.Param):
            return [m]
        name = self._name(m.name, m.index, env, m.name_span)
        self.current = name
        if cond:
            self.masks[name] = cond
        doc = m.doc
        for var, k in env.items():  # `/// drawer {i}` says which copy it documents
            doc = doc.replace("{" + var + "}", str(k))
        m = replace(m, doc=doc) if doc != m.doc else m
        if isinstance(m, ast.Link):
            members = self._members(m.members, env, cond, depth)
            return [replace(m, name=name, index=(), members=tuple(members))]
        if isinstance(m, ast.Part) and m.variants:
            return self._variant(m, name, env, cond)
        changes: dict[str, Any] = {"name": name, "index": ()}
        for f in EXPR_FIELDS:
            if getattr(m, f, None) is not None:
                changes[f] = self._x(getattr(m, f), env)
        if isinstance(m, ast.Part):
            changes["args"] = tuple(replace(a, value=self._x(a.value, env)) for a in m.args)
        if isinstance(m, ast.Joint):
            changes["parent"] = self._ref(m.parent, m.parent_index, env, m.parent_span)
            changes["child"] = self._ref(m.child, m.child_index, env, m.child_span)
            changes["parent_index"] = changes["child_index"] = ()
            if m.limits is not None:
                lim = m.limits
                changes["limits"] = replace(lim, lo=self._x(lim.lo, env), hi=self._x(lim.hi, env))
        if isinstance(m, ast.Grasp):
            changes["free"] = tuple(
                replace(
                    fp,
                    lo=self._x(fp.lo, env),
                    hi=self._x(fp.hi, env),
                    default=self._x(fp.default, env) if fp.default is not None else None,
                )
                for fp in m.free
            )
        if isinstance(m, ast.Action):
            if m.joint is not None:
                changes["joint"] = self._ref(m.joint, m.joint_index, env, m.joint_span)
            ixs = m.using_index or tuple(() for _ in m.using)
            changes["using"] = tuple(
                self._ref(u, ix, env, m.span) for u, ix in zip(m.using, ixs, strict=True)
            )
            changes["joint_index"], changes["using_index"] = (), ()
        return [replace(m, **changes)]

    def _variant(self, m: ast.Part, name: str, env: dict[str, int], cond: Cond) -> list[Any]:
        assert m.selector is not None
        selector = self._fold(self._x(m.selector, env))
        options = [v.value for v in m.variants]
        for i, v in enumerate(m.variants):
            if v.value in options[:i]:
                self.err("E126", f'option "{v.value}" appears twice', v.span, "keep one")
        at = self._x(m.at, env) if m.at is not None else None

        def part(v: ast.Variant, part_name: str) -> ast.Part:
            args = tuple(replace(a, value=self._x(a.value, env)) for a in v.args)
            return replace(
                m,
                name=part_name,
                concept=v.concept,
                args=args,
                at=_mount(at, self._x(v.at, env), name, part_name) if v.at is not None else at,
                index=(),
                concept_span=v.concept_span,
                selector=None,
                variants=(),
            )

        if isinstance(selector, ast.String):
            chosen = next((v for v in m.variants if v.value == selector.value), None)
            if chosen is None:
                self.err(
                    "E126",
                    f'no option "{selector.value}" in the `match` of part `{name}`',
                    selector.span,
                    did_you_mean(selector.value, options) or "options: " + ", ".join(options),
                )
                self.quiet.add(name)
                return []
            return [part(chosen, name)]
        p = self.params.get(selector.id) if isinstance(selector, ast.Name) else None
        if p is None or p.type.choices is None:
            self.err(
                "E126",
                "a variant part is chosen by a choice parameter, or by an expression of the "
                "loop variable that picks one option",
                m.selector.span,
                'declare `param kind : choice{"bar", "knob"} = "bar"` and write `match kind`',
            )
            self.quiet.add(name)
            return []
        missing = [c for c in p.type.choices if c not in options]
        extra = [v for v in m.variants if v.value not in p.type.choices]
        for v in extra:
            self.err(
                "E126",
                f'"{v.value}" is not an option of `{p.name}`',
                v.span,
                did_you_mean(v.value, p.type.choices) or "options: " + ", ".join(p.type.choices),
            )
        if missing:
            self.err(
                "E126",
                f"part `{name}` has no alternative for "
                + ", ".join(f'"{c}"' for c in missing)
                + f" of `{p.name}`",
                m.selector.span,
                "every option of the choice needs an alternative",
            )
        if extra or missing:
            self.quiet.add(name)
            return []
        out = []
        for v in m.variants:
            alt = f"{name}{VARIANT_SEP}{v.value}"
            self.masks[alt] = (*cond, (p.name, v.value))
            out.append(replace(part(v, alt), variant=(name, v.value)))
        self.variants[name] = (
            p.name,
            tuple((v.value, f"{name}{VARIANT_SEP}{v.value}") for v in m.variants),
        )
        return out

    def _fold(self, e: ast.Expr) -> ast.Expr:
        """``if 0 == 0 then "knob" else "bar"`` -> ``"knob"``: a selector made constant."""
        while isinstance(e, ast.IfExpr):
            c = e.cond
            if not (isinstance(c, ast.Binary) and c.op in ast.COMPARISONS):
                return e
            a, b = const_int(c.left, {}), const_int(c.right, {})
            if a is None or b is None:
                return e
            ops = {
                "<": a < b,
                "<=": a <= b,
                ">": a > b,
                ">=": a >= b,
                "==": a == b,
                "!=": a != b,
            }
            e = e.then if ops[c.op] else e.orelse
        return e

    def _using_variants(self, m: Any) -> Any:
        """``using handle.pull`` with ``handle`` a variant part: every option's grasp."""
        if isinstance(m, ast.Link):
            return m
        if not isinstance(m, ast.Action) or not self.variants:
            return m
        using: list[str] = []
        for u in m.using:
            head, dot, rest = u.partition(".")
            if dot and head in self.variants:
                using += [f"{alt}.{rest}" for _, alt in self.variants[head][1]]
            else:
                using.append(u)
        return replace(m, using=tuple(using))

    # ---- names and expressions ----------------------------------------------------------------
    def _name(self, template: str, index: ast.Indices, env: dict[str, int], span: ast.Span) -> str:
        values = []
        for e in index:
            k = const_int(self._x(e, env), env)
            if k is None:
                self.err(
                    "E125",
                    "an index is an integer: a constant or arithmetic on loop variables",
                    e.span,
                    "write `drawer[i]`, `drawer[i + 1]` or `drawer[2]`",
                )
                k = 0
            values.append(str(k))
        return ast.fill(template, values)

    def _ref(self, template: str, index: ast.Indices, env: dict[str, int], span: ast.Span) -> str:
        name = self._name(template, index, env, span)
        if index:
            self.refs.append((name.split(".")[0], span, self.current))
        return name

    def _x(self, e: ast.Expr, env: dict[str, int]) -> ast.Expr:
        """An expression with loop variables replaced by their values and indices resolved."""
        if isinstance(e, ast.Name):
            if e.id in env:
                k = env[e.id]
                num = ast.Number(str(abs(k)), None, e.span)
                return num if k >= 0 else ast.Unary("-", num, e.span)
            return e
        if isinstance(e, ast.Index) and isinstance(e.index, ast.String):
            obj = self._x(e.obj, env)  # `handle["bar"]`: option "bar" of variant part `handle`
            if isinstance(obj, ast.Name):
                return ast.Name(f"{obj.id}{VARIANT_SEP}{e.index.value}", e.span)
        if isinstance(e, ast.Index):
            obj = self._x(e.obj, env)
            at = const_int(self._x(e.index, env), env)
            if at is None:
                self.err(
                    "E125",
                    "an index is an integer: a constant or arithmetic on loop variables",
                    e.index.span,
                    "write `drawer[i]`, `drawer[i + 1]` or `drawer[2]`",
                )
            elif isinstance(obj, ast.Name):
                name = f"{obj.id}[{at}]"
                self.refs.append((name, e.span, self.current))
                return ast.Name(name, e.span)
            elif isinstance(obj, ast.Member):
                return ast.Member(obj.obj, f"{obj.field}[{at}]", e.span)
            else:
                self.err(
                    "E125",
                    "only the name of a repeated declaration takes an index",
                    e.span,
                    "index a name: `drawer[i]`, `drawer[i].width`",
                )
            self.bad.add(self.current)
            return ast.Name("[]", e.span)
        kids = ast._children(e)
        if not kids:
            return e
        new = [self._x(k, env) for k in kids]
        if all(a is b for a, b in zip(new, kids, strict=True)):
            return e
        if isinstance(e, ast.Unary):
            return replace(e, operand=new[0])
        if isinstance(e, ast.Binary):
            return replace(e, left=new[0], right=new[1])
        if isinstance(e, ast.Call):
            args = tuple(replace(a, value=v) for a, v in zip(e.args, new, strict=True))
            return replace(e, args=args)
        if isinstance(e, ast.Vector):
            return replace(e, items=tuple(new))
        if isinstance(e, ast.Member):
            return replace(e, obj=new[0])
        if isinstance(e, ast.IfExpr):  # `if i == 0 then ...`: one branch per copy
            return self._fold(replace(e, cond=new[0], then=new[1], orelse=new[2]))
        return e

    # ---- after unrolling ------------------------------------------------------------------------
    def _unique(self, members: list[Any]) -> list[Any]:
        """Copies of a declaration without an index share its name: report once, keep one."""
        seen: set[str] = set()
        reported: set[str] = set()

        def keep(m: Any) -> bool:
            name = getattr(m, "name", None)
            if name is None or isinstance(m, ast.Param):
                return True
            if name in seen and name in self.in_loop:
                if name not in reported:
                    reported.add(name)
                    self.err(
                        "E123",
                        f"every copy of `{name}` made by a `for` loop has the same name",
                        m.name_span,
                        f"give it the loop's index: `{name}[i]`",
                    )
                return False
            seen.add(name)
            return True

        out = []
        for m in members:
            if not keep(m):
                continue
            if isinstance(m, ast.Link):
                m = replace(m, members=tuple(x for x in m.members if keep(x)))
            out.append(m)
        return out

    def _check_ranges(self, members: list[Any]) -> None:
        declared = {m.name for m in _walk_members(members) if hasattr(m, "name")}
        declared |= set(self.variants)
        arrays: dict[str, set[tuple[int, ...]]] = {}
        for name in declared:
            split = split_indexed(name.split(VARIANT_SEP)[0])
            if split is not None:
                arrays.setdefault(split[0], set()).add(split[1])
        reported: set[tuple[str, ast.Span]] = set()
        for name, span, owner in self.refs:
            split = split_indexed(name)
            if name in declared or split is None:
                continue
            base, _ = split
            if base in arrays or base in declared:
                self.bad.add(owner)
            if (name, span) in reported:
                continue
            reported.add((name, span))
            if base not in arrays:
                if base in declared:
                    self.err(
                        "E125",
                        f"`{base}` is not repeated: it takes no index",
                        span,
                        f"write `{base}`",
                    )
                continue  # an unknown name: resolve and check report it
            self.err(
                "E122",
                f"`{name}` is out of range: `{base}` has indices {_ranges(arrays[base])}",
                span,
                "indices start at the loop's start and stop before its bound",
            )

    def _inherit(self, members: list[Any]) -> None:
        """Declarations outside a loop that hang on a masked copy share its mask: a joint on
        ``drawer[3]``, the link below that joint and what the link holds, an action along it."""
        masks = self.masks

        def join(name: str, *sources: str) -> bool:
            cond = list(masks.get(name, ()))
            for src in sources:
                cond += [c for c in masks.get(src, ()) if c not in cond]
            if tuple(cond) != masks.get(name, ()):
                masks[name] = tuple(cond)
                return True
            return False

        joints = [m for m in members if isinstance(m, ast.Joint)]
        links = {m.name: m for m in members if isinstance(m, ast.Link)}
        changed = bool(masks)
        while changed:
            changed = False
            for j in joints:
                changed |= join(j.name, j.parent, j.child)
                changed |= join(j.child, j.name) if j.child in links else False
        for link in links.values():
            for m in _walk_members(link.members):
                if hasattr(m, "name") and link.name in masks:
                    join(m.name, link.name)
        for a in members:
            if isinstance(a, ast.Action) and a.joint is not None:
                join(a.name, a.joint.split(".")[0])

    def _check_reads(self, members: list[Any]) -> None:
        """E128 where a declaration reads a copy that may be absent when it is present.

        Why a diagnostic and not a mask: every copy is compiled, so an absent copy's values
        still evaluate, and a `let total = w[0] + w[2]` outside the loop would silently add a
        drawer the instance does not have.  Masking `total` in turn would make whatever reads
        it vanish with the copy.  The reader says what it means instead: it lives in the same
        loop (its own mask then covers the copy), or it guards the read with the count
        (`if n > 2 then w[2] else 0mm`)."""
        if not self.masks:
            return
        reported: set[ast.Span] = set()  # the copies of a loop share their source: once
        for m in _walk_members(members):
            if isinstance(m, ast.For):
                continue
            owner = self.masks.get(getattr(m, "name", ""), ())
            for e in _exprs(m):
                for ref, span, facts in _reads(e, owner):
                    need = self.masks.get(ref) or self.masks.get(ref.split(".")[0], ())
                    missing = [c for c in need if not _implied(c, facts)]
                    if not missing or span in reported:
                        continue
                    reported.add(span)
                    what = f"`{m.name}`" if hasattr(m, "name") else "this requirement"
                    when = " and ".join(_show(c) for c in missing)
                    self.err(
                        "E128",
                        f"{what} reads `{ref}`, which exists only when {when}",
                        span,
                        "read it inside the loop that makes it, or guard the read with the count: "
                        f"`if {_show(missing[0])} then {ref} else ...`",
                    )

    def _drop_bad(self, members: list[Any]) -> list[Any]:
        """Declarations with a bad index go, like a syntax error's: no follow-on errors."""
        if not self.bad:
            return members
        self.quiet |= self.bad
        out = []
        for m in members:
            if getattr(m, "name", None) in self.bad:
                continue
            if isinstance(m, ast.Link):
                kept = tuple(x for x in m.members if getattr(x, "name", None) not in self.bad)
                m = replace(m, members=kept)
            out.append(m)
        return out


def _mount(shared: ast.Expr | None, own: ast.Expr, name: str, alt: str) -> ast.Expr:
    """An option's pose: the shared mounting frame, then the option's own ``at``, in which the
    part's name (``handle.stem``) reads this option's members (``handle@knob.stem``)."""
    own = rename_part(own, name, alt)
    return own if shared is None else ast.Binary("*", shared, own, own.span)


def rename_part(e: ast.Expr, name: str, alt: str) -> ast.Expr:
    """``e`` with every read of part ``name``'s members (``name.x``) made a read of ``alt``'s."""
    if isinstance(e, ast.Member) and isinstance(e.obj, ast.Name) and e.obj.id == name:
        return replace(e, obj=ast.Name(alt, e.obj.span))
    kids = ast._children(e)
    new = [rename_part(k, name, alt) for k in kids]
    if all(a is b for a, b in zip(new, kids, strict=True)):
        return e
    return ast.rebuild(e, new)


def _when(cond: Cond, e: ast.Expr) -> ast.Expr:
    """``e`` as a requirement of a masked copy: true when the copy is absent."""
    for param, k in reversed(cond):
        if not param:
            continue
        name = ast.Name(param, e.span)
        absent = (
            ast.Binary("!=", name, ast.String(k, e.span), e.span)
            if isinstance(k, str)
            else ast.Binary("<=", name, ast.Number(str(k), None, e.span), e.span)
        )
        e = ast.Binary("or", absent, e, e.span)
    return e


_Fact = tuple[str, int | str]  # as in Cond: (count, k) says count > k; (choice, option) ==


def _reads(
    e: ast.Expr, facts: Iterable[_Fact]
) -> Iterator[tuple[str, ast.Span, tuple[_Fact, ...]]]:
    """Every name ``e`` reads, with what the ``if``/``and``/``or`` around it establish."""
    known = tuple(facts)
    if isinstance(e, ast.Name):
        yield e.id, e.span, known
    elif isinstance(e, ast.Member) and isinstance(e.obj, ast.Name):
        yield f"{e.obj.id}.{e.field}", e.span, known
    elif isinstance(e, ast.IfExpr):
        yield from _reads(e.cond, known)
        yield from _reads(e.then, known + _facts(e.cond, True))
        yield from _reads(e.orelse, known + _facts(e.cond, False))
    elif isinstance(e, ast.Binary) and e.op in ("and", "or"):
        yield from _reads(e.left, known)
        yield from _reads(e.right, known + _facts(e.left, e.op == "and"))
    else:
        for kid in ast._children(e):
            yield from _reads(kid, known)


def _facts(cond: ast.Expr, holds: bool) -> tuple[_Fact, ...]:
    """What ``cond`` being ``holds`` says about counts (n > k) and choices (kind == "bar")."""
    if isinstance(cond, ast.Unary) and cond.op == "not":
        return _facts(cond.operand, not holds)
    if isinstance(cond, ast.Binary) and cond.op in ("and", "or"):
        if (cond.op == "and") == holds:  # both sides are known
            return _facts(cond.left, holds) + _facts(cond.right, holds)
        return ()
    if not (isinstance(cond, ast.Binary) and cond.op in ast.COMPARISONS):
        return ()
    op, left, right = cond.op, cond.left, cond.right
    if not isinstance(left, ast.Name):  # `2 < n` as `n > 2`
        flip = {"<": ">", ">": "<", "<=": ">=", ">=": "<=", "==": "==", "!=": "!="}
        op, left, right = flip[op], right, left
    if not isinstance(left, ast.Name):
        return ()
    if not holds:
        op = {"<": ">=", ">": "<=", "<=": ">", ">=": "<", "==": "!=", "!=": "=="}[op]
    if isinstance(right, ast.String):
        return ((left.id, right.value),) if op == "==" else ()
    k = const_int(right, {})
    if k is None:
        return ()
    return {">": ((left.id, k),), ">=": ((left.id, k - 1),)}.get(op, ())


def facts_of(cond: ast.Expr, holds: bool) -> tuple[_Fact, ...]:
    """What ``cond`` being ``holds`` says about counts and choices (for later passes)."""
    return _facts(cond, holds)


def _implied(need: _Fact, facts: Iterable[_Fact]) -> bool:
    param, k = need
    if not param:  # a count or choice the host binds: the host's own masks decide
        return True
    for p, v in facts:
        if p != param:
            continue
        if isinstance(k, str) and v == k:
            return True
        if isinstance(k, int) and isinstance(v, int) and v >= k:
            return True
    return False


def _show(c: _Fact) -> str:
    param, k = c
    return f'{param} == "{k}"' if isinstance(k, str) else f"{param} > {k}"


def _ranges(indices: set[tuple[int, ...]]) -> str:
    if all(len(ix) == 1 for ix in indices):
        ks = sorted(ix[0] for ix in indices)
        if ks == list(range(ks[0], ks[-1] + 1)):
            return f"{ks[0]} to {ks[-1]}"
        return ", ".join(map(str, ks))
    return ", ".join("".join(f"[{k}]" for k in ix) for ix in sorted(indices))
