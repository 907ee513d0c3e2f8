"""Values at the defaults: the second half of the check pass.

A concept that type-checks is evaluated at its defaults with the NumPy backend: bounds ordered,
defaults inside their ranges, every ``require`` true, every grasp and joint range sensible, every
value finite, and every part's or primitive's arguments inside its ranges and requirements (else
every instance of the concept would fail at run time).  Parts are checked before their hosts, so
a host reads its parts' defaults from ``done``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.compiler.backends import NUMPY, Backend
from grace_dsl.compiler.cues import shape_cue
from grace_dsl.compiler.evaluate import Evaluator, definition_needs
from grace_dsl.compiler.resolve import flat_members
from grace_dsl.compiler.types import ANGLE, LENGTH, SCALAR, Dim, Type, format_si
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic, error

if TYPE_CHECKING:
    from grace_dsl.compiler.check import CheckedConcept

SET_OPS = ("union", "difference")


def check_values(
    out: CheckedConcept, done: dict[str, CheckedConcept], types: dict[int, Type]
) -> list[Diagnostic]:
    """Evaluate a type-checked concept at its defaults, filling ``out.defaults``/``out.bounds``."""
    checker = _ValueChecker(out, done, types)
    checker._check_values(out)
    return checker.diags


class _ValueChecker:
    def __init__(
        self, out: CheckedConcept, done: dict[str, CheckedConcept], types: dict[int, Type]
    ):
        self.decl, self.done, self.types = out.decl, done, types
        self.param_types, self.free_types = out.param_types, out.free_types
        self.params = {m.name: m for m in self.decl.members if isinstance(m, ast.Param)}
        self.lets = {m.name: m for m in flat_members(self.decl) if isinstance(m, ast.Let)}
        self.members = {getattr(m, "name", None): m for m in flat_members(self.decl)}
        self.diags: list[Diagnostic] = []

    def err(self, code: str, msg: str, span: ast.Span, hint: str | None = None) -> None:
        self.diags.append(error(code, msg, span, hint))

    def _check_values(self, out: CheckedConcept) -> None:
        with np.errstate(all="ignore"):
            self._check_param_values(out)
            if self.diags:
                return
            ev = self._defaults_evaluator(out)
            if ev is None:
                return
            for m in flat_members(self.decl):
                self._check_member_values(m, ev)

    def _defaults_evaluator(self, out: CheckedConcept) -> Evaluator | None:
        """The concept evaluated at its defaults; None (after a diagnostic) on a cycle."""
        ev = evaluator_at(self.decl, out.defaults, self.done, self.types)
        if ev is None:
            return None
        parts = [m for m in flat_members(self.decl) if isinstance(m, ast.Part)]
        for part in parts:
            for arg in (a for a in part.args if a.name):
                try:
                    ev.lookup(f"{part.name}.{arg.name}")
                except _Cycle as cycle:
                    self.err(
                        "E119",
                        f"`{part.name}.{arg.name}` is defined in terms of itself: "
                        + " -> ".join(cycle.names),
                        arg.span,
                    )
                    return None
        return ev

    def _check_arguments(self, m: ast.Part | ast.Shape, ev: Evaluator) -> None:
        """A part's or primitive's arguments at the defaults: inside its ranges, and meeting
        its requirements (otherwise every instance would fail at run time)."""
        call = m.value if isinstance(m, ast.Shape) else None
        if isinstance(m, ast.Part):
            target, args, prefix = m.concept, m.args, f"{m.name}."
        elif isinstance(call, ast.Call) and call.func not in SET_OPS:
            target, args, prefix = call.func, call.args, None
        else:
            return
        sub = self.done.get(target)
        if sub is None or not sub.ok:
            return
        values = dict(sub.defaults)
        for a in args:
            bound = bound_target(self.done, target, a.name) if a.name else None
            if a.name is None or bound is None or bound[1] not in bound[0].param_types:
                continue
            value = ev.lookup(prefix + a.name) if prefix else ev(a.value)
            if a.name in sub.param_types or "." in a.name:  # `handle.length`: a nested part's
                values[a.name] = value
            owner, param = bound
            if param in owner.bounds and not _within(value, *owner.bounds[param]):
                lo, hi = owner.bounds[param]
                dim = owner.param_types[param].dim
                self.err(
                    "E209",
                    f"`{a.name}` = {format_si(value, dim)} at the defaults lies "
                    f"outside the range of {target}",
                    a.value.span,
                    f"{owner.decl.name}.{param} is in [{format_si(lo, dim)}, {format_si(hi, dim)}]",
                )
        sub_ev = evaluator_at(sub.decl, values, self.done, self.types)
        if sub_ev is None:
            return
        self._check_requires(m, target, sub.decl, sub_ev)
        # a dotted argument (`handle.length`) also binds the nested part's own requirements
        # (and those of every part on the way: `door.handle.length` binds the door's too)
        paths = {a.name.rsplit(".", 1)[0] for a in args if a.name and "." in a.name}
        levels = {".".join(p.split(".")[: k + 1]) for p in paths for k in range(p.count(".") + 1)}
        for path in sorted(levels):
            found = self._nested(sub.decl, sub_ev, path, values)
            if found is not None:
                decl, nested_ev = found
                self._check_requires(m, f"{target}'s part `{path}` ({decl.name})", decl, nested_ev)

    def _check_requires(
        self, m: ast.Part | ast.Shape, what: str, decl: ast.Concept, ev: Evaluator
    ) -> None:
        for r in (x for x in decl.members if isinstance(x, ast.Require)):
            if not bool(ev(r.cond)):
                self.err(
                    "E210",
                    f"with these arguments, {what} fails its requirement"
                    + (f" ({r.message})" if r.message else ""),
                    getattr(m, "name_span", m.span),
                    f"at {r.cond.span.file}:{r.cond.span.line}",
                )

    def _nested(
        self, decl: ast.Concept, ev: Evaluator, path: str, values: dict[str, Any]
    ) -> tuple[ast.Concept, Evaluator] | None:
        """The concept of the nested part at ``path`` (``handle``, ``door.handle``) and its
        evaluator with the values its hosts give it; None when one on the way did not check."""
        for depth, step in enumerate(path.split(".")):
            part = next(
                (p for p in flat_members(decl) if isinstance(p, ast.Part) and p.name == step),
                None,
            )
            sub = self.done.get(part.concept) if part is not None else None
            if sub is None or not sub.ok:
                return None
            here = ".".join(path.split(".")[: depth + 1]) + "."
            given = {k: ev.lookup(f"{step}.{k}") for k in sub.param_types}
            given.update(  # deeper bindings: `door.handle.length` reaches the handle
                {k[len(here) :]: v for k, v in values.items() if k.startswith(here)}
            )
            nested = evaluator_at(sub.decl, given, self.done, self.types)
            if nested is None:
                return None
            decl, ev = sub.decl, nested
        return decl, ev

    def _check_param_values(self, out: CheckedConcept) -> None:
        ev = Evaluator(NUMPY, self.types, {})
        for name, p in self.params.items():
            t = self.param_types[name]
            lo = hi = None
            if p.bounds is not None:
                lo, hi = ev(p.bounds.lo), ev(p.bounds.hi)
                if not self._finite_constant(name, "bound", (p.bounds.lo, lo), (p.bounds.hi, hi)):
                    continue
                if np.any(np.asarray(lo) > np.asarray(hi)):
                    self.err(
                        "E208",
                        f"the range of `{name}` is empty: its lower bound is above its upper bound",
                        p.bounds.span,
                        "swap the bounds: `in [lo, hi]`",
                    )
                    continue
                out.bounds[name] = (lo, hi)
            if p.default is not None:
                value = ev(p.default)
                if t.kind in ("num", "vec") and not self._finite_constant(
                    name, "default", (p.default, value)
                ):
                    continue
                if t.kind == "choice":
                    value = float(t.choices.index(value))
                elif t.kind == "bool":
                    value = float(bool(value))
            elif p.bounds is not None:
                value = (np.asarray(lo) + np.asarray(hi)) / 2
                value = tuple(value) if t.kind == "vec" else float(value)
            else:
                continue
            if t.integer and float(value) != int(value):
                span = p.default.span if p.default is not None else p.name_span
                what = "its default" if p.default is not None else "the middle of its range"
                self.err(
                    "E226",
                    f"`{name}` is an int, but {what} is {float(value):g}",
                    span,
                    f"give it a whole-number default, e.g. `= {int(np.floor(float(value)))}`",
                )
            if lo is not None and (
                np.any(np.asarray(value) < np.asarray(lo))
                or np.any(np.asarray(value) > np.asarray(hi))
            ):
                assert p.default is not None and p.bounds is not None
                self.err(
                    "E209",
                    f"the default of `{name}` lies outside its range",
                    p.default.span,
                    f"the range is [{format_si(lo, t.dim)}, {format_si(hi, t.dim)}]",
                )
            out.defaults[name] = value

    def _finite_constant(self, name: str, what: str, *values: tuple[ast.Expr, Any]) -> bool:
        """A parameter's bound or default must be a finite number: a NaN bound would switch
        range checks off, an infinite one makes the range meaningless."""
        for expr, value in values:
            if not np.all(np.isfinite(np.asarray(value, dtype=float))):
                self.err(
                    "E225",
                    f"the {what} of `{name}` is not a finite number",
                    expr.span,
                    "ranges and defaults are finite numbers; look for a division by zero, "
                    "the square root of a negative number or an overflow",
                )
                return False
        return True

    def _check_member_values(self, m: ast.Member_, ev: Evaluator) -> None:
        name = getattr(m, "name", None)
        if name is not None and self.members.get(name) is not m:
            return  # a duplicate, already reported (E105)
        if isinstance(m, ast.Require):
            if not bool(ev(m.cond)):
                used = sorted({n.id for n in ast.names_in(m.cond)} & set(ev.env) - {"pi"})
                shown = ", ".join(f"{n} = {format_si(ev.env[n], self._dim(n))}" for n in used)
                self.err(
                    "E210",
                    "this requirement is false at the defaults"
                    + (f" ({m.message})" if m.message else ""),
                    m.cond.span,
                    f"at the defaults {shown}" if shown else None,
                )
        elif isinstance(m, ast.Let):
            self._finite(ev(m.value), m.value.span, f"`{m.name}`")
        elif isinstance(m, ast.Joint):
            self._check_joint_values(m, ev)
        elif isinstance(m, ast.Action) and m.direction is not None:
            if not np.any(np.asarray(ev(m.direction), dtype=float)):
                self.err(
                    "E221",
                    f"the direction of action `{m.name}` is the zero vector",
                    m.direction.span,
                )
        elif isinstance(m, ast.Grasp):
            self._check_grasp_values(m, ev)
        elif isinstance(m, (ast.Part, ast.Shape)):
            self._check_arguments(m, ev)

    def _check_joint_values(self, j: ast.Joint, ev: Evaluator) -> None:
        if j.axis is not None and not np.any(np.asarray(ev(j.axis), dtype=float)):
            self.err("E221", f"the axis of joint `{j.name}` is the zero vector", j.axis.span)
        if j.limits is None or j.kind not in ("revolute", "prismatic"):
            return
        lo, hi = float(ev(j.limits.lo)), float(ev(j.limits.hi))
        dim = ANGLE if j.kind == "revolute" else LENGTH
        shown = f"[{format_si(lo, dim)}, {format_si(hi, dim)}]"
        if lo > hi:
            self.err(
                "E208",
                f"the range of joint `{j.name}` is empty at the defaults ({shown})",
                j.limits.span,
                "swap the bounds: `range [closed, open]`",
            )
        elif not lo <= 0 <= hi:
            self.err(
                "E209",
                f"the range of joint `{j.name}` ({shown}) leaves out 0, its closed state",
                j.limits.span,
                "q = 0 is closed and positive q opens: e.g. `range [0, 90deg]`",
            )

    def _check_grasp_values(self, g: ast.Grasp, ev: Evaluator) -> None:
        free = {}
        for fp in g.free:
            lo, hi = ev(fp.lo), ev(fp.hi)
            if not lo <= hi:
                dim = self.free_types[g.name][fp.name].dim
                self.err(
                    "E211",
                    f"the range of `{fp.name}` is empty at the defaults "
                    f"([{format_si(float(lo), dim)}, {format_si(float(hi), dim)}])",
                    fp.span,
                    "its lower bound must not exceed its upper bound at the defaults",
                )
                return
            free[fp.name] = ev(fp.default) if fp.default is not None else (lo + hi) / 2
            if fp.default is not None and not _within(free[fp.name], lo, hi):
                dim = self.free_types[g.name][fp.name].dim
                self.err(
                    "E209",
                    f"the default of `{fp.name}` lies outside its range at the defaults",
                    fp.default.span,
                    f"the range is [{format_si(float(lo), dim)}, {format_si(float(hi), dim)}]",
                )
        sub = ev.with_names(free)
        self._finite(sub(g.pose), g.pose.span, f"grasp `{g.name}`")
        if g.width is not None:
            self._finite(sub(g.width), g.width.span, f"the width of grasp `{g.name}`")

    def _finite(self, value: Any, span: ast.Span, what: str) -> None:
        if isinstance(value, str):
            return
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            self.err(
                "E225",
                f"{what} is not a finite number at the defaults",
                span,
                "look for a division by zero or the square root of a negative number",
            )

    def _dim(self, name: str) -> Dim:
        """The dimension of a parameter or let, for showing its value."""
        let = self.lets.get(name)
        t = self.param_types.get(name) or (self.types.get(id(let.value)) if let else None)
        return t.dim if t is not None else SCALAR


def evaluator_at(
    decl: ast.Concept,
    values: dict[str, Any],
    done: dict[str, CheckedConcept],
    types: dict[int, Type],
    backend: Backend = NUMPY,
    observe: Callable[[ast.Expr, Any], None] | None = None,
) -> Evaluator | None:
    """An evaluator of ``decl`` with parameter ``values``: lets and part arguments are
    computed on demand (raising ``_Cycle`` on a loop), a part's unbound parameters take their
    concept's defaults unless ``values`` gives them (``handle.r_in``).  None when a part's
    concept did not check.  NumPy by default; the interval pass uses its own backend."""
    lets = {m.name: m for m in flat_members(decl) if isinstance(m, ast.Let)}
    parts = [m for m in flat_members(decl) if isinstance(m, ast.Part)]
    args = {f"{p.name}.{a.name}": a for p in parts for a in p.args if a.name}
    env = dict(values)
    for part in parts:
        sub = done.get(part.concept)
        if sub is None or not sub.ok:
            return None
        env.update(
            {
                f"{part.name}.{k}": v
                for k, v in sub.defaults.items()
                if f"{part.name}.{k}" not in args and f"{part.name}.{k}" not in values
            }
        )
    shapes = {m.name: m for m in flat_members(decl) if isinstance(m, ast.Shape)}
    visiting: list[str] = []

    def value(name: str) -> Any:
        if name in visiting:
            raise _Cycle([*visiting[visiting.index(name) :], name])
        visiting.append(name)
        try:
            head, _, field = name.partition(".")
            if head in shapes:
                return _shape_cue(shapes[head], field)
            if name in lets or name in args:
                return ev(lets[name].value if name in lets else args[name].value)
            return _inside(head).lookup(field)  # a nested part's parameter: left.handle.length
        finally:
            visiting.pop()

    inner: dict[str, Evaluator | None] = {}

    def _inside(part_name: str) -> Evaluator:
        """The evaluator of a part's concept with the values this concept gives it."""
        if part_name not in inner:
            part = next(p for p in parts if p.name == part_name)
            sub = done[part.concept]
            own = part_name + "."
            given = {k: ev.lookup(own + k) for k in sub.param_types}
            given.update(
                {a.name: ev.lookup(own + a.name) for a in part.args if a.name and "." in a.name}
            )
            given.update(
                {
                    k[len(own) :]: v
                    for k, v in values.items()
                    if k.startswith(own) and "." in k[len(own) :]
                }
            )
            inner[part_name] = evaluator_at(sub.decl, given, done, types, backend, observe)
        found = inner[part_name]
        if found is None:
            raise KeyError(part_name)
        return found

    def _shape_cue(shape: ast.Shape, field: str) -> Any:
        call = shape.value
        prim = done.get(call.func) if isinstance(call, ast.Call) else None
        return shape_cue(backend, ev, shape, dict(prim.defaults) if prim else {}, field)

    needs = definition_needs(lets, {k: a.value for k, a in args.items()}, shapes)
    qualified = frozenset([*(p.name for p in parts), *shapes])
    ev = Evaluator(backend, types, env, value, qualified, needs, observe)
    return ev


def bound_target(
    done: dict[str, CheckedConcept], concept: str, name: str
) -> tuple[CheckedConcept, str] | None:
    """The checked concept and parameter that argument ``name`` of a part made with
    ``concept`` binds: its own (``length``) or a nested part's (``handle.length`` binds
    ``length`` of the part ``handle``).  None when a concept on the way did not check."""
    *path, param = name.split(".")
    for step in path:
        sub = done.get(concept)
        found = [
            m
            for m in (flat_members(sub.decl) if sub is not None else ())
            if isinstance(m, ast.Part) and m.name == step
        ]
        if not found:
            return None
        concept = found[0].concept
    sub = done.get(concept)
    return (sub, param) if sub is not None and sub.ok else None


def _within(value: Any, lo: Any, hi: Any) -> bool:
    v = np.asarray(value, dtype=float)
    return bool(np.all(v >= np.asarray(lo) - 1e-12) and np.all(v <= np.asarray(hi) + 1e-12))


class _Cycle(Exception):
    def __init__(self, names: list[str]):
        self.names = names
