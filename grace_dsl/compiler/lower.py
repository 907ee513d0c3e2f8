"""Lower pass: a checked concept -> a flat kinematic model over one backend's values.

Parts are flattened into their host: the links, joints, shapes, grasps and actions of a part get
qualified names (``handle.pull``), its base link hangs on the host link through its placement, and
its parameters are either bound by the part's arguments or lifted into the host as parameters of
their own (``handle.r_in``), so perception can estimate them.

Every link frame coincides with the frame of the concept that declares it when all joints are
closed (q = 0): the concept frame for the concept's own links, the part's placed frame for a
part's links.  A joint moves its child as ``T(o) * M(s q) * T(-o)`` where o is the joint origin
and s its opening sense; ``JointInfo.axis`` already carries that sense.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import PurePath
from typing import Any

from grace_dsl.compiler import se3
from grace_dsl.compiler.backends import Backend
from grace_dsl.compiler.check import VERBS, Checked, CheckedConcept
from grace_dsl.compiler.cues import shape_cue
from grace_dsl.compiler.evaluate import Evaluator, definition_needs, reads
from grace_dsl.compiler.resolve import BASE_LINK
from grace_dsl.compiler.types import Type
from grace_dsl.lang import ast
from grace_dsl.lang.formatter import format_expr

MakeSymbol = Callable[[str, str], Any]  # (kind "p" | "q" | "g", qualified name)


@dataclass(frozen=True)
class ParamInfo:
    name: str  # qualified: "handle.r_in"
    type: Type
    size: int  # number of scalars in the parameter vector
    lo: Any  # SI float or tuple, None without a range
    hi: Any
    default: Any
    help: str | None
    doc: str


@dataclass(frozen=True)
class JointInfo:
    name: str
    kind: str
    parent: str
    child: str
    lo: Any  # backend value (may depend on parameters); None for continuous/fixed
    hi: Any
    axis: Any  # unit axis in the concept frame at the current q of its parent (backend tuple)
    origin: Any  # a point on the axis, concept frame (backend tuple)
    doc: str
    where: str = ""  # ``file.eac:line`` of the declaration
    range_where: str = ""  # ``file.eac:line`` of its range


@dataclass(frozen=True)
class FreeInfo:
    name: str
    type: Type
    lo: Any
    hi: Any
    default: Any


@dataclass(frozen=True)
class GraspInfo:
    name: str
    link: str
    free: tuple[FreeInfo, ...]
    symbols: tuple[Any, ...]
    pose: Any  # 4x4 tuple in the concept frame
    width: Any  # backend value or None
    doc: str
    source: ast.Grasp
    mode: str = "pinch"
    axis: Any = None  # the symmetry axis in the grasp frame (3 backend values), or None
    when: WhenInfo | None = None  # where the family applies (None: everywhere)


@dataclass(frozen=True)
class WhenInfo:
    """A grasp's ``when`` condition over (p, q): compiled like a requirement's residual."""

    residual: Any  # <= 0 where the family applies (how far from applying, for a search)
    holds: Any  # 1 where the condition is true, else 0: the exact test, strict `<` included
    condition: str  # as the formatter writes it, in the declaring concept's names
    joints: tuple[str, ...]  # the qualified joints it reads
    where: str  # ``file.eac:line`` of the condition


@dataclass(frozen=True)
class ActionInfo:
    name: str
    verb: str
    joint: str | None
    sign: int  # +1: along q increasing (opening), -1: closing
    direction: Any  # explicit direction, unit 3-tuple in the concept frame (or None)
    using: tuple[str, ...]
    doc: str
    where: str = ""  # ``file.eac:line`` of the declaration (of its direction, if explicit)


@dataclass(frozen=True)
class ShapeInfo:
    name: str
    link: str
    primitive: str  # primitive name, or "union"/"difference"
    args: dict[str, Any]  # primitive parameter -> backend value (SI)
    operands: tuple[str, ...]  # for set operations: qualified shape names
    pose: Any  # 4x4 in the concept frame
    at: Any = None  # 4x4 placement in its declaring frame (what its `at` says; None: identity)
    where: str = ""  # ``file.eac:line`` of the declaration


@dataclass(frozen=True)
class RequireInfo:
    residual: Any  # <= 0 when the requirement holds (a measure of violation, for fitting)
    holds: Any  # 1 when the condition is true, else 0: the exact test, strict `<` included
    message: str
    source: str
    condition: str = ""  # the condition as the formatter writes it
    reads: tuple[str, ...] = ()  # qualified names the condition reads (some are parameters)


@dataclass
class Lowered:
    """The flat model of a concept over one backend."""

    name: str
    doc: str
    params: list[ParamInfo] = field(default_factory=list)
    p: list[Any] = field(default_factory=list)
    q: list[Any] = field(default_factory=list)
    links: dict[str, Any] = field(default_factory=dict)
    link_docs: dict[str, str] = field(default_factory=dict)
    joints: list[JointInfo] = field(default_factory=list)
    grasps: dict[str, GraspInfo] = field(default_factory=dict)
    actions: dict[str, ActionInfo] = field(default_factory=dict)
    shapes: list[ShapeInfo] = field(default_factory=list)
    requires: list[RequireInfo] = field(default_factory=list)
    parts: dict[str, str] = field(default_factory=dict)  # qualified part -> concept
    # repeated and variant members (``compiler/expand.py``), qualified: when each exists, as
    # [(count parameter, k): count > k | (choice parameter, option): choice == option]
    masks: dict[str, list[tuple[str, int | str]]] = field(default_factory=dict)
    # variant part -> (its choice parameter, {option: the part that option places})
    variants: dict[str, tuple[str, dict[str, str]]] = field(default_factory=dict)


# A value a host binds, computed when first read: a part's argument may read a sibling part's
# parameters, nested ones included (``drawer1.handle.radius``), so no part's values can be
# computed before every part's scope exists.
Binding = Callable[[], Any]


@dataclass(frozen=True)
class _Scope:
    """One concept or part being flattened: its evaluator and its parts' scopes."""

    cc: CheckedConcept
    prefix: str
    ev: Evaluator
    parts: dict[str, _Scope]
    lifted: frozenset[str] = frozenset()  # its parameters lifted into the flat model
    bound: dict[str, Binding] = field(default_factory=dict)  # the values its host binds


