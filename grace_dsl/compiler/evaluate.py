"""Lower a type-checked expression to a backend value: one implementation, three backends.

Values are backend scalars, tuples (vectors), 3x3 tuples (rotations), 4x4 tuples (poses),
conditions, and Python strings for choice literals.  The checker's type table tells how to
combine them; the expression is never turned into text or evaluated as Python.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any

from grace_dsl.compiler import se3
from grace_dsl.compiler.backends import Backend
from grace_dsl.compiler.types import PART, Type
from grace_dsl.lang import ast

TypeTable = Mapping[int, Type]
Needs = Callable[[str], Iterable[str]]  # an on-demand name -> the on-demand names it reads


class Evaluator:
    """Evaluates expressions under ``env`` (name -> value); ``lazy`` supplies values on demand.

    ``needs`` tells which on-demand names a definition reads.  With it, a name's definitions are
    computed dependencies first, each once, so a chain of a thousand ``let``s costs no Python
    recursion beyond one expression's depth."""

    def __init__(
        self,
        backend: Backend,
        types: TypeTable,
        env: Mapping[str, Any],
        lazy: Callable[[str], Any] | None = None,
        parts: frozenset[str] = frozenset(),
        needs: Needs | None = None,
        observe: Callable[[ast.Expr, Any], None] | None = None,
    ):
        self.b = backend
        self.types = types
        self.env = dict(env)
        self.lazy = lazy
        self.parts = parts  # names whose members are parameters of a part: ``handle.r_in``
        self.needs = needs
        self.observe = observe  # called with every expression node and its value
        self._computing: set[str] = set()

    def with_names(self, extra: Mapping[str, Any]) -> Evaluator:
        """The same evaluator with more names bound (a grasp's free parameters)."""
        env = {**self.env, **extra}
        return Evaluator(self.b, self.types, env, self.lazy, self.parts, self.needs, self.observe)

    def type_of(self, e: ast.Expr) -> Type:
        return self.types[id(e)]

    def __call__(self, e: ast.Expr) -> Any:
        method: Callable[[Any], Any] = getattr(self, "_" + type(e).__name__.lower())
        value = method(e)
        if self.observe is not None:
            self.observe(e, value)
        return value

    # -- leaves
    def _number(self, e: ast.Number) -> Any:
        return self.b.literal(e)

    def _string(self, e: ast.String) -> Any:
        return e.value

    def _bool(self, e: ast.Bool) -> Any:
        return self.b.boolean(e.value)

    def _name(self, e: ast.Name) -> Any:
        if e.id == "pi" and e.id not in self.env:
            return self.b.pi
        return self.lookup(e.id)

    def lookup(self, name: str) -> Any:
        """The value of a name (or ``part.param``), computed on demand and then remembered."""
        if name in self.env:
            return self.env[name]
        if self.lazy is None:
            raise KeyError(name)
        for dep in self._unready(name):
            if dep not in self.env:
                self._computing.add(dep)
                try:
                    value = self.lazy(dep)
                finally:
                    self._computing.discard(dep)
                self.env[dep] = value
        return self.env[name]

    def _unready(self, name: str) -> list[str]:
        """``name`` and the not yet computed definitions it reads, dependencies first.

        An iterative depth-first walk; a name met again while on the walk (a cycle) or being
        computed is left out, so the on-demand function still meets, and reports, the cycle."""
        if self.needs is None:
            return [name]
        order: list[str] = []
        seen = {name}
        stack: list[tuple[str, Iterator[str]]] = [(name, iter(self.needs(name)))]
        while stack:
            node, deps = stack[-1]
            for dep in deps:
                if dep not in seen and dep not in self.env and dep not in self._computing:
                    seen.add(dep)
                    stack.append((dep, iter(self.needs(dep))))
                    break
            else:
                stack.pop()
                order.append(node)
        return order

    def _vector(self, e: ast.Vector) -> Any:
        return tuple(self(x) for x in e.items)

    def _member(self, e: ast.Member) -> Any:
        if isinstance(e.obj, ast.Name) and e.obj.id in self.parts:
            return self.lookup(f"{e.obj.id}.{e.field}")  # a part's parameter
        if self.types.get(id(e.obj)) == PART:  # a nested part's parameter: left.handle.length
            return self.lookup(f"{dotted(e.obj)}.{e.field}")
        return self(e.obj)["xyz".index(e.field)]

    def _ifexpr(self, e: ast.IfExpr) -> Any:
        cond, a, b = self(e.cond), self(e.then), self(e.orelse)
        return _zip_apply(lambda x, y: self.b.if_else(cond, x, y), a, b)

    # -- operators
    def _unary(self, e: ast.Unary) -> Any:
        v = self(e.operand)
        if e.op == "not":
            return self.b.not_(v)
        return _map(lambda x: -x, v) if e.op == "-" else v

    def _binary(self, e: ast.Binary) -> Any:
        if e.op == "and":
            return self.b.and_(self(e.left), self(e.right))
        if e.op == "or":
            return self.b.or_(self(e.left), self(e.right))
        lt, rt = self.type_of(e.left), self.type_of(e.right)
        a, b = self(e.left), self(e.right)
        if e.op in ast.COMPARISONS:
            return self._compare(e.op, lt, a, rt, b)
        if e.op == "+":
            return _zip_apply(lambda x, y: x + y, a, b)
        if e.op == "-":
            return _zip_apply(lambda x, y: x - y, a, b)
        if e.op == "^":
            return self.b.pow(a, b)
        if e.op == "/":
            return _map(lambda x: x / b, a)
        return self._multiply(lt, a, rt, b)

    def _compare(self, op: str, lt: Type, a: Any, rt: Type, b: Any) -> Any:
        if isinstance(a, str) and isinstance(b, str):  # a part's choice bound to an option
            return self.b.boolean((a == b) == (op == "=="))
        if isinstance(a, str) or isinstance(b, str):
            (choice_t, index), text = ((lt, a), b) if isinstance(b, str) else ((rt, b), a)
            code = self.b.num(float(choice_t.choices.index(text)))
            return self.b.compare(op, index, code)
        if lt.kind == "bool":
            a, b = self.b.as_number(a), self.b.as_number(b)
        return self.b.compare(op, a, b)

    def _multiply(self, lt: Type, a: Any, rt: Type, b: Any) -> Any:
        if lt.kind == "num":
            return _map(lambda y: a * y, b)
        if rt.kind == "num":
            return _map(lambda x: x * b, a)
        if rt.kind == "vec":
            return se3.matvec(a, b) if lt.kind == "rot" else se3.transform_point(a, b)
        if lt.kind == rt.kind:
            return se3.matmul(a, b)
        if lt.kind == "rot":  # rot * pose
            return se3.matmul(se3.pose(a, (0, 0, 0)), b)
        return se3.matmul(a, se3.pose(b, (0, 0, 0)))  # pose * rot

    # -- calls
    def _call(self, e: ast.Call) -> Any:
        args = [self(a.value) for a in e.args]
        return BUILTINS[e.func](self.b, [self.type_of(a.value) for a in e.args], *args)


