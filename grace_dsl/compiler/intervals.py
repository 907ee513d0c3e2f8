"""Interval analysis: values that become infinite, undefined or invalid inside the declared ranges.

The check pass evaluates a concept at its defaults (``values.py``); this pass looks at the whole
parameter box.  Every expression is evaluated once more by the one evaluator (``evaluate.py``),
now over an interval backend: each parameter is the interval of its range, so every
sub-expression gets an interval that contains all its values in range (up to float rounding).
That proves most expressions safe.  Where it cannot (a divisor's interval holds 0, a square
root's argument reaches below 0, an interval overflows, an argument's interval leaves the range
of its primitive or part), the candidate is confirmed with a witness: the concept is evaluated
with NumPy at corners of the box and at seeded random points that satisfy its requirements, and
only a candidate some point really exhibits becomes a warning, located at the sub-expression and
naming the parameter values that show it.  Interval arithmetic overestimates (``x - x`` is not
0), so without witnesses it would warn about problems that cannot happen.

Entry: ``check_intervals(concept, done, types)``, called by ``check`` for a concept that checked.
The arithmetic is the backend in ``interval_backend.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from grace_dsl.compiler.backends import NUMPY
from grace_dsl.compiler.evaluate import reads
from grace_dsl.compiler.interval_backend import EITHER, INTERVALS, Interval, hull, iv
from grace_dsl.compiler.resolve import flat_members
from grace_dsl.compiler.types import Dim, Type, format_si
from grace_dsl.compiler.values import bound_target
from grace_dsl.lang import ast
from grace_dsl.lang.diagnostics import Diagnostic

if TYPE_CHECKING:
    from grace_dsl.compiler.check import CheckedConcept

INF = math.inf
SAMPLES = 256  # random points of the box, besides its corners and the defaults
MAX_CORNER_DIMS = 10  # all corners up to 2^10; beyond, a random subset of them


# ---- the pass -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Candidate:
    """A sub-expression the intervals cannot prove safe, and what to confirm about it."""

    code: str
    node: ast.Expr
    check: str  # "divisor" | "sqrt" | "finite" | "range"
    lo: Any = None  # for "range": the target's bounds (SI)
    hi: Any = None
    what: str = ""  # for "range": "`inner` of RectRing"
    dim: Dim | None = None


def check_intervals(
    concept: CheckedConcept, done: dict[str, CheckedConcept], types: dict[int, Type]
) -> list[Diagnostic]:
    """Warnings for values that are infinite, undefined or out of range somewhere inside the
    declared ranges (and requirements) of a concept that checked; each with a witness."""
    from grace_dsl.compiler.values import evaluator_at

    decl = concept.decl
    boxes: dict[int, Any] = {}
    env = _interval_env(concept, done)
    ev = evaluator_at(decl, env, done, types, INTERVALS, lambda e, v: boxes.__setitem__(id(e), v))
    if ev is None:
        return []
    with np.errstate(all="ignore"):
        for _, run in _roots(decl):
            run(ev, _hull_free)
        found = list(_candidates(concept, done, boxes))
        if not found:
            return []
        return _confirm(concept, done, types, found)


def _unbound_params(
    concept: CheckedConcept, done: dict[str, CheckedConcept]
) -> Iterator[tuple[str, CheckedConcept, str]]:
    """(key, owner, name) of every parameter the concept leaves free: its own, and those of its
    parts at any depth that no argument binds (``handle.r_in``, ``left.handle.length``)."""
    stack: list[tuple[str, CheckedConcept, set[str]]] = [("", concept, set())]
    while stack:
        prefix, cc, bound = stack.pop(0)
        for name in cc.param_types:
            if name not in bound:
                yield prefix + name, cc, name
        for part in (m for m in flat_members(cc.decl) if isinstance(m, ast.Part)):
            sub = done.get(part.concept)
            if sub is None:
                continue
            own = part.name + "."
            inner = {a.name for a in part.args if a.name}
            inner |= {b[len(own) :] for b in bound if b.startswith(own)}
            stack.append((prefix + own, sub, inner))


def _interval_env(concept: CheckedConcept, done: dict[str, CheckedConcept]) -> dict[str, Any]:
    """Each free parameter as the interval of its range (a point without one)."""
    env: dict[str, Any] = {}
    for key, cc, name in _unbound_params(concept, done):
        t = cc.param_types[name]
        if t.kind == "bool":
            env[key] = EITHER
        elif t.kind == "choice":
            env[key] = Interval(0.0, float(len(t.choices) - 1))
        elif name in cc.bounds:
            env[key] = hull(*_intervals(cc.bounds[name]))
        elif name in cc.defaults:
            env[key] = _as_intervals(cc.defaults[name])
    return env


def _intervals(bounds: tuple[Any, Any]) -> tuple[Any, Any]:
    return _as_intervals(bounds[0]), _as_intervals(bounds[1])


def _as_intervals(value: Any) -> Any:
    if isinstance(value, tuple) or (isinstance(value, np.ndarray) and value.ndim):
        return tuple(iv(float(x)) for x in value)
    return iv(float(value))


def _hull_free(lo: Any, hi: Any, key: str) -> Any:
    return hull(lo, hi)


Run = Callable[[Any, Callable[[Any, Any, str], Any]], None]


def _roots(decl: ast.Concept) -> Iterator[tuple[list[ast.Expr], Run]]:
    """Every expression tree of a concept, with how to evaluate it: a grasp's pose and width
    see its free parameters, whose values ``free(lo, hi, key)`` chooses."""
    last = {getattr(m, "name", None): m for m in flat_members(decl)}
    for m in flat_members(decl):
        name = getattr(m, "name", None)
        if name is not None and last[name] is not m:
            continue  # a duplicate (E105): the checker typed only the last one
        trees: list[ast.Expr] = []
        if isinstance(m, ast.Let):
            trees = [m.value]
        elif isinstance(m, ast.Require):
            trees = [m.cond]
        elif isinstance(m, ast.Shape):
            call = m.value
            if isinstance(call, ast.Call) and call.func not in ("union", "difference"):
                trees = [a.value for a in call.args]
            trees += [m.at] if m.at is not None else []
        elif isinstance(m, ast.Part):
            trees = [a.value for a in m.args] + ([m.at] if m.at is not None else [])
        elif isinstance(m, ast.Joint):
            limits = [m.limits.lo, m.limits.hi] if m.limits is not None else []
            trees = [x for x in (m.axis, m.origin) if x is not None] + limits
        elif isinstance(m, ast.Action) and m.direction is not None:
            trees = [m.direction]
        elif isinstance(m, ast.Grasp):
            yield _grasp_root(m)
            continue
        if trees:
            yield trees, _plain(trees)


def _plain(trees: list[ast.Expr]) -> Run:
    def run(ev: Any, free: Callable[[Any, Any, str], Any]) -> None:
        for t in trees:
            ev(t)

    return run


def _grasp_root(g: ast.Grasp) -> tuple[list[ast.Expr], Run]:
    bounds = [x for fp in g.free for x in (fp.lo, fp.hi, fp.default) if x is not None]
    inside = [x for x in (g.pose, g.width, g.about) if x is not None]

    def run(ev: Any, free: Callable[[Any, Any, str], Any]) -> None:
        names = {}
        for fp in g.free:
            names[fp.name] = free(ev(fp.lo), ev(fp.hi), f"{g.name}:{fp.name}")
            if fp.default is not None:
                ev(fp.default)
        sub = ev.with_names(names)
        for x in inside:
            sub(x)

    return bounds + inside, run


def _candidates(
    concept: CheckedConcept, done: dict[str, CheckedConcept], boxes: dict[int, Any]
) -> Iterator[_Candidate]:
    for trees, _ in _roots(concept.decl):
        for node in _nodes(trees):
            yield from _node_candidates(node, boxes)
    for m in flat_members(concept.decl):
        yield from _argument_candidates(m, done, boxes)


def _node_candidates(node: ast.Expr, boxes: dict[int, Any]) -> Iterator[_Candidate]:
    value = boxes.get(id(node))
    if value is None:
        return
    if isinstance(node, ast.Binary) and node.op == "/":
        divisor = boxes.get(id(node.right))
        if isinstance(divisor, Interval) and divisor.contains(0.0):
            yield _Candidate("E233", node, "divisor")
        return
    if isinstance(node, ast.Call) and node.func == "sqrt" and node.args:
        arg = boxes.get(id(node.args[0].value))
        if isinstance(arg, Interval) and arg.lo < 0:
            yield _Candidate("E234", node, "sqrt")
        return
    if not isinstance(node, (ast.Binary, ast.Unary, ast.Call)):
        return  # a name's or a component's value is judged where it is computed
    children = [boxes.get(id(c)) for c in ast._children(node)]
    if not _all_finite(value) and all(c is not None and _all_finite(c) for c in children):
        yield _Candidate("E235", node, "finite")
    elif isinstance(node, ast.Call) and node.func in ("asin", "acos") and children:
        arg = children[0]
        if isinstance(arg, Interval) and (arg.lo < -1 or arg.hi > 1):
            yield _Candidate("E235", node, "finite")


def _argument_candidates(
    m: ast.Member_, done: dict[str, CheckedConcept], boxes: dict[int, Any]
) -> Iterator[_Candidate]:
    """Arguments of a primitive or part whose interval leaves that target's range."""
    if isinstance(m, ast.Shape) and isinstance(m.value, ast.Call):
        target, args = m.value.func, m.value.args
    elif isinstance(m, ast.Part):
        target, args = m.concept, m.args
    else:
        return
    sub = done.get(target)
    if sub is None:
        return
    for a in args:
        bound = bound_target(done, target, a.name) if a.name else None
        if bound is None or bound[1] not in bound[0].bounds:
            continue
        owner, param = bound
        lo, hi = owner.bounds[param]
        box = boxes.get(id(a.value))
        if box is not None and not _inside(box, lo, hi):
            dim = owner.param_types[param].dim
            yield _Candidate("E236", a.value, "range", lo, hi, f"`{a.name}` of {target}", dim)