def lower(checked: Checked, name: str, backend: Backend, make_symbol: MakeSymbol) -> Lowered:
    """Flatten concept ``name`` into a ``Lowered`` model whose inputs are fresh symbols."""
    cc = checked.concepts[name]
    out = Lowered(name, cc.decl.doc)
    _Instance(checked, backend, make_symbol, out).build(cc, "", {}, se3.identity(4), BASE_LINK)
    return out


def symbol_names(param: ParamInfo) -> list[str]:
    """Names of the scalar entries of a parameter (``size.x``, ``size.y``, ...)."""
    if param.size == 1:
        return [param.name]
    return [f"{param.name}.{c}" for c in "xyz"[: param.size]]


class _Instance:
    def __init__(self, checked: Checked, backend: Backend, make_symbol: MakeSymbol, out: Lowered):
        self.checked, self.b, self.sym, self.out = checked, backend, make_symbol, out
        self.joint_values: dict[str, Any] = {}  # qualified moving joint -> its q symbol

    def build(
        self,
        cc: CheckedConcept,
        prefix: str,
        bindings: dict[str, Any],
        host_pose: Any,
        host_link: str,
    ) -> None:
        self._emit(self._scope(cc, prefix, bindings), host_pose, host_link)

    def _scope(self, cc: CheckedConcept, prefix: str, bindings: dict[str, Binding]) -> _Scope:
        """The evaluator of a concept (or part) and, recursively, of its parts.

        ``bindings`` gives the concept's parameters that its host binds, and with dotted keys
        (``handle.length``) parameters of its nested parts; the others are lifted.  Parts'
        scopes are made here, depth first, before any bound value is computed: bound values
        are read on demand, so an argument can read ``left.handle.length`` of a sibling part
        declared before or after it (the checker rejects cycles, E119)."""
        decl = cc.decl
        env: dict[str, Any] = {}
        for p in (m for m in decl.members if isinstance(m, ast.Param)):
            if p.name not in bindings:
                env[p.name] = self._lift(cc, p, prefix)
        lets = {m.name: m for m in _all(decl) if isinstance(m, ast.Let)}
        parts = [m for m in _all(decl) if isinstance(m, ast.Part)]
        args = {f"{m.name}.{a.name}": a.value for m in parts for a in m.args if a.name}
        shapes = {m.name: m for m in _all(decl) if isinstance(m, ast.Shape)}
        scopes: dict[str, _Scope] = {}

        def on_demand(name: str) -> Any:  # bound values, lets, part arguments, shape cues
            if name in bindings:
                return bindings[name]()
            head, _, field = name.partition(".")
            if head in shapes:
                return self._cue(shapes[head], field, ev)
            if name in lets or name in args:
                return ev(lets[name].value if name in lets else args[name])
            return scopes[head].ev.lookup(field)  # a nested part's parameter: left.handle.length

        qualified = frozenset([*(m.name for m in parts), *shapes])
        needs = definition_needs(lets, args, shapes)
        ev = Evaluator(self.b, self.checked.types, env, on_demand, qualified, needs)
        bound = {m.name: self._part_bindings(m, prefix, ev, bindings) for m in parts}
        for m in parts:
            sub = self.checked.concepts[m.concept]
            scopes[m.name] = self._scope(sub, f"{prefix}{m.name}.", bound[m.name])
        lifted = frozenset(p.name for p in decl.members if isinstance(p, ast.Param)) - set(bindings)
        return _Scope(cc, prefix, ev, scopes, lifted, bindings)

    def _emit(self, scope: _Scope, host_pose: Any, host_link: str) -> None:
        """Links, joints, shapes, grasps, parts, actions and requirements of a scope."""
        cc, prefix, ev = scope.cc, scope.prefix, scope.ev
        decl = cc.decl
        self._masks(scope)
        # links and joints
        link_of = {BASE_LINK: host_link}
        for link in (m for m in decl.members if isinstance(m, ast.Link)):
            link_of[link.name] = prefix + link.name
            self.out.link_docs[prefix + link.name] = link.doc
        poses = {BASE_LINK: host_pose}
        self._joints(decl, prefix, ev, poses, link_of)
        for lname, pose in poses.items():
            if lname != BASE_LINK or not prefix:
                self.out.links[link_of[lname]] = pose
        # shapes, grasps and parts in link order
        for m, lname in _placed(decl):
            pose = poses[lname]
            if isinstance(m, ast.Shape):
                self._shape(m, prefix, link_of[lname], pose, ev)
            elif isinstance(m, ast.Grasp):
                self._grasp(cc, m, prefix, link_of[lname], pose, ev)
            elif isinstance(m, ast.Part):
                self._part(m, prefix, link_of[lname], pose, ev, scope.parts[m.name])
        for m in decl.members:
            if isinstance(m, ast.Action):
                self._action(m, prefix, ev, host_pose)
            elif isinstance(m, ast.Require):
                self._require(m, prefix, ev)

    def _masks(self, scope: _Scope) -> None:
        """A part's masks and variants, qualified: a condition on a lifted count or choice
        names it; one its host binds to a constant is decided here (the copy always or never
        exists: ``("", 0)``), and one bound to a host parameter names that parameter."""
        prefix = scope.prefix
        for name, cond in scope.cc.decl.masks:
            out: list[tuple[str, int | str]] = []
            for param, v in cond:
                if param in scope.lifted:
                    out.append((prefix + param, v))
                    continue
                value = _read(scope.bound, param)
                decided = _decide(value, v, scope.cc.param_types.get(param))
                if decided is False:
                    out = [("", 0)]
                    break
                host = _symbol_name(value)
                if decided is None and host is not None:
                    out.append((host, v))
            if out:
                self.out.masks[prefix + name] = out
        for name, (param, options) in scope.cc.decl.variants:
            host = (
                prefix + param if param in scope.lifted else _symbol_name(_read(scope.bound, param))
            )
            if host is not None:
                self.out.variants[prefix + name] = (
                    host,
                    {value: prefix + part for value, part in options},
                )

    # -- parameters
    def _lift(self, cc: CheckedConcept, p: ast.Param, prefix: str) -> Any:
        t = cc.param_types[p.name]
        lo, hi = cc.bounds.get(p.name, (None, None))
        info = ParamInfo(
            prefix + p.name,
            t,
            t.size if t.kind == "vec" else 1,
            lo,
            hi,
            cc.defaults.get(p.name),
            p.help,
            p.doc,
        )
        self.out.params.append(info)
        symbols = [self.sym("p", n) for n in symbol_names(info)]
        self.out.p += symbols
        return tuple(symbols) if t.kind == "vec" else symbols[0]

    def _part_bindings(
        self, part: ast.Part, prefix: str, ev: Evaluator, bindings: dict[str, Binding]
    ) -> dict[str, Binding]:
        """Every parameter of a part: its argument's value, a value the host's host binds
        (``bindings["handle.length"]``), or a lifted parameter of the host; and the values
        bound for the part's own nested parts (``grip.size``), each read from ``ev`` when
        first needed.

        Lifting comes first, in declaration order, so the parameter vector's layout does not
        depend on which arguments read which part parameters."""
        sub = self.checked.concepts[part.concept]
        given = {a.name for a in part.args if a.name is not None}
        own = f"{part.name}."
        params = [m for m in sub.decl.members if isinstance(m, ast.Param)]
        for p in params:
            if own + p.name not in bindings and p.name not in given:
                ev.env[own + p.name] = self._lift(sub, p, prefix + own)
        out = {p.name: _reader(ev, own + p.name) for p in params}
        for name in given:
            if "." in name:
                out[name] = _reader(ev, own + name)
        for key, value in bindings.items():
            if key.startswith(own) and "." in key[len(own) :]:
                out[key[len(own) :]] = value
        return out

    # -- kinematics
    def _joints(
        self,
        decl: ast.Concept,
        prefix: str,
        ev: Evaluator,
        poses: dict[str, Any],
        link_of: dict[str, str],
    ) -> None:
        pending = [m for m in decl.members if isinstance(m, ast.Joint)]
        while pending:
            ready = [j for j in pending if j.parent in poses]
            if not ready:
                raise AssertionError("joint tree not checked")  # resolve guarantees a tree
            for j in ready:
                pending.remove(j)
                poses[j.child] = self._joint(j, prefix, ev, poses[j.parent], link_of)

    def _joint(
        self, j: ast.Joint, prefix: str, ev: Evaluator, parent_pose: Any, link_of: dict[str, str]
    ) -> Any:
        name = prefix + j.name
        sign = j.opens if j.opens is not None else 1
        if j.kind == "fixed":
            self.out.joints.append(
                JointInfo(
                    name,
                    j.kind,
                    link_of[j.parent],
                    link_of[j.child],
                    None,
                    None,
                    None,
                    None,
                    j.doc,
                    where(j.span),
                )
            )
            return parent_pose
        qv = self.sym("q", name)
        self.out.q.append(qv)
        self.joint_values[name] = qv
        assert j.axis is not None
        axis = _unit(self.b, ev(j.axis))
        origin = ev(j.origin) if j.origin is not None else (0, 0, 0)
        if j.kind == "prismatic":
            motion = se3.translation(tuple(a * (sign * qv) for a in axis))
        else:
            angle = sign * qv
            rot = se3.axis_angle(axis, self.b.cos(angle), self.b.sin(angle))
            back = tuple(-o for o in origin)
            motion = se3.matmul(
                se3.translation(origin), se3.matmul(se3.pose(rot, (0, 0, 0)), se3.translation(back))
            )
        lo = ev(j.limits.lo) if j.limits is not None else None
        hi = ev(j.limits.hi) if j.limits is not None else None
        rot_parent = se3.rotation_of(parent_pose)
        world_axis = tuple(sign * a for a in se3.matvec(rot_parent, axis))
        world_origin = se3.transform_point(parent_pose, origin)
        self.out.joints.append(
            JointInfo(
                name,
                j.kind,
                link_of[j.parent],
                link_of[j.child],
                lo,
                hi,
                world_axis,
                world_origin,
                j.doc,
                where(j.span),
                where(j.limits.span) if j.limits is not None else "",
            )
        )
        return se3.matmul(parent_pose, motion)

    # -- geometry and manipulation
    def _cue(self, s: ast.Shape, field: str, ev: Evaluator) -> Any:
        v = s.value
        assert isinstance(v, ast.Call)
        prim = self.checked.concepts.get(v.func)
        defaults = {k: _as_backend(self.b, x) for k, x in prim.defaults.items()} if prim else {}
        return shape_cue(self.b, ev, s, defaults, field)

    def _shape(self, s: ast.Shape, prefix: str, link: str, link_pose: Any, ev: Evaluator) -> None:
        v = s.value
        assert isinstance(v, ast.Call)
        local = se3.identity(4) if s.at is None else _as_pose(ev(s.at))
        pose = link_pose if s.at is None else se3.matmul(link_pose, local)
        if v.func in ("union", "difference"):
            operands = tuple(prefix + a.value.id for a in v.args if isinstance(a.value, ast.Name))
            self.out.shapes.append(
                ShapeInfo(prefix + s.name, link, v.func, {}, operands, pose, local, where(s.span))
            )
            return
        prim = self.checked.concepts[v.func]
        args = dict(prim.defaults)
        args.update({a.name: ev(a.value) for a in v.args if a.name is not None})
        args = {k: _as_backend(self.b, val) for k, val in args.items()}
        self.out.shapes.append(
            ShapeInfo(prefix + s.name, link, v.func, args, (), pose, local, where(s.span))
        )

    def _grasp(
        self,
        cc: CheckedConcept,
        g: ast.Grasp,
        prefix: str,
        link: str,
        link_pose: Any,
        ev: Evaluator,
    ) -> None:
        name = prefix + g.name
        free, symbols = [], []
        for fp in g.free:
            sym = self.sym("g", f"{name}:{fp.name}")
            lo, hi = ev(fp.lo), ev(fp.hi)
            default = ev(fp.default) if fp.default is not None else (lo + hi) / 2
            free.append(FreeInfo(fp.name, cc.free_types[g.name][fp.name], lo, hi, default))
            symbols.append(sym)
        free_env = dict(zip((f.name for f in g.free), symbols))
        sub = ev.with_names(free_env)
        pose = se3.matmul(link_pose, _as_pose(sub(g.pose)))
        width = sub(g.width) if g.width is not None else None
        axis = None
        if g.symmetric:
            axis = tuple(sub(g.about)) if g.about is not None else (0.0, 0.0, 1.0)
        when = self._when(cc, g.when, prefix, ev) if g.when is not None else None
        self.out.grasps[name] = GraspInfo(
            name,
            link,
            tuple(free),
            tuple(symbols),
            pose,
            width,
            g.doc,
            g,
            g.mode or "pinch",
            axis,
            when,
        )

    def _when(self, cc: CheckedConcept, cond: ast.Expr, prefix: str, ev: Evaluator) -> WhenInfo:
        """A ``when`` condition with the declaring concept's joints bound to their values (the
        joints are emitted before the grasps, so a part's are known under its prefix)."""
        joints = {
            m.name: self.joint_values[prefix + m.name]
            for m in _all(cc.decl)
            if isinstance(m, ast.Joint) and prefix + m.name in self.joint_values
        }
        sub = ev.with_names(joints)
        read = tuple(prefix + n.id for n in ast.names_in(cond) if n.id in joints)
        return WhenInfo(
            residual(self.b, sub, cond),
            self.b.as_number(sub(cond)),
            format_expr(cond),
            tuple(dict.fromkeys(read)),
            where(cond.span),
        )

    def _part(
        self,
        m: ast.Part,
        prefix: str,
        link: str,
        link_pose: Any,
        ev: Evaluator,
        scope: _Scope,
    ) -> None:
        host = link_pose if m.at is None else se3.matmul(link_pose, _as_pose(ev(m.at)))
        self.out.parts[prefix + m.name] = m.concept
        self._emit(scope, host, link)

    def _action(self, a: ast.Action, prefix: str, ev: Evaluator, frame: Any) -> None:
        sense = a.sense or VERBS[a.verb]
        direction = None
        if a.direction is not None:
            direction = _unit(self.b, se3.matvec(se3.rotation_of(frame), ev(a.direction)))
        joint = prefix + a.joint if a.joint else None
        self.out.actions[prefix + a.name] = ActionInfo(
            prefix + a.name,
            a.verb,
            joint,
            1 if sense == "opening" else -1,
            direction,
            tuple(prefix + u for u in a.using),
            a.doc,
            where(a.direction.span if a.direction is not None else a.span),
        )

    def _require(self, r: ast.Require, prefix: str, ev: Evaluator) -> None:
        where = f"{prefix.rstrip('.')}: " if prefix else ""
        self.out.requires.append(
            RequireInfo(
                residual(self.b, ev, r.cond),
                self.b.as_number(ev(r.cond)),
                where + (r.message or ""),
                _brief(r),
                format_expr(r.cond),
                tuple(dict.fromkeys(prefix + n for n in reads(r.cond))),
            )
        )