def dotted(e: ast.Expr) -> str:
    """``left.handle`` for a chain of member accesses on a name."""
    fields: list[str] = []
    while isinstance(e, ast.Member):
        fields.append(e.field)
        e = e.obj
    assert isinstance(e, ast.Name)
    return ".".join([e.id, *reversed(fields)])


def reads(e: ast.Expr) -> Iterator[str]:
    """Every name an expression reads, and every member chain on a name whole (``handle.r_in``,
    ``left.handle.length``, and also ``size.x``: callers filter by what they know)."""
    stack: list[ast.Expr] = [e]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Name):
            yield node.id
        elif isinstance(node, ast.Member):
            root = node.obj
            while isinstance(root, ast.Member):
                root = root.obj
            if isinstance(root, ast.Name):
                yield dotted(node)
        stack += ast._children(node)


def _map(f: Callable[[Any], Any], v: Any) -> Any:
    if isinstance(v, tuple):
        return tuple(_map(f, x) for x in v)
    return f(v)


def _zip_apply(f: Callable[[Any, Any], Any], a: Any, b: Any) -> Any:
    if isinstance(a, tuple):
        return tuple(_zip_apply(f, x, y) for x, y in zip(a, b))
    return f(a, b)


def _norm(b: Backend, v: tuple[Any, ...]) -> Any:
    total = v[0] * v[0]
    for x in v[1:]:
        total = total + x * x
    return b.sqrt(total)