def _inside(box: Any, lo: Any, hi: Any) -> bool:
    boxes = box if isinstance(box, tuple) else (box,)
    los, his = np.atleast_1d(lo), np.atleast_1d(hi)
    return all(
        isinstance(b, Interval) and b.lo >= x - 1e-12 and b.hi <= y + 1e-12
        for b, x, y in zip(boxes, los, his)
    )


def _all_finite(value: Any) -> bool:
    if isinstance(value, tuple):
        return all(_all_finite(v) for v in value)
    if isinstance(value, Interval):
        return value.finite
    return True


def _nodes(trees: list[ast.Expr]) -> Iterator[ast.Expr]:
    stack = list(trees)
    while stack:
        node = stack.pop()
        yield node
        stack += ast._children(node)


# ---- witnesses ----------------------------------------------------------------------------------


def _confirm(
    concept: CheckedConcept,
    done: dict[str, CheckedConcept],
    types: dict[int, Type],
    found: list[_Candidate],
) -> list[Diagnostic]:
    """Evaluate the concept at sample points of its box; warn about the candidates that some
    point satisfying every requirement exhibits."""
    from grace_dsl.compiler.values import evaluator_at

    env, n = _sample_env(concept, done)
    seen: dict[int, Any] = {}
    ev = evaluator_at(
        concept.decl, env, done, types, NUMPY, lambda e, v: seen.__setitem__(id(e), v)
    )
    if ev is None:
        return []
    rng = np.random.default_rng(1)

    def free(lo: Any, hi: Any, key: str) -> Any:
        u = rng.uniform(size=n)
        u[: n // 8], u[n // 8 : n // 4] = 0.0, 1.0
        return _zip(lambda a, b: a + u * (b - a), lo, hi)

    try:
        for _, run in _roots(concept.decl):
            run(ev, free)
    except (KeyError, ValueError, TypeError, IndexError):
        return []  # a shape the sampler cannot broadcast; stay quiet rather than guess
    allowed = np.ones(n, dtype=bool)
    for r in (m for m in concept.decl.members if isinstance(m, ast.Require)):
        allowed &= _array(seen.get(id(r.cond), True), n).astype(bool)
    guards = _guards(concept.decl)
    out: list[Diagnostic] = []
    done_spans: set[tuple[str, ast.Span]] = set()
    for c in found:
        mask = allowed.copy()
        for cond, want in guards.get(id(c.node), ()):
            mask &= _array(seen.get(id(cond), want), n).astype(bool) == want
        witness = _witness(c, seen, mask, n, types)
        if witness is None or (c.code, c.node.span) in done_spans:
            continue
        done_spans.add((c.code, c.node.span))
        out.append(_warning(c, concept, env, witness))
    return out


# (key, component or -1, lo, hi, type, owning concept, parameter name): one axis of the box
_Dim = tuple[str, int, float, float, Type, "CheckedConcept", str]


def _sample_env(
    concept: CheckedConcept, done: dict[str, CheckedConcept]
) -> tuple[dict[str, Any], int]:
    """Parameter values as arrays: the defaults, corners of the box and seeded random points."""
    dims: list[_Dim] = []
    fixed: dict[str, Any] = {}

    for key, cc, name in _unbound_params(concept, done):
        t = cc.param_types[name]
        if t.kind == "bool":
            dims.append((key, -1, 0.0, 1.0, t, cc, name))
        elif t.kind == "choice":
            dims.append((key, -1, 0.0, float(len(t.choices) - 1), t, cc, name))
        elif name in cc.bounds:
            los, his = (np.atleast_1d(np.asarray(x, dtype=float)) for x in cc.bounds[name])
            vector = t.kind == "vec"
            for i, (lo, hi) in enumerate(zip(los, his)):
                dims.append((key, i if vector else -1, float(lo), float(hi), t, cc, name))
        elif name in cc.defaults:
            fixed[key] = cc.defaults[name]
    rng = np.random.default_rng(0)
    d = len(dims)
    if d <= MAX_CORNER_DIMS:
        corners = ((np.arange(2**d)[:, None] >> np.arange(d)) & 1).astype(float)
    else:
        corners = rng.integers(0, 2, size=(2**MAX_CORNER_DIMS, d)).astype(float)
    unit = np.vstack([_defaults_row(dims), corners, rng.uniform(size=(SAMPLES, d))])
    n = len(unit)
    columns: dict[str, dict[int, np.ndarray]] = {}
    for j, (key, comp, lo, hi, t, _, _) in enumerate(dims):
        col = lo + unit[:, j] * (hi - lo)
        if t.kind in ("bool", "choice") or t.integer:
            col = np.round(col)
        columns.setdefault(key, {})[comp] = col
    env: dict[str, Any] = {
        k: _array(v, n) if not isinstance(v, tuple) else tuple(_array(x, n) for x in v)
        for k, v in fixed.items()
    }
    for key, comps in columns.items():
        env[key] = comps[-1] if -1 in comps else tuple(comps[i] for i in sorted(comps))
    return env, n


def _defaults_row(dims: list[_Dim]) -> np.ndarray:
    """The defaults as a point of the unit box (they satisfy the requirements)."""
    row = []
    for _, comp, lo, hi, _, owner, name in dims:
        default = owner.defaults.get(name)
        if default is None:
            row.append(0.5)
            continue
        value = float(np.atleast_1d(np.asarray(default, dtype=float))[max(comp, 0)])
        row.append((value - lo) / (hi - lo) if hi > lo else 0.0)
    return np.asarray(row, dtype=float)[None, :]


def _guards(decl: ast.Concept) -> dict[int, list[tuple[ast.Expr, bool]]]:
    """For every node below an ``if``: the conditions (and their truth) under which it counts."""
    out: dict[int, list[tuple[ast.Expr, bool]]] = {}
    stack: list[tuple[ast.Expr, list[tuple[ast.Expr, bool]]]] = [
        (t, []) for trees, _ in _roots(decl) for t in trees
    ]
    while stack:
        node, path = stack.pop()
        out[id(node)] = path
        if isinstance(node, ast.IfExpr):
            stack += [(node.cond, path), (node.then, [*path, (node.cond, True)])]
            stack.append((node.orelse, [*path, (node.cond, False)]))
        else:
            stack += [(c, path) for c in ast._children(node)]
    return out


def _witness(
    c: _Candidate, seen: dict[int, Any], mask: np.ndarray, n: int, types: dict[int, Type]
) -> str | None:
    """A description of the value that shows the problem at an allowed point, with its index
    appended as ``@i``; None when no allowed point shows it."""
    if not mask.any():
        return None
    node = c.node
    if c.check == "divisor":
        assert isinstance(node, ast.Binary)
        den = _array(seen.get(id(node.right)), n)
        zero = mask & (den == 0)
        if zero.any():
            return f"the divisor is 0@{int(np.argmax(zero))}"
        if _has_branch(node.right):
            return None
        neg, pos = mask & (den < 0), mask & (den > 0)
        if neg.any() and pos.any():
            return f"the divisor crosses 0: it is negative@{int(np.argmax(neg))}"
        return None
    if c.check == "sqrt":
        assert isinstance(node, ast.Call)
        arg = _array(seen.get(id(node.args[0].value)), n)
        scale = float(np.nanmax(np.abs(np.where(mask, arg, 0.0)))) or 1.0
        bad = mask & (arg < -1e-9 * scale)
        if bad.any():
            i = int(np.argmax(bad))
            return f"the argument is {_shown(float(arg[i]), types.get(id(node.args[0].value)))}@{i}"
        return None
    if c.check == "finite":
        value = seen.get(id(node))
        if value is None:
            return None
        ok = _finite_rows(value, n)
        for child in ast._children(node):
            ok_child = _finite_rows(seen.get(id(child), 0.0), n)
            ok |= ~ok_child  # only where every operand is finite
        bad = mask & ~ok
        if bad.any():
            return f"it is not finite@{int(np.argmax(bad))}"
        return None
    value = seen.get(id(node))
    if value is None:
        return None
    rows = np.stack([_array(v, n) for v in (value if isinstance(value, tuple) else (value,))])
    lo = np.atleast_1d(np.asarray(c.lo, dtype=float))[:, None]
    hi = np.atleast_1d(np.asarray(c.hi, dtype=float))[:, None]
    bad = mask & np.any((rows < lo - 1e-12) | (rows > hi + 1e-12), axis=0)
    if bad.any():
        i = int(np.argmax(bad))
        shown = format_si(tuple(rows[:, i]) if len(rows) > 1 else rows[0, i], c.dim)
        return f"it is {shown}@{i}"
    return None


def _warning(
    c: _Candidate, concept: CheckedConcept, env: dict[str, Any], witness: str
) -> Diagnostic:
    what, _, index = witness.rpartition("@")
    at = _where(c.node, concept, env, int(index))
    if c.code == "E233":
        msg = "division by an interval containing 0: the divisor reaches 0 inside the ranges"
        hint = f"{what} {at}; keep the divisor away from 0 with the ranges or a `require`"
    elif c.code == "E234":
        msg = "square root of an interval reaching below 0 inside the ranges"
        hint = f"{what} {at}; narrow the ranges or add a `require` that keeps it >= 0"
    elif c.code == "E235":
        msg = "this value overflows or is undefined inside the ranges"
        hint = f"{what} {at}; narrow the ranges"
    else:
        lo, hi = format_si(c.lo, c.dim), format_si(c.hi, c.dim)
        msg = f"{c.what} leaves its range [{lo}, {hi}] inside the declared ranges"
        hint = f"{what} {at}; narrow the ranges or add a `require`"
    return Diagnostic(c.code, msg, c.node.span, hint, "warning")


def _where(node: ast.Expr, concept: CheckedConcept, env: dict[str, Any], i: int) -> str:
    """``at r = 0mm, h = 5mm``: the parameters the expression reads (else all), at point i."""
    read = [n for n in dict.fromkeys(reads(node)) if n in env]
    names = read or [n for n in env if "." not in n][:4] or list(env)[:4]
    shown = []
    for name in names:
        value = env[name]
        v = tuple(float(x[i]) for x in value) if isinstance(value, tuple) else float(value[i])
        t = concept.param_types.get(name)
        if t is not None and t.kind == "choice":
            shown.append(f'{name} = "{t.choices[int(v)]}"')  # type: ignore[arg-type]
        elif t is not None and t.kind == "bool":
            shown.append(f"{name} = {'true' if v else 'false'}")
        else:
            shown.append(f"{name} = {format_si(v, t.dim if t is not None else '')}")
    return "at " + ", ".join(shown) if shown else "at the defaults"


def _shown(value: float, t: Type | None) -> str:
    """A value in mm-based units: ``-5520mm^2`` for an area."""
    k = t.dim.length if t is not None else 0
    if k in (0, 1) or t is None:
        return format_si(value, t.dim if t is not None else "")
    return f"{value * 1000.0**k:g}mm^{k}"


def _has_branch(e: ast.Expr) -> bool:
    return any(isinstance(n, ast.IfExpr) for n in _nodes([e]))


def _finite_rows(value: Any, n: int) -> np.ndarray:
    if isinstance(value, str):
        return np.ones(n, dtype=bool)
    if isinstance(value, tuple):
        ok = np.ones(n, dtype=bool)
        for v in value:
            ok &= _finite_rows(v, n)
        return ok
    return np.isfinite(_array(value, n))


def _array(value: Any, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(value, dtype=float), (n,))


def _zip(f: Callable[[Any, Any], Any], a: Any, b: Any) -> Any:
    if isinstance(a, tuple):
        return tuple(_zip(f, x, y) for x, y in zip(a, b))
    return f(a, b)
