"""The manifest entry of a compiled concept: everything a user, a runtime or a VLM prompt needs to
know about it, as plain JSON (parameters with units and ranges, links, joints, grasps, actions,
synopses and formulas)."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import sympy as sp

from grace_dsl.compiler.functions import sympy_matrix
from grace_dsl.compiler.lower import GraspInfo, Lowered, ParamInfo
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
                "formula": _formula(exact.grasps[g.name].pose),
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
                "args": [
                    {"name": k, "size": len(v) if isinstance(v, tuple) else 1}
                    for k, v in s.args.items()
                ],
            }
            for s in low.shapes
        ],
        "parts": dict(low.parts),
        "requires": [{"message": r.message, "where": r.source} for r in low.requires],
        "functions": function_names,
    }