def _dot(v: tuple[Any, ...], w: tuple[Any, ...]) -> Any:
    total = v[0] * w[0]
    for x, y in zip(v[1:], w[1:]):
        total = total + x * y
    return total


def _trans(b: Backend, types: list[Type], *args: Any) -> Any:
    t = args[0] if len(args) == 1 else tuple(args)
    return se3.translation(t)


def _rpy(b: Backend, types: list[Type], r: Any, p: Any, y: Any) -> Any:
    rx = se3.rot_x(b.cos(r), b.sin(r))
    ry = se3.rot_y(b.cos(p), b.sin(p))
    rz = se3.rot_z(b.cos(y), b.sin(y))
    return se3.matmul(rz, se3.matmul(ry, rx))


def _axis_angle(b: Backend, types: list[Type], axis: Any, a: Any) -> Any:
    n = _norm(b, axis)
    unit = tuple(x / n for x in axis)
    return se3.axis_angle(unit, b.cos(a), b.sin(a))


def _rotation(make: Callable[[Any, Any], Any]) -> Callable[..., Any]:
    return lambda b, types, a: make(b.cos(a), b.sin(a))


def _inv(b: Backend, types: list[Type], m: Any) -> Any:
    return se3.invert(m)


def _clamp(b: Backend, types: list[Type], x: Any, lo: Any, hi: Any) -> Any:
    return b.min(b.max(x, lo), hi)


BUILTINS: dict[str, Callable[..., Any]] = {
    "sin": lambda b, t, x: b.sin(x),
    "cos": lambda b, t, x: b.cos(x),
    "tan": lambda b, t, x: b.tan(x),
    "asin": lambda b, t, x: b.asin(x),
    "acos": lambda b, t, x: b.acos(x),
    "atan2": lambda b, t, y, x: b.atan2(y, x),
    "sqrt": lambda b, t, x: b.sqrt(x),
    "abs": lambda b, t, x: _map(b.abs, x),
    "min": lambda b, t, x, y: _zip_apply(b.min, x, y),
    "max": lambda b, t, x, y: _zip_apply(b.max, x, y),
    "clamp": _clamp,
    "dot": lambda b, t, v, w: _dot(v, w),
    "cross": lambda b, t, v, w: se3.cross(v, w),
    "norm": lambda b, t, v: _norm(b, v),
    "normalize": lambda b, t, v: tuple(x / _norm(b, v) for x in v),
    "rotx": _rotation(se3.rot_x),
    "roty": _rotation(se3.rot_y),
    "rotz": _rotation(se3.rot_z),
    "rpy": _rpy,
    "axis_angle": _axis_angle,
    "trans": _trans,
    "inv": _inv,
}


def definition_needs(
    lets: Mapping[str, ast.Let],
    args: Mapping[str, ast.Expr],
    shapes: Mapping[str, ast.Shape],
) -> Needs:
    """``needs`` for a concept's on-demand names: lets, part arguments (``handle.length``) and
    shape cues (``bar.center``, defined by the shape's arguments and placement)."""

    def exprs_of(name: str) -> list[ast.Expr] | None:
        if name in lets:
            return [lets[name].value]
        if name in args:
            return [args[name]]
        head, _, field = name.partition(".")
        shape = shapes.get(head)
        if shape is None or not field:
            return None
        return [shape.value, *([shape.at] if shape.at is not None else [])]

    def needs(name: str) -> Iterator[str]:
        for e in exprs_of(name) or ():
            for n in ast.dotted_names_in(e):
                if exprs_of(n) is not None:
                    yield n

    return needs