def _reader(ev: Evaluator, name: str) -> Binding:
    """A binding that reads ``name`` from the host's evaluator."""
    return lambda: ev.lookup(name)


def _read(bound: dict[str, Binding], name: str) -> Any:
    """The value a host binds to ``name``, or None when it binds none."""
    return bound[name]() if name in bound else None


def _decide(value: Any, v: int | str, t: Type | None) -> bool | None:
    """Whether a mask's condition holds for a value its host binds, when that is a constant
    (a count above k; a choice equal to the option), else None."""
    if isinstance(value, str):
        return value == v
    number = _constant(value)
    if number is None:
        return None
    if isinstance(v, str):
        choices = t.choices if t is not None else ()
        return v in choices and number == choices.index(v)
    return number > v


def _constant(value: Any) -> float | None:
    if isinstance(value, (int, float)):
        return float(value)
    is_constant = getattr(value, "is_constant", None)  # CasADi SX
    if callable(is_constant) and is_constant():
        return float(value)
    if getattr(value, "is_Number", False):  # SymPy
        return float(value)
    return None


def _symbol_name(value: Any) -> str | None:
    """The host parameter a bound value is, when it is one parameter's symbol."""
    is_symbolic = getattr(value, "is_symbolic", None)  # CasADi SX
    if callable(is_symbolic) and is_symbolic():
        return str(value.name())
    if getattr(value, "is_Symbol", False):  # SymPy
        return str(value)
    return None


