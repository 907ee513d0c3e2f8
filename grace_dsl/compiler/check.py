"""Check pass: types and units, then values at the defaults (``values.py``).

Every expression gets a type (recorded in a table keyed by node identity for lowering).  Unit
rules live in ``types.py``; a concept that type-checks is then evaluated at its defaults.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from grace_dsl.compiler import types as T
from grace_dsl.compiler.cues import CUE_TYPES, has_cue
from grace_dsl.compiler.evaluate import BUILTINS, dotted
from grace_dsl.compiler.intervals import check_intervals
from grace_dsl.compiler.resolve import Program, flat_members
from grace_dsl.compiler.types import ANGLE, LENGTH, SCALAR, Dim, Type
from grace_dsl.compiler.values import SET_OPS, check_values
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, did_you_mean, error, has_errors

ERR = Type("error")
JOINT_KINDS = ("revolute", "prismatic", "continuous", "fixed")
# How the hand touches the part: pinch closes the fingers on it; hook slides the closed fingers
# behind it and pulls; push and press lean the closed fingertips against a face or a button.
GRASP_MODES = ("pinch", "hook", "push", "press")
VERBS = {  # verb -> default sense along a joint
    "pull": "opening",
    "push": "closing",
    "lift": "opening",
    "lower": "closing",
    "press": "closing",
    "turn": "opening",
    "rotate": "opening",
    "slide": "opening",
    "open": "opening",
    "close": "closing",
}


@dataclass(frozen=True)
class TE:
    """A typed expression: its type and, for unit-less literal arithmetic, its constant value."""

    type: Type
    const: Any = None  # float or tuple of floats; None when not a bare constant


@dataclass
class CheckedConcept:
    decl: ast.Concept
    file: str
    param_types: dict[str, Type]
    free_types: dict[str, dict[str, Type]]
    defaults: dict[str, Any] = field(default_factory=dict)  # SI values at the defaults
    bounds: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    ok: bool = True


@dataclass
class Checked:
    program: Program
    types: dict[int, Type]
    concepts: dict[str, CheckedConcept]


def check(prog: Program) -> tuple[Checked, list[Diagnostic]]:
    """Type-check every concept of the program and evaluate it at its defaults."""
    types: dict[int, Type] = {}
    diags: list[Diagnostic] = []
    concepts: dict[str, CheckedConcept] = {}
    for name in _parts_first(prog):
        entry = prog.concepts[name]
        checker = _ConceptChecker(prog, entry.decl, entry.file, types, concepts)
        concepts[name] = checker.run()
        diags += checker.diags
    # the copies a `for` loop made share their source: each problem there is reported once
    return Checked(prog, types, concepts), list(dict.fromkeys(diags))


def _parts_first(prog: Program) -> list[str]:
    """Concept names ordered so that every part's concept and primitive comes before its host."""
    order: list[str] = []
    seen: set[str] = set()

    def visit(name: str) -> None:
        if name in seen or name not in prog.concepts:
            return
        seen.add(name)
        for m in flat_members(prog.concept(name)):
            if isinstance(m, ast.Part):
                visit(m.concept)
            elif isinstance(m, ast.Shape) and isinstance(m.value, ast.Call):
                visit(m.value.func)  # a primitive
        order.append(name)

    for name in prog.concepts:
        visit(name)
    return order


