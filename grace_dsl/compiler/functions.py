"""Turn a lowered concept into CasADi functions and SymPy formulas.

Every function takes the flat parameter vector ``p`` (SI units, in the order of the manifest's
parameters), and where relevant the joint values ``q``, the free grasp parameters ``g`` or a point
``x``.  Functions are keyed ``grasp:handle.pull``; their CasADi names are plain identifiers
(``f3_grasp``) so they can become C symbols.

``link_jac:NAME(p, q)`` and ``grasp_jac:NAME(p, q, g)`` return a pose ``T`` together with its
twist Jacobian ``J`` (6 x (nq [+ ng])), exact derivatives of the same SX graph: rows
``[v; w]`` with ``v = dt/dx`` the velocity of the frame's origin and ``w`` its angular velocity
(``dR/dx_i = [w_i]x R``), both along the concept frame's axes.  Robot IK solves in joints and
free grasp parameters with them (``grace_dsl.runtime.kinematics``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import casadi as ca

from grace_dsl import tolerances
from grace_dsl.compiler import se3
from grace_dsl.compiler.backends import CASADI
from grace_dsl.compiler.check import Checked
from grace_dsl.compiler.lower import Lowered, lower


def fn_key(kind: str, name: str = "") -> str:
    """The key of a function: ``kind`` (link, grasp, ...) and a qualified member name."""
    return kind if not name else f"{kind}:{name}"


@dataclass(frozen=True)
class Compiled:
    lowered: Lowered
    functions: dict[str, ca.Function]


def _column(xs: list[Any], name: str) -> Any:
    return ca.vertcat(*xs) if xs else ca.SX.sym(name, 0)


def _mat(rows: Any) -> Any:
    return ca.vertcat(*[ca.horzcat(*row) for row in rows])


def _vec(xs: Any) -> Any:
    return ca.vertcat(*xs) if len(xs) else ca.SX(0, 1)


def casadi_functions(checked: Checked, name: str) -> Compiled:
    """Lower concept ``name`` to CasADi SX and wrap every query as a ``casadi.Function``."""
    low = lower(checked, name, CASADI, lambda kind, sym: ca.SX.sym(sym))
    p, q = _column(low.p, "p"), _column(low.q, "q")
    fns: dict[str, ca.Function] = {}

    def add(key: str, inputs: list[tuple[str, Any]], outputs: list[tuple[str, Any]]) -> None:
        ident = f"f{len(fns)}_{key.split(':')[0]}"
        fns[key] = ca.Function(
            ident,
            [v for _, v in inputs],
            [v for _, v in outputs],
            [n for n, _ in inputs],
            [n for n, _ in outputs],
        )

    for link, pose in low.links.items():
        t_link = _mat(pose)
        add(fn_key("link", link), [("p", p), ("q", q)], [("T", t_link)])
        add(
            fn_key("link_jac", link),
            [("p", p), ("q", q)],
            [("T", t_link), ("J", twist_jacobian(t_link, q))],
        )
    for gname, g in low.grasps.items():
        gv = _column(list(g.symbols), "g")
        t_grasp = _mat(g.pose)
        add(fn_key("grasp", gname), [("p", p), ("q", q), ("g", gv)], [("T", t_grasp)])
        add(
            fn_key("grasp_jac", gname),
            [("p", p), ("q", q), ("g", gv)],
            [("T", t_grasp), ("J", twist_jacobian(t_grasp, ca.vertcat(q, gv)))],
        )
        add(
            fn_key("grasp_range", gname),
            [("p", p)],
            [
                ("lo", _vec([f.lo for f in g.free])),
                ("hi", _vec([f.hi for f in g.free])),
                ("default", _vec([f.default for f in g.free])),
            ],
        )
        if g.width is not None:
            add(fn_key("grasp_width", gname), [("p", p)], [("width", g.width)])
        if g.axis is not None:
            add(fn_key("grasp_axis", gname), [("p", p), ("g", gv)], [("axis", _vec(g.axis))])
        if g.when is not None:
            add(
                fn_key("grasp_when", gname),
                [("p", p), ("q", q)],
                [("r", _vec([g.when.residual])), ("holds", _vec([g.when.holds]))],
            )
    _add_world_queries(low, p, q, add)
    holds = _vec([r.holds for r in low.requires])
    add("requires", [("p", p)], [("r", _vec([r.residual for r in low.requires])), ("holds", holds)])
    moving = [j for j in low.joints if j.kind != "fixed"]
    limits = [
        ("lo", _vec([j.lo if j.lo is not None else -ca.inf for j in moving])),
        ("hi", _vec([j.hi if j.hi is not None else ca.inf for j in moving])),
    ]
    add("joint_limits", [("p", p)], limits)
    # what instantiating needs in one call: the requirement tests and the joint ranges
    add("instance_checks", [("p", p)], [("holds", holds), *limits])
    add(
        "joint_axes",
        [("p", p), ("q", q)],
        [
            ("axis", _vec([a for j in moving for a in j.axis])),
            ("origin", _vec([o for j in moving for o in j.origin])),
        ],
    )
    for shape in low.shapes:
        args = [
            v for val in shape.args.values() for v in (val if isinstance(val, tuple) else (val,))
        ]
        add(
            fn_key("shape", shape.name),
            [("p", p), ("q", q)],
            [("T", _mat(shape.pose)), ("args", _vec(args)), ("at", _mat(shape.at))],
        )
    return Compiled(low, fns)


def twist_jacobian(pose: Any, x: Any) -> Any:
    """The 6 x n twist Jacobian of a 4x4 SX pose in the variables ``x``: rows ``[v; w]``, with
    ``v`` the derivative of the origin and ``w`` the angular velocity, ``[w]x = dR/dx R^T``
    (its antisymmetric part, so rounding in R cannot make it lopsided)."""
    rot, origin = pose[:3, :3], pose[:3, 3]
    n = x.numel()
    d_rot = ca.jacobian(ca.vec(rot), x)  # column-major: entry (r, c) at row r + 3 c
    columns = []
    for i in range(n):
        w = ca.mtimes(ca.reshape(d_rot[:, i], 3, 3), rot.T)
        columns.append(
            ca.vertcat((w[2, 1] - w[1, 2]) / 2, (w[0, 2] - w[2, 0]) / 2, (w[1, 0] - w[0, 1]) / 2)
        )
    angular = ca.horzcat(*columns) if columns else ca.SX(3, 0)
    return ca.vertcat(ca.jacobian(origin, x), angular)


Add = Callable[[str, list[tuple[str, Any]], list[tuple[str, Any]]], None]


def _add_world_queries(low: Lowered, p: Any, q: Any, add: Add) -> None:
    """Fused per-call queries in world coordinates, so the runtime makes one native call where
    it would make two or three and then finish the job with numpy:

    * ``grasps_world:NAME(p, q, u, M)``: ``M G(p, q, lo + u (hi - lo))``, the grasp at a point
      ``u`` of the unit box of free parameters (its range evaluated inside), at world pose M;
    * ``force:NAME(p, q, M, t)``: ``R f(p, q, R^T (t - t_M))``, the force at the world point t
      (the paper's ``F_world = R F_local``); with M = [I | 0] it is the force in the concept
      frame.

    M is passed as its top three rows ``[R | t_M]`` (3x4).
    """
    m = ca.SX.sym("M", 3, 4)  # the rows of M that are not (0, 0, 0, 1): fewer operations
    rot, origin = m[:, :3], m[:, 3]
    for gname, g in low.grasps.items():
        gv = _column(list(g.symbols), "g")
        u = ca.SX.sym("u", gv.numel())
        lo, hi = _vec([f.lo for f in g.free]), _vec([f.hi for f in g.free])
        local = ca.substitute(_mat(g.pose), gv, lo + u * (hi - lo)) if gv.numel() else _mat(g.pose)
        world = ca.vertcat(ca.mtimes(m, local), ca.horzcat(0, 0, 0, 1))
        add(
            fn_key("grasps_world", gname),
            [("p", p), ("q", q), ("u", u), ("M", m)],
            [("T", world)],
        )
    t = ca.SX.sym("t", 3)
    local_point = ca.mtimes(rot.T, t - origin)
    for aname in low.actions:
        f_local = force_direction(low, aname, [local_point[0], local_point[1], local_point[2]])
        add(
            fn_key("force", aname),
            [("p", p), ("q", q), ("M", m), ("t", t)],
            [("f", ca.mtimes(rot, f_local))],
        )


AXIS_TOLERANCE = tolerances.ON_AXIS  # metres (times the axis' unit length)
_NAN = float("nan")


def force_direction(low: Lowered, action: str, x: list[Any]) -> Any:
    """The unit direction in which the point x must move to perform ``action``."""
    a = low.actions[action]
    if a.direction is not None:
        return _vec(list(a.direction))
    joint = next(j for j in low.joints if j.name == a.joint)
    if joint.kind == "prismatic":
        v = joint.axis
    else:
        v = se3.cross(joint.axis, tuple(xi - oi for xi, oi in zip(x, joint.origin)))
    v = tuple(a.sign * c for c in v)
    n = ca.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    # On the axis (within a micrometre) no direction moves the point: NaN, not rounding noise.
    return _vec([ca.if_else(n > AXIS_TOLERANCE, c / n, _NAN) for c in v])


def sympy_model(checked: Checked, name: str) -> Lowered:
    """The same model with exact SymPy expressions (free grasp parameters by their own names)."""
    import sympy as sp

    from grace_dsl.compiler.sympy_backend import SYMPY

    def make(kind: str, sym: str) -> sp.Symbol:
        label = {"p": sym, "q": f"q_{sym}", "g": sym.split(":", 1)[-1]}[kind]
        return sp.Symbol(label, real=True)

    return lower(checked, name, SYMPY, make)


def sympy_matrix(rows: Any) -> Any:
    import sympy as sp

    return sp.Matrix([[_exact(v) for v in row] for row in rows])


def _exact(v: Any) -> Any:
    import sympy as sp

    if isinstance(v, (int, float)):
        return sp.Integer(int(v)) if float(v).is_integer() else sp.Float(v)
    return v
