"""The manifest entry of a compiled concept: everything a user, a runtime or a VLM prompt needs to
know about it, as plain JSON (parameters with units and ranges, links, joints, grasps, actions,
synopses and formulas)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from grace_dsl.compiler import se3
from grace_dsl.compiler.functions import sympy_matrix
from grace_dsl.compiler.lower import GraspInfo, Lowered, ParamInfo, where
from grace_dsl.compiler.types import Type
from grace_dsl.lang import ast


def _json_value(v: Any) -> Any:
    if v is None:
        return None
    if isinstance(v, tuple):
        return [float(x) for x in v]
    return float(np.asarray(v, dtype=float))


def _type_fields(t: Type) -> dict[str, Any]:
    return {
        "type": str(t),
        "kind": "int" if t.integer else t.kind,
        "dim": str(t.dim) if t.kind in ("num", "vec") else None,
        "choices": list(t.choices) if t.kind == "choice" else None,
    }


def param_entry(p: ParamInfo, offset: int) -> dict[str, Any]:
    return {
        "name": p.name,
        **_type_fields(p.type),
        "size": p.size,
        "offset": offset,
        "lo": _json_value(p.lo),
        "hi": _json_value(p.hi),
        "default": _json_value(p.default),
        "help": p.help,
        "doc": p.doc,
    }


def source_text(source: str, span: ast.Span) -> str:
    """The exact text a span covers, with runs of whitespace folded to one space."""
    lines = source.splitlines()
    if not span.line or span.line > len(lines):
        return ""
    if span.line == span.end_line:
        text = lines[span.line - 1][span.col - 1 : span.end_col - 1]
    else:
        chunk = [
            lines[span.line - 1][span.col - 1 :],
            *lines[span.line : span.end_line - 1],
            lines[span.end_line - 1][: span.end_col - 1],
        ]
        text = " ".join(chunk)
    return " ".join(text.split())


def _formula(rows: Any) -> dict[str, str]:
    m = sympy_matrix(rows)
    return {"latex": sp.latex(m), "text": sp.sstr(m.tolist())}


def grasp_demands(g: GraspInfo) -> dict[str, Any]:
    """What a grasp asks of the gripper: whether the fingers must close on the part, and whether
    the whole orientation matters or only the approach direction (a grasp symmetric about its
    own approach axis +z may spin freely)."""
    about_approach = g.axis is not None and _constant_axis(g.axis) == (0.0, 0.0, 1.0)
    return {
        "closes": g.mode == "pinch",
        "orientation": "approach" if about_approach else "full",
    }


def _constant_axis(axis: Any) -> tuple[float, ...] | None:
    """The unit axis when it is a constant, else None (it depends on parameters)."""
    sx = [ca.SX(a) for a in axis]
    if not all(a.is_constant() for a in sx):
        return None
    v = np.array([float(ca.DM(a)) for a in sx])
    n = float(np.linalg.norm(v))
    return tuple(float(x) for x in np.round(v / n, 12)) if n > 0 else None


GRASP_POINT = tuple(sp.Symbol(n, real=True) for n in ("x_g", "y_g", "z_g"))


def force_vector(exact: Lowered, action: str) -> tuple[list[Any], bool]:
    """The vector v along which the grasp point x = (x_g, y_g, z_g) (concept frame) moves for an
    action, and whether F = v / |v| still needs normalising (SymPy model ``exact``).

    An explicit direction is the unit vector itself; along a revolute joint v = s a x (x - o),
    along a prismatic one v = s a (sense s, axis a, origin o)."""
    a = exact.actions[action]
    if a.direction is not None:
        v = list(a.direction)
    else:
        joint = next(j for j in exact.joints if j.name == a.joint)
        v = list(joint.axis)
        if joint.kind != "prismatic":
            v = list(se3.cross(tuple(v), tuple(x - o for x, o in zip(GRASP_POINT, joint.origin))))
        v = [a.sign * c for c in v]
    v = [_tidy(c, exact.q) for c in v]
    return v, _tidy(sum(c**2 for c in v), exact.q) != 1


def force_formula(exact: Lowered, action: str) -> dict[str, Any]:
    """The force direction of an action as LaTeX and text (see ``force_vector``); ``rest_*`` is
    the same with every joint at 0, the short form a prompt shows."""
    v, normalize = force_vector(exact, action)
    rest = [_tidy(sp.sympify(c).subs({q: 0 for q in exact.q}), exact.q) for c in v]
    return {
        **_vector_text(v, normalize),
        **{f"rest_{k}": t for k, t in _vector_text(rest, normalize).items()},
        "normalize": normalize,
    }


def _vector_text(v: list[Any], normalize: bool) -> dict[str, str]:
    latex, text = sp.latex(sp.Matrix(v)), sp.sstr(v)
    if normalize:
        return {
            "latex": rf"\operatorname{{normalize}}\left({latex}\right)",
            "text": f"normalize({text})",
        }
    return {"latex": latex, "text": text}


def _tidy(e: Any, qs: list[Any]) -> Any:
    """Cheap exact simplification (trigsimp costs seconds): expand, replace sin(q)^2 by
    1 - cos(q)^2 for every joint value q, expand again, pull out common factors."""
    e = sp.expand(sp.sympify(e))
    for q in qs:
        e = e.subs(sp.sin(q) ** 2, 1 - sp.cos(q) ** 2)
    e = sp.expand(e)
    for q in qs:  # sqrt(sin^2 + cos^2) from a normalised explicit direction
        e = e.subs(sp.sqrt(sp.sin(q) ** 2 + sp.cos(q) ** 2), 1)
    return sp.factor_terms(e)


def _when_entry(g: GraspInfo) -> dict[str, Any] | None:
    """Where a grasp family applies: its ``when`` condition as written, the qualified joints it
    reads and its ``file:line`` (None: the family applies at every joint value)."""
    if g.when is None:
        return None
    return {"condition": g.when.condition, "joints": list(g.when.joints), "where": g.when.where}


def concept_entry(
    decl: ast.Concept,
    file: str,
    source: str,
    low: Lowered,
    exact: Lowered,
    function_names: dict[str, str],
) -> dict[str, Any]:
    """The manifest entry of one concept (``low``: CasADi model, ``exact``: SymPy model)."""
    offsets = np.cumsum([0] + [p.size for p in low.params]).tolist()
    operand_of = {o: s.name for s in low.shapes for o in s.operands}
    moving = [j for j in low.joints if j.kind != "fixed"]
    param_names = {p.name for p in low.params}
    return {
        "name": decl.name,
        "kind": decl.kind,
        "doc": decl.doc,
        "file": file,
        "params": [param_entry(p, int(o)) for p, o in zip(low.params, offsets)],
        "n_params": int(offsets[-1]),
        "links": [{"name": n, "doc": low.link_docs.get(n, "")} for n in low.links],
        "joints": [
            {
                "name": j.name,
                "kind": j.kind,
                "parent": j.parent,
                "child": j.child,
                "doc": j.doc,
                "index": moving.index(j) if j in moving else None,
                "where": j.where,
                "range_where": j.range_where,
            }
            for j in low.joints
        ],
        "grasps": [
            {
                "name": g.name,
                "link": g.link,
                "doc": g.doc,
                "free": [{"name": f.name, **_type_fields(f.type)} for f in g.free],
                "has_width": g.width is not None,
                "mode": g.mode,
                "symmetric": g.axis is not None,
                "demands": grasp_demands(g),
                "source": source_text(source, g.source.pose.span) if "." not in g.name else "",
                "where": where(g.source.pose.span),
                "width_where": where(g.source.width.span) if g.source.width is not None else "",
                "formula": _formula(exact.grasps[g.name].pose),
                "when": _when_entry(g),
            }
            for g in low.grasps.values()
        ],
        "actions": [
            {
                "name": a.name,
                "verb": a.verb,
                "joint": a.joint,
                "sense": "opening" if a.sign > 0 else "closing",
                "direction": a.direction is not None,
                "using": list(a.using),
                "doc": a.doc,
                "where": a.where,
                "formula": force_formula(exact, a.name),
            }
            for a in low.actions.values()
        ],
        "shapes": [
            {
                "name": s.name,
                "link": s.link,
                "primitive": s.primitive,
                "operands": list(s.operands),
                "operand_of": operand_of.get(s.name),  # consumed by a union/difference
                "where": s.where,
                "args": [
                    {"name": k, "size": len(v) if isinstance(v, tuple) else 1}
                    for k, v in s.args.items()
                ],
            }
            for s in low.shapes
        ],
        "parts": dict(low.parts),
        "masks": {n: [list(c) for c in cond] for n, cond in low.masks.items()},
        "variants": {
            n: {"param": param, "options": dict(options)}
            for n, (param, options) in low.variants.items()
        },
        "requires": [
            {
                "message": r.message,
                "where": r.source,
                "condition": r.condition,
                "params": [n for n in r.reads if n in param_names],
            }
            for r in low.requires
        ],
        "functions": function_names,
    }