class _ConceptChecker:
    def __init__(
        self,
        prog: Program,
        decl: ast.Concept,
        file: str,
        types: dict[int, Type],
        done: dict[str, CheckedConcept],
    ):
        self.prog, self.decl, self.file, self.types = prog, decl, file, types
        self.done = done  # concepts checked before this one: every part's concept
        self.diags: list[Diagnostic] = []
        self.dropped = prog.dropped(file)
        self.members = {getattr(m, "name", None): m for m in flat_members(decl)}
        self.params = {m.name: m for m in decl.members if isinstance(m, ast.Param)}
        self.param_types = {n: self._param_type(p) for n, p in self.params.items()}
        self.lets = {m.name: m for m in flat_members(decl) if isinstance(m, ast.Let)}
        self.let_types: dict[str, Type] = {}
        self.visiting: list[str] = []
        self.scope: dict[str, Type] = {}  # free grasp parameters while checking a grasp
        self.shape_names: set[str] = set()
        self.free_types: dict[str, dict[str, Type]] = {}
        self.incomplete = False  # set when a name refers to a declaration dropped by the parser
        self.free_names: set[str] = set()  # a grasp's free parameters while checking its ranges

    def err(self, code: str, msg: str, span: ast.Span, hint: str | None = None) -> None:
        self.diags.append(error(code, msg, span, hint))

    # ---- driver ---------------------------------------------------------------------------------
    def run(self) -> CheckedConcept:
        for m in self.decl.members:
            self._member(m)
        result = CheckedConcept(self.decl, self.file, self.param_types, self.free_types)
        result.ok = not has_errors(self.diags) and not self.incomplete
        if result.ok:
            self.diags += check_values(result, self.done, self.types)
            result.ok = not has_errors(self.diags)
        if result.ok:
            self.diags += check_intervals(result, self.done, self.types)
        return result

    def _member(self, m: ast.Member_) -> None:
        if isinstance(m, ast.Param):
            self._param(m)
        elif isinstance(m, ast.Require):
            self._expect_bool(self.expr(m.cond), m.cond.span)
        elif isinstance(m, ast.Let):
            self._let_type(m.name)
        elif isinstance(m, ast.Shape):
            self._shape(m)
        elif isinstance(m, ast.Part):
            self._part(m)
        elif isinstance(m, ast.Link):
            for sub in m.members:
                self._member(sub)
        elif isinstance(m, ast.Joint):
            self._joint(m)
        elif isinstance(m, ast.Grasp):
            self._grasp(m)
        elif isinstance(m, ast.Action):
            self._action(m)

    # ---- parameters -----------------------------------------------------------------------------
    def _param_type(self, p: ast.Param) -> Type:
        ref = p.type
        if ref.choices is not None and len(set(ref.choices)) != len(ref.choices):
            self.err("E202", "a choice lists the same option twice", ref.span)
        t = declared_type(ref)
        if t is None:
            shown = ref.name + (f" {ref.unit}" if ref.unit else "")
            hint = did_you_mean(ref.name, T.TYPE_NAMES) or "types: " + ", ".join(T.TYPE_NAMES)
            if ref.name in T.VECTOR_TYPES:
                hint = "a vector's unit is length, angle or scalar: `vec3 length`"
            self.err("E201", f"unknown type `{shown}`", ref.span, hint)
            return ERR
        return t

    def _param(self, p: ast.Param) -> None:
        t = self.param_types[p.name]
        if p.bounds is not None:
            if t.kind in ("bool", "choice"):
                self.err("E202", f"a {t.kind} parameter takes no range", p.bounds.span)
            else:
                for bound in (p.bounds.lo, p.bounds.hi):
                    self._constant(bound, "a parameter's bound")
                    self.coerce(self.expr(bound), t, bound.span)
        if p.default is not None:
            self._constant(p.default, "a parameter's default")
            self.coerce(self.expr(p.default), t, p.default.span)
        elif p.bounds is None and t.kind != "choice":
            self.err(
                "E222",
                f"parameter `{p.name}` has neither a default nor a range",
                p.name_span,
                "add `= true` or `= false`"
                if t.kind == "bool"
                else "add `= value` or `in [lo, hi]` (the default is then the middle)",
            )
        elif t.kind == "choice" and p.default is None:
            self.err(
                "E222",
                f"choice parameter `{p.name}` needs a default",
                p.name_span,
                f'add `= "{t.choices[0]}"`',
            )

    def _constant(self, e: ast.Expr, what: str) -> None:
        for n in ast.names_in(e):
            if n.id in self.param_types or n.id in self.lets:
                self.err(
                    "E207",
                    f"{what} must be a constant, but it uses `{n.id}`",
                    n.span,
                    "ranges and defaults of parameters are fixed numbers; relate "
                    "parameters with `require`",
                )
                return

    # ---- declarations ---------------------------------------------------------------------------
    def _let_type(self, name: str) -> Type:
        if name in self.let_types:
            return self.let_types[name]
        if not self.visiting:  # type what it reads first: no recursion along a chain of lets
            for dep in self._lets_first(name)[:-1]:
                self._type_let(dep)
        return self._type_let(name)

    def _lets_first(self, name: str) -> list[str]:
        """``name`` and the untyped lets it reads, dependencies first (iterative).  On a cycle
        just ``[name]``: ``_type_let`` then walks to it and reports it from ``name``."""
        order: list[str] = []
        seen, path = {name}, {name}
        stack = [(name, iter(ast.names_in(self.lets[name].value)))]
        while stack:
            node, reads = stack[-1]
            for n in reads:
                dep = n.id
                if dep in path:
                    return [name]
                if dep in self.lets and dep not in seen and dep not in self.let_types:
                    seen.add(dep)
                    path.add(dep)
                    stack.append((dep, iter(ast.names_in(self.lets[dep].value))))
                    break
            else:
                stack.pop()
                path.discard(node)
                order.append(node)
        return order

    def _type_let(self, name: str) -> Type:
        if name in self.let_types:
            return self.let_types[name]
        let = self.lets[name]
        if name in self.visiting:
            cycle = " -> ".join([*self.visiting[self.visiting.index(name) :], name])
            self.err("E119", f"`{name}` is defined in terms of itself: {cycle}", let.name_span)
            self.let_types[name] = ERR
            return ERR
        self.visiting.append(name)
        saved, self.scope = self.scope, {}
        t = self.expr(let.value).type
        if t.kind == "string":
            self.err(
                "E227",
                "a string can only be a choice's value",
                let.value.span,
                "declare a `choice{...}` parameter and compare it with its options",
            )
            t = ERR
        self.scope = saved
        self.visiting.pop()
        self.let_types[name] = t
        return t

    def _shape(self, s: ast.Shape) -> None:
        v = s.value
        if isinstance(v, ast.Call) and v.func in SET_OPS:
            if len(v.args) < 2:
                self.err("E205", f"`{v.func}` takes two or more shapes", v.span)
            for a in v.args:
                if not (isinstance(a.value, ast.Name) and a.value.id in self.shape_names):
                    self.err(
                        "E223",
                        f"`{v.func}` combines shapes declared above",
                        a.value.span,
                        did_you_mean(getattr(a.value, "id", ""), self.shape_names),
                    )
                self.types[id(a.value)] = T.SHAPE
        elif isinstance(v, ast.Call) and self._primitive(v.func) is not None:
            prim = self._primitive(v.func)
            assert prim is not None
            self._named_args(v.args, prim, v.func_span, "primitive")
        elif isinstance(v, ast.Call) and (v.func in self.dropped or "*" in self.dropped):
            self.incomplete = True  # its import failed and was reported
        else:
            func = v.func if isinstance(v, ast.Call) else None
            prims = [
                n
                for n, f in self.prog.visible.get(self.file, {}).items()
                if self.prog.concepts[n].decl.kind == "primitive"
            ]
            hint = did_you_mean(func, prims) if func else None
            entry = self.prog.concepts.get(func) if func else None
            if entry is not None and entry.decl.kind == "primitive":
                module = Path(entry.file).stem
                hint = f"import it: `use {module}.{{{func}}}`"
            elif entry is not None:
                hint = f"`{func}` is a concept: place it with `part {s.name} = {func}(...)`"
            self.err(
                "E223",
                "a shape is a primitive such as `Cuboid(size: ...)`, or "
                "`union(a, b)` / `difference(a, b)` of shapes",
                v.span,
                hint or "import primitives with `use primitives.{...}`",
            )
        if s.at is not None:
            self._expect_pose(s.at)
        self.shape_names.add(s.name)

    def _primitive(self, name: str) -> ast.Concept | None:
        file = self.prog.visible.get(self.file, {}).get(name)
        if file is None:
            return None
        decl = self.prog.concepts[name].decl
        return decl if decl.kind == "primitive" else None

    def _part(self, p: ast.Part) -> None:
        entry = self.prog.concepts.get(p.concept)
        if entry is not None and entry.decl.kind == "primitive":
            self.err(
                "E114",
                f"`{p.concept}` is a primitive: place it with `shape`, not `part`",
                p.concept_span,
                f"shape {p.name} = {p.concept}(...)",
            )
            return
        if entry is not None and p.concept in self.prog.visible.get(self.file, {}):
            self._named_args(p.args, entry.decl, p.concept_span, "concept")
        if p.at is not None:
            self._expect_pose(p.at)

    def _named_args(
        self, args: tuple[ast.Arg, ...], target: ast.Concept, span: ast.Span, what: str
    ) -> None:
        params = {m.name: m for m in target.members if isinstance(m, ast.Param)}
        seen: set[str] = set()
        for a in args:
            te = self.expr(a.value)
            if a.name is None:
                self.err(
                    "E117",
                    f"arguments of a {what} are named",
                    a.span,
                    f"write `name: value`; `{target.name}` has " + ", ".join(params)
                    if params
                    else None,
                )
                continue
            if a.name in seen:
                self.err("E118", f"argument `{a.name}` is given twice", a.span, "keep one of them")
            seen.add(a.name)
            if "." in a.name and what == "concept":
                nested = self._nested_param(target, a)
                if nested is not None:
                    self.coerce(te, nested, a.value.span)
                continue
            if a.name not in params:
                self.err(
                    "E116",
                    f"`{target.name}` has no parameter `{a.name}`",
                    a.span,
                    did_you_mean(a.name, params),
                )
                continue
            expected = declared_type(params[a.name].type)
            if expected is not None:
                self.coerce(te, expected, a.value.span)

    def _joint(self, j: ast.Joint) -> None:
        if j.kind not in JOINT_KINDS:
            self._not_one_of("E218", "joint kind", j.kind, j.kind_span, JOINT_KINDS)
            return
        moving = j.kind != "fixed"
        if moving and j.axis is None:
            self.err("E217", f"a {j.kind} joint needs an `axis (x, y, z)`", j.span)
        if not moving and (j.axis, j.limits, j.origin, j.opens) != (None, None, None, None):
            self.err(
                "E219",
                "a fixed joint takes no axis, at, range or opens",
                j.span,
                "a fixed joint glues its child to its parent where both are declared",
            )
        if j.kind == "continuous" and j.limits is not None:
            self.err(
                "E219",
                "a continuous joint turns freely and takes no range",
                j.limits.span,
                "use a revolute joint for a limited rotation",
            )
        if j.kind in ("revolute", "prismatic") and j.limits is None:
            self.err("E219", f"a {j.kind} joint needs a `range [closed, open]`", j.span)
        if j.axis is not None:
            te = self.expr(j.axis)
            if not (te.type.kind == "vec" and te.type.size == 3) and te.type is not ERR:
                self.err("E230", f"a joint axis is a 3-vector, not {_a(te.type)}", j.axis.span)
        if j.origin is not None:
            self.coerce(self.expr(j.origin), T.vec(3, LENGTH), j.origin.span)
        if j.limits is not None and j.kind in ("revolute", "prismatic"):
            unit = ANGLE if j.kind == "revolute" else LENGTH
            bounds = [(b, self.expr(b)) for b in (j.limits.lo, j.limits.hi)]
            wrong = [
                te.type
                for _, te in bounds
                if te.type.kind == "num" and te.type.dim not in (unit, SCALAR)
            ]
            if wrong:
                example = "[0deg, 90deg]" if unit == ANGLE else "[0mm, 400mm]"
                self.err(
                    "E229",
                    f"a {j.kind} joint's range is in {unit}s, not in {wrong[0].dim}s",
                    j.limits.span,
                    f"e.g. `range {example}`",
                )
            else:
                for bound, te in bounds:
                    self.coerce(te, T.num(unit), bound.span)

    def _grasp(self, g: ast.Grasp) -> None:
        self.scope = {}  # ranges and defaults see the concept's parameters, not the free ones
        self.free_names = {fp.name for fp in g.free}
        free: dict[str, Type] = {}
        for fp in g.free:
            lo, hi = self.expr(fp.lo), self.expr(fp.hi)
            t = self._unify(lo, hi, fp.span, "bounds of a grasp parameter")
            if fp.default is not None:
                self.coerce(self.expr(fp.default), t, fp.default.span)
            if fp.name in free or fp.name in self.members:
                self.err("E105", f"`{fp.name}` is already defined", fp.span)
            free[fp.name] = t
        self.scope, self.free_names = dict(free), set()
        self._expect_pose(g.pose)
        if g.width is not None:
            te = self.expr(g.width)
            not_length = te.type.kind != "num" or (te.type.dim != LENGTH and te.const != 0)
            if not_length and te.type is not ERR:
                self.err(
                    "E231",
                    f"the gripper width is a length, not {_a(te.type)}",
                    g.width.span,
                    "e.g. `width r_out - r_in` or `width 30mm`",
                )
        if g.mode is not None and g.mode not in GRASP_MODES:
            self._not_one_of("E232", "grasp mode", g.mode, g.mode_span, GRASP_MODES)
        if g.about is not None:
            te = self.expr(g.about)
            if not (te.type.kind == "vec" and te.type.size == 3) and te.type is not ERR:
                self.err("E230", f"a symmetry axis is a 3-vector, not {_a(te.type)}", g.about.span)
        if g.when is not None:
            self._when(g.when, free)
        self.free_types[g.name] = free
        self.scope = {}

    def _when(self, cond: ast.Expr, free: dict[str, Type]) -> None:
        """A grasp's ``when``: a condition on the parameters, lets and the values of the
        concept's moving joints (an angle for a revolute or continuous joint, a length for a
        prismatic one), never on the family's own free parameters (E238: their range says where
        the family is, the condition when it applies)."""
        for n in ast.names_in(cond):
            if n.id in free:
                self.err(
                    "E238",
                    f"`{n.id}` is a free parameter of this grasp: a `when` condition reads the "
                    "concept's parameters and joint values",
                    n.span,
                    f"narrow the range of `{n.id}` instead: `{n.id} in [lo, hi]`",
                )
                return
        self.scope = {
            j.name: T.num(LENGTH if j.kind == "prismatic" else ANGLE)
            for j in self.members.values()
            if isinstance(j, ast.Joint) and j.kind != "fixed"
        }
        self._expect_bool(self.expr(cond), cond.span)

    def _action(self, a: ast.Action) -> None:
        if a.verb not in VERBS:
            self._not_one_of("E220", "action verb", a.verb, a.verb_span, VERBS)
        joint = self.members.get(a.joint) if a.joint else None
        if isinstance(joint, ast.Joint) and joint.kind == "fixed":
            self.err("E219", f"`{a.joint}` is fixed: nothing moves along it", a.joint_span)
        if a.direction is not None:
            te = self.expr(a.direction)
            if not (te.type.kind == "vec" and te.type.size == 3) and te.type is not ERR:
                self.err(
                    "E230", f"a force direction is a 3-vector, not {_a(te.type)}", a.direction.span
                )

    def _not_one_of(
        self, code: str, what: str, word: str, span: ast.Span, known: Iterable[str]
    ) -> None:
        """An unknown word from a fixed vocabulary: the closest one, or the whole list."""
        hint = did_you_mean(word, known) or f"{what}s: " + ", ".join(known)
        self.err(code, f"unknown {what} `{word}`", span, hint)

    # ---- coercion helpers -----------------------------------------------------------------------
    def coerce(self, te: TE, want: Type, span: ast.Span) -> None:
        got = te.type
        if ERR in (got, want) or got == want:
            return
        if got.kind == "string":
            if want.kind == "choice" and not isinstance(te.const, str):
                self.err(
                    "E227",
                    "a choice's value is one of its options, written out",
                    span,
                    'e.g. `hand: "left"`; to depend on a condition, give the part a bool',
                )
                return
            if want.kind == "choice":
                assert isinstance(te.const, str)
                if te.const not in want.choices:
                    self.err(
                        "E216",
                        f'"{te.const}" is not one of {want}',
                        span,
                        _choice_hint(te.const, want.choices),
                    )
                return
            self.err("E227", "a string can only be a choice's value", span, _unquote_hint(te.const))
            return
        if got.kind == want.kind and got.kind in ("num", "vec") and got.size == want.size:
            if want.integer and te.const is not None:
                return
            if _is_zero(te.const) or (got.dim == SCALAR and want.dim == SCALAR):
                return
            if te.const is not None and got.dim == SCALAR:
                unit = "mm" if want.dim == LENGTH else "deg" if want.dim == ANGLE else ""
                example = _example(te.const, unit)
                self.err(
                    "E204",
                    f"a bare number where {_a(want)} is needed",
                    span,
                    f"write the unit: `{example}`" if unit else None,
                )
                return
            self.err("E203", f"expected {_a(want)}, found {_a(got)}", span)
            return
        if got.kind == "vec" and want.kind == "vec":
            self.err("E213", f"expected a {want}, found a {got}", span)
            return
        self.err("E202", f"expected {_a(want)}, found {_a(got)}", span)

    def _unify(
        self,
        a: TE,
        b: TE,
        span: ast.Span,
        what: str,
        spans: tuple[ast.Span, ast.Span] | None = None,
    ) -> Type:
        """The common type of two operands that must agree (+, -, comparisons, branches);
        ``spans`` locate the operands, so a bare number's error points at the number."""
        ta, tb = a.type, b.type
        if ERR in (ta, tb):
            return ERR
        if ta == tb:
            return ta
        if ta.kind == tb.kind and ta.kind in ("num", "vec") and ta.size == tb.size:
            if _is_zero(a.const):
                return tb
            if _is_zero(b.const):
                return ta
            bare, other = (
                (a, tb) if a.const is not None else (b, ta) if b.const is not None else (None, None)
            )
            bare_vs_unit = bare is not None and other is not None and bare.type.dim == SCALAR
            if bare_vs_unit and other is not None and other.dim in (LENGTH, ANGLE):
                assert bare is not None
                unit = "mm" if other.dim == LENGTH else "deg"
                where = span if spans is None else spans[0] if bare is a else spans[1]
                self.err(
                    "E204",
                    f"a bare number in {what} with {_a(T.num(other.dim))}",
                    where,
                    f"write the unit, e.g. `{_example(bare.const, unit)}`",
                )
                return ERR
            if ta.integer != tb.integer and ta.dim == tb.dim:
                return T.num(ta.dim) if ta.kind == "num" else T.vec(ta.size, ta.dim)
            self.err("E203", f"{what} mixes {_a(ta)} and {_a(tb)}", span)
            return ERR
        if ta.kind == "vec" and tb.kind == "vec":
            self.err("E213", f"{what} mixes a {ta} and a {tb}", span)
            return ERR
        self.err("E202", f"{what} mixes {_a(ta)} and {_a(tb)}", span)
        return ERR

    def _expect_bool(self, te: TE, span: ast.Span) -> None:
        if te.type not in (T.BOOL, ERR):
            self.err(
                "E214",
                f"a condition must be true or false, not {_a(te.type)}",
                span,
                "compare it, e.g. `x > 0`",
            )

    def _expect_pose(self, e: ast.Expr) -> None:
        te = self.expr(e)
        if te.type.kind not in ("pose", "rot", "error"):
            self.err(
                "E224",
                f"expected a pose, found {_a(te.type)}",
                e.span,
                "build poses with trans(x, y, z), rotx/roty/rotz(a), rpy(r, p, y) and `*`",
            )

    # ---- expressions ----------------------------------------------------------------------------
    def expr(self, e: ast.Expr) -> TE:
        te = self._expr(e)
        self.types[id(e)] = te.type
        return te

    def _expr(self, e: ast.Expr) -> TE:
        if isinstance(e, ast.Number):
            if e.unit is None:
                return TE(T.num(), float(e.text))
            return TE(T.num(T.UNIT_FACTORS[e.unit][0]))
        if isinstance(e, ast.String):
            return TE(T.STRING, e.value)
        if isinstance(e, ast.Bool):
            return TE(T.BOOL)
        if isinstance(e, ast.Name):
            return TE(self._name(e))
        if isinstance(e, ast.Vector):
            return self._vector(e)
        if isinstance(e, ast.Member):
            return self._member_access(e)
        if isinstance(e, ast.IfExpr):
            self._expect_bool(self.expr(e.cond), e.cond.span)
            a, b = self.expr(e.then), self.expr(e.orelse)
            t = self._unify(a, b, e.span, "`if ... then ... else`")
            if t is ERR and a.type.kind != b.type.kind and ERR not in (a.type, b.type):
                self.diags[-1] = error(
                    "E215",
                    f"`if` gives {_a(a.type)} in one branch and {_a(b.type)} in the other",
                    e.span,
                )
            return TE(t)
        if isinstance(e, ast.Unary):
            return self._unary(e)
        if isinstance(e, ast.Binary):
            return self._binary(e)
        assert isinstance(e, ast.Call)
        return self._call(e)

    def _name(self, e: ast.Name) -> Type:
        if e.id in self.scope:
            return self.scope[e.id]
        if e.id in self.param_types:
            return self.param_types[e.id]
        if e.id in self.lets:
            return self._let_type(e.id)
        if e.id == "pi":
            return T.num(ANGLE)
        if e.id in self.dropped:
            self.incomplete = True  # a declaration lost to a syntax error: stay quiet
            return ERR
        if e.id in self.members:
            member = self.members[e.id]
            kind = type(member).__name__.lower()
            hint = None
            if isinstance(member, ast.Joint) and member.kind != "fixed":
                hint = "a joint's value may be read only in a grasp's `when` condition"
            elif isinstance(member, ast.Joint):
                hint = "a fixed joint has no value"
            self.err("E202", f"`{e.id}` is a {kind}, not a value", e.span, hint)
            return ERR
        if e.id in self.free_names:
            self.err(
                "E106",
                f"`{e.id}` is a free grasp parameter and cannot bound another",
                e.span,
                "a grasp parameter's range and default use the concept's parameters",
            )
            return ERR
        known = [*self.scope, *self.param_types, *self.lets, "pi"]
        self.err("E106", f"unknown name `{e.id}`", e.span, did_you_mean(e.id, known))
        return ERR

    def _vector(self, e: ast.Vector) -> TE:
        items = [self.expr(x) for x in e.items]
        if len(items) > 3:
            self.err("E213", f"vectors have 2 or 3 components, not {len(items)}", e.span)
            return TE(ERR)
        if any(i.type.kind != "num" for i in items):
            bad = next(i for i in items if i.type.kind != "num")
            if bad.type is not ERR:
                self.err("E202", f"a vector's components are numbers, not {_a(bad.type)}", e.span)
            return TE(ERR)
        t = items[0]
        for other in items[1:]:
            common = self._unify(t, other, e.span, "a vector")
            t = TE(common, t.const if _is_zero(other.const) else None)
        if t.type is ERR:
            return TE(ERR)
        consts = tuple(i.const for i in items)
        const = consts if all(c is not None for c in consts) else None
        return TE(T.vec(len(items), t.type.dim), const)

    def _member_access(self, e: ast.Member) -> TE:
        part = self.members.get(e.obj.id) if isinstance(e.obj, ast.Name) else None
        if isinstance(part, ast.Part):
            return TE(self._part_param(part, e))
        nested = self._part_path(e.obj) if isinstance(e.obj, ast.Member) else None
        if nested is not None:
            self.types[id(e.obj)] = T.PART
            return TE(self._param_of(nested, e, f"`{dotted(e.obj)}`"))
        if isinstance(part, ast.Shape):
            return TE(self._shape_cue(part, e))
        te = self.expr(e.obj)
        t = te.type
        if t is ERR:
            return TE(ERR)
        fields = "xyz"[: t.size] if t.kind == "vec" else ""
        if e.field not in fields or len(e.field) != 1:
            where = f"a {t}" if t.kind == "vec" else _a(t)
            self.err(
                "E212",
                f"`.{e.field}` is not a component of {where}",
                e.span,
                f"components: {', '.join('.' + f for f in fields)}" if fields else None,
            )
            return TE(ERR)
        const = te.const["xyz".index(e.field)] if isinstance(te.const, tuple) else None
        return TE(T.num(t.dim), const)

    def _shape_cue(self, shape: ast.Shape, e: ast.Member) -> Type:
        """``bar.principal_axis``: an affordance cue of a shape (see ``compiler/cues.py``)."""
        self.types[id(e.obj)] = ERR
        func = shape.value.func if isinstance(shape.value, ast.Call) else ""
        if not has_cue(func, e.field):
            known = [f for f in CUE_TYPES if has_cue(func, f)]
            self.err(
                "E212",
                f"shape `{shape.name}` ({func}) has no cue `{e.field}`",
                e.span,
                did_you_mean(e.field, known) or "cues: " + ", ".join(known),
            )
            return ERR
        if self._shape_refers_to_itself(shape):
            self.err(
                "E119",
                f"shape `{shape.name}` is placed or sized in terms of its own cues",
                e.span,
                "compute the value from parameters instead",
            )
            return ERR
        return CUE_TYPES[e.field]

    def _shape_refers_to_itself(self, shape: ast.Shape) -> bool:
        """Whether the shape's arguments or placement reach one of its own cues (through lets
        or other shapes' cues)."""
        roots = [shape.value, *([shape.at] if shape.at is not None else [])]
        seen: set[str] = set()
        while roots:
            for node in (n.id for n in ast.names_in(roots.pop())):  # `bar.center` names `bar`
                target = self.members.get(node)
                if target is shape:
                    return True
                if node in seen or not isinstance(target, (ast.Let, ast.Shape)):
                    continue
                seen.add(node)
                if isinstance(target, ast.Let):
                    roots.append(target.value)
                else:
                    roots += [target.value, *([target.at] if target.at is not None else [])]
        return False

    def _part_param(self, part: ast.Part, e: ast.Member) -> Type:
        """``handle.r_in``: a parameter of a part, as bound by its arguments or lifted."""
        self.types[id(e.obj)] = ERR
        return self._param_of(part.concept, e, f"`{part.name}`")

    def _param_of(self, concept: str, e: ast.Member, label: str) -> Type:
        """Parameter ``e.field`` of the part ``label`` made with ``concept``."""
        entry = self.prog.concepts.get(concept)
        if entry is None:
            return ERR
        params = {m.name: m for m in entry.decl.members if isinstance(m, ast.Param)}
        if e.field not in params:
            parts = [m.name for m in flat_members(entry.decl) if isinstance(m, ast.Part)]
            self.err(
                "E212",
                f"part {label} ({concept}) has no parameter `{e.field}`",
                e.span,
                did_you_mean(e.field, params)
                or (
                    f"`{e.field}` is a part: read its parameters, `{e.field}.name`"
                    if e.field in parts
                    else None
                ),
            )
            return ERR
        return declared_type(params[e.field].type) or ERR

    def _nested_param(self, target: ast.Concept, a: ast.Arg) -> Type | None:
        """The type of ``handle.length`` bound from a host: a parameter of a nested part that
        the part in between leaves unbound (else it is not the host's to set)."""
        assert a.name is not None
        *path, name = a.name.split(".")
        decl = target
        for i, step in enumerate(path):
            found = [m for m in flat_members(decl) if isinstance(m, ast.Part) and m.name == step]
            entry = self.prog.concepts.get(found[0].concept) if found else None
            if entry is None:
                self.err(
                    "E116",
                    f"`{decl.name}` has no part `{step}`",
                    a.span,
                    did_you_mean(
                        step, [m.name for m in flat_members(decl) if isinstance(m, ast.Part)]
                    ),
                )
                return None
            rest = ".".join([*path[i + 1 :], name])
            if any(x.name == rest for x in found[0].args):
                self.err(
                    "E116",
                    f"`{a.name}` is already given by {decl.name}",
                    a.span,
                    f"{decl.name} binds it in `part {step} = {found[0].concept}(...)`",
                )
                return None
            decl = entry.decl
        params = {m.name: m for m in decl.members if isinstance(m, ast.Param)}
        if name not in params:
            self.err(
                "E116",
                f"`{decl.name}` has no parameter `{name}`",
                a.span,
                did_you_mean(name, params),
            )
            return None
        return declared_type(params[name].type)

    def _part_path(self, e: ast.Expr) -> str | None:
        """The concept of the part that ``left`` or ``left.handle`` (nested parts) denotes."""
        if isinstance(e, ast.Name):
            m = self.members.get(e.id)
            return m.concept if isinstance(m, ast.Part) else None
        if not isinstance(e, ast.Member):
            return None
        outer = self._part_path(e.obj)
        entry = self.prog.concepts.get(outer) if outer is not None else None
        if entry is None:
            return None
        found = [
            m for m in flat_members(entry.decl) if isinstance(m, ast.Part) and m.name == e.field
        ]
        return found[0].concept if found else None

    def _unary(self, e: ast.Unary) -> TE:
        te = self.expr(e.operand)
        if e.op == "not":
            self._expect_bool(te, e.operand.span)
            return TE(T.BOOL)
        if te.type.kind not in ("num", "vec", "error"):
            self.err("E202", f"cannot negate {_a(te.type)}", e.span)
            return TE(ERR)
        return TE(te.type, _neg(te.const) if e.op == "-" else te.const)

    def _binary(self, e: ast.Binary) -> TE:
        a, b = self.expr(e.left), self.expr(e.right)
        ta, tb = a.type, b.type
        if e.op in ("and", "or"):
            self._expect_bool(a, e.left.span)
            self._expect_bool(b, e.right.span)
            return TE(T.BOOL)
        if ERR in (ta, tb):
            return TE(ERR)
        if e.op in ast.COMPARISONS:
            return self._comparison(e, a, b)
        if "string" in (ta.kind, tb.kind):
            self.err("E227", "strings can only be compared with a choice parameter", e.span)
            return TE(ERR)
        if e.op in ("+", "-"):
            t = self._unify(a, b, e.span, f"`{e.op}`", (e.left.span, e.right.span))
            if ta.kind not in ("num", "vec") and t is not ERR:
                self.err(
                    "E202", f"cannot add or subtract {_a(ta)}", e.span, "compose poses with `*`"
                )
                return TE(ERR)
            const = _arith(e.op, a.const, b.const)
            return TE(t, const)
        if e.op == "^":
            return self._power(e, a, b)
        if e.op == "/":
            if tb.kind != "num" or ta.kind not in ("num", "vec"):
                self.err("E202", f"cannot divide {_a(ta)} by {_a(tb)}", e.span)
                return TE(ERR)
            return TE(
                Type(ta.kind, T.div_dim(ta.dim, tb.dim), ta.size), _arith("/", a.const, b.const)
            )
        return self._product(e, a, b)

    def _comparison(self, e: ast.Binary, a: TE, b: TE) -> TE:
        ta, tb = a.type, b.type
        if "string" in (ta.kind, tb.kind) or "choice" in (ta.kind, tb.kind):
            choice, text = (ta, b) if tb.kind == "string" else (tb, a)
            if choice.kind != "choice" or text.type.kind != "string" or e.op not in ("==", "!="):
                self.err(
                    "E227",
                    'compare a choice parameter with one of its options, e.g. `side == "left"`',
                    e.span,
                )
                return TE(ERR)
            self.coerce(text, choice, (e.right if tb.kind == "string" else e.left).span)
            return TE(T.BOOL)
        if ta.kind == "bool" and tb.kind == "bool" and e.op in ("==", "!="):
            return TE(T.BOOL)
        if ta.kind != "num" or tb.kind != "num":
            self.err(
                "E202",
                f"cannot compare {_a(ta)} with {_a(tb)}",
                e.span,
                "compare components, e.g. `v.x < 1mm`" if "vec" in (ta.kind, tb.kind) else None,
            )
            return TE(ERR)
        self._unify(a, b, e.span, f"`{e.op}`", (e.left.span, e.right.span))
        return TE(T.BOOL)

    def _power(self, e: ast.Binary, a: TE, b: TE) -> TE:
        if a.type.kind != "num" or b.type.kind != "num" or b.type.dim != SCALAR:
            self.err("E202", "`^` raises a number to a unit-less power", e.span)
            return TE(ERR)
        if a.type.dim == SCALAR:
            return TE(T.num(), _arith("^", a.const, b.const))
        if b.const is None or float(b.const) != int(b.const):
            self.err(
                "E202", f"a {a.type} can only be raised to a whole constant power", e.right.span
            )
            return TE(ERR)
        n = int(b.const)
        return TE(T.num(Dim(a.type.dim.length * n, a.type.dim.angle and n == 1)))

    def _product(self, e: ast.Binary, a: TE, b: TE) -> TE:
        ta, tb = a.type, b.type
        if ta.kind == "num" and tb.kind in ("num", "vec"):
            return TE(
                Type(tb.kind, T.mul_dim(ta.dim, tb.dim), tb.size), _arith("*", a.const, b.const)
            )
        if tb.kind == "num" and ta.kind == "vec":
            return TE(
                Type("vec", T.mul_dim(ta.dim, tb.dim), ta.size), _arith("*", a.const, b.const)
            )
        if ta.kind in ("rot", "pose") and tb.kind == "vec":
            if tb.size != 3:
                self.err("E213", f"a {ta} acts on 3-vectors, not on a {tb}", e.span)
                return TE(ERR)
            if ta.kind == "pose" and tb.dim != LENGTH and not _is_zero(b.const):
                self.err(
                    "E203",
                    "a pose moves points (lengths); rotate directions with a rotation",
                    e.span,
                )
                return TE(ERR)
            return TE(T.vec(3, LENGTH) if ta.kind == "pose" else tb)
        if ta.kind in ("rot", "pose") and tb.kind in ("rot", "pose"):
            return TE(T.ROT if ta.kind == tb.kind == "rot" else T.POSE)
        hint = "use dot(a, b) or cross(a, b)" if ta.kind == tb.kind == "vec" else None
        self.err("E202", f"cannot multiply {_a(ta)} by {_a(tb)}", e.span, hint)
        return TE(ERR)

    def _call(self, e: ast.Call) -> TE:
        args = [self.expr(a.value) for a in e.args]
        for a in e.args:
            if a.name is not None:
                self.err("E116", f"`{e.func}` takes positional arguments", a.span)
                return TE(ERR)
        if e.func not in BUILTINS:
            hint = did_you_mean(e.func, BUILTINS)
            if e.func in self.prog.concepts:
                hint = "concepts and primitives are placed with `part` or `shape`, not called"
            self.err("E115", f"unknown function `{e.func}`", e.func_span, hint)
            return TE(ERR)
        if any(a.type is ERR for a in args):
            return TE(ERR)
        return TE(_builtin_type(self, e, args))

    # ---- values at the defaults -----------------------------------------------------------------