def residual(b: Backend, ev: Evaluator, cond: ast.Expr) -> Any:
    """A number that is <= 0 exactly when ``cond`` holds, scaled like the compared quantities."""
    if isinstance(cond, ast.Binary) and cond.op in ("<", "<=", ">", ">="):
        left, right = ev(cond.left), ev(cond.right)
        if not isinstance(left, (tuple, str)):
            return left - right if cond.op in ("<", "<=") else right - left
    if isinstance(cond, ast.Binary) and cond.op in ("and", "or"):
        r1, r2 = residual(b, ev, cond.left), residual(b, ev, cond.right)
        return b.max(r1, r2) if cond.op == "and" else b.min(r1, r2)
    return b.if_else(ev(cond), b.num(-1.0), b.num(1.0))


def _brief(r: ast.Require) -> str:
    return where(r.cond.span)


def where(span: ast.Span) -> str:
    """``file.eac:line`` of a span (the file's name only), or "" without a position: what the
    manifest records so that runtime errors can point at the source of a formula."""
    return f"{PurePath(span.file).name}:{span.line}" if span.line else ""


def _unit(b: Backend, v: tuple[Any, ...]) -> tuple[Any, ...]:
    total = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    n = b.sqrt(total)
    return tuple(x / n for x in v)


def _as_pose(m: Any) -> Any:
    return se3.pose(m, (0, 0, 0)) if len(m) == 3 else m


def _as_backend(b: Backend, value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(_as_backend(b, v) for v in value)
    if isinstance(value, (int, float)):
        return b.num(float(value))
    return value


def _all(decl: ast.Concept) -> list[ast.Member_]:
    out: list[ast.Member_] = []
    for m in decl.members:
        out.append(m)
        if isinstance(m, ast.Link):
            out += list(m.members)
    return out


def _placed(decl: ast.Concept) -> list[tuple[ast.Member_, str]]:
    """Shapes, grasps and parts with the link they belong to."""
    out: list[tuple[ast.Member_, str]] = []
    for m in decl.members:
        if isinstance(m, ast.Link):
            out += [(x, m.name) for x in m.members if not isinstance(x, ast.Let)]
        elif isinstance(m, (ast.Shape, ast.Grasp, ast.Part)):
            out.append((m, BASE_LINK))
    return out