def declared_type(ref: ast.TypeRef) -> Type | None:
    """The type a parameter declaration names, or None when it names no type."""
    if ref.name == "choice" and ref.choices is not None:
        return Type("choice", choices=ref.choices)
    return T.param_type(ref.name, ref.unit)


def _builtin_type(c: _ConceptChecker, e: ast.Call, args: list[TE]) -> Type:
    """The result type of a built-in call, reporting arity and argument errors."""
    f, n = e.func, len(args)
    arity = {
        "atan2": (2,),
        "min": (2,),
        "max": (2,),
        "clamp": (3,),
        "dot": (2,),
        "cross": (2,),
        "rpy": (3,),
        "axis_angle": (2,),
        "trans": (1, 3),
    }.get(f, (1,))
    if n not in arity:
        want = " or ".join(map(str, arity))
        c.err("E205", f"`{f}` takes {want} argument{'s' if arity != (1,) else ''}, not {n}", e.span)
        return ERR
    kinds = [a.type.kind for a in args]

    def bad(i: int, want: str) -> Type:
        c.err(
            "E206",
            f"argument {i + 1} of `{f}` must be {want}, not {_a(args[i].type)}",
            e.args[i].span,
        )
        return ERR

    def angle_like(i: int) -> bool:
        if kinds[i] == "num" and args[i].type.dim == SCALAR:
            _bare_angle(c, e.args[i].value, args[i])
        return kinds[i] == "num" and args[i].type.dim in (ANGLE, SCALAR)

    if f in ("sin", "cos", "tan"):
        return T.num() if angle_like(0) else bad(0, "an angle")
    if f in ("rotx", "roty", "rotz"):
        return T.ROT if angle_like(0) else bad(0, "an angle")
    if f == "rpy":
        for i in range(3):
            if not angle_like(i):
                return bad(i, "an angle")
        return T.ROT
    if f in ("asin", "acos"):
        return (
            T.num(ANGLE)
            if kinds[0] == "num" and args[0].type.dim == SCALAR
            else bad(0, "a unit-less number")
        )
    if f == "atan2":
        if kinds != ["num", "num"]:
            return bad(0 if kinds[0] != "num" else 1, "a number")
        c._unify(args[0], args[1], e.span, "`atan2`")
        return T.num(ANGLE)
    if f == "sqrt":
        if kinds[0] != "num":
            return bad(0, "a number")
        d = args[0].type.dim
        if d.length % 2 or d.angle:
            c.err(
                "E228",
                f"the square root of a {d} has no unit here",
                e.span,
                "square roots take unit-less numbers or areas (length^2)",
            )
            return ERR
        return T.num(Dim(d.length // 2))
    if f == "abs":
        return args[0].type if kinds[0] in ("num", "vec") else bad(0, "a number or vector")
    if f in ("min", "max", "clamp"):
        if any(k != "num" for k in kinds):
            return bad(kinds.index(next(k for k in kinds if k != "num")), "a number")
        t = args[0].type
        for i in range(1, n):
            t = c._unify(TE(t), args[i], e.span, f"`{f}`")
        return t
    if f in ("dot", "cross"):
        for i in range(2):
            if kinds[i] != "vec" or (f == "cross" and args[i].type.size != 3):
                return bad(i, "a 3-vector" if f == "cross" else "a vector")
        if args[0].type.size != args[1].type.size:
            c.err("E213", f"`{f}` of vectors of different sizes", e.span)
            return ERR
        d = T.mul_dim(args[0].type.dim, args[1].type.dim)
        return T.num(d) if f == "dot" else T.vec(3, d)
    if f in ("norm", "normalize"):
        if kinds[0] != "vec":
            return bad(0, "a vector")
        return T.num(args[0].type.dim) if f == "norm" else T.vec(args[0].type.size)
    if f == "axis_angle":
        if kinds[0] != "vec" or args[0].type.size != 3:
            return bad(0, "a 3-vector")
        return T.ROT if angle_like(1) else bad(1, "an angle")
    if f == "trans":
        if n == 1:
            if kinds[0] != "vec" or args[0].type.size != 3:
                return bad(0, "a 3-vector of lengths")
            c.coerce(args[0], T.vec(3, LENGTH), e.args[0].span)
            return T.POSE
        for i in range(3):
            if kinds[i] != "num":
                return bad(i, "a length")
            c.coerce(args[i], T.num(LENGTH), e.args[i].span)
        return T.POSE
    if f == "inv":
        return args[0].type if kinds[0] in ("rot", "pose") else bad(0, "a rotation or pose")
    raise AssertionError(f"builtin without a type rule: {f}")


def _bare_angle(c: _ConceptChecker, arg: ast.Expr, te: TE) -> None:
    """``rotx(90)``: a bare non-zero constant where an angle is expected is radians, which is
    rarely what was meant; a warning, since radians are the SI unit."""
    if isinstance(te.const, (int, float)) and te.const != 0:
        value = float(te.const)
        c.diags.append(
            Diagnostic(
                "E237",
                f"the bare number {value:g} is taken as {value:g} radians "
                f"({math.degrees(value):g} degrees)",
                arg.span,
                f"write the unit: `{value:g}deg`, or `{value:g}rad` if radians are meant",
                "warning",
            )
        )


def _choice_hint(text: str, choices: tuple[str, ...]) -> str:
    close = did_you_mean(text, choices)
    if close is not None:
        return close.replace("`", '"')
    return "options: " + ", ".join(f'"{c}"' for c in choices)


def _unquote_hint(text: object) -> str | None:
    """``"300mm"`` written where a length belongs: suggest dropping the quotes."""
    if isinstance(text, str) and re.fullmatch(r"\s*[0-9.]+(e[+-]?\d+)?(mm|cm|m|deg|rad)?\s*", text):
        return f"remove the quotes: `{text.strip()}`"
    return None


def _a(t: Type) -> str:
    s = str(t)
    return ("an " if s[0] in "aeiou" else "a ") + s


def _is_zero(const: Any) -> bool:
    if const is None or isinstance(const, str):
        return False
    if isinstance(const, tuple):
        return all(_is_zero(c) for c in const)
    return float(const) == 0.0


def _neg(const: Any) -> Any:
    if const is None:
        return None
    return tuple(-c for c in const) if isinstance(const, tuple) else -const


def _arith(op: str, a: Any, b: Any) -> Any:
    """Fold unit-less constants (so that ``0 * x`` and ``-0`` still count as zero)."""
    if a is None or b is None or isinstance(a, (tuple, str)) or isinstance(b, (tuple, str)):
        return None
    with np.errstate(all="ignore"):
        if op == "+":
            return a + b
        if op == "-":
            return a - b
        if op == "*":
            return a * b
        if op == "/":
            return a / b if b != 0 else None
        return float(np.power(float(a), float(b)))


def _example(const: Any, unit: str) -> str:
    if isinstance(const, tuple):
        return "(" + ", ".join(_example(c, unit) for c in const) + ")"
    return f"{float(const):g}{unit}"
