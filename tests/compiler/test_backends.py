"""CasADi and SymPy lowerings of every library concept agree on random inputs to 1e-9.

Both come from the same lowering code but through independent backends (CasADi's SX graph and
its VM; SymPy's exact expressions evaluated by substitution), so a wrong operator mapping,
a unit conversion slip in either backend or a graph-construction bug shows up here.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from grace_dsl.compiler.functions import casadi_functions, sympy_matrix, sympy_model
from grace_dsl.compiler.lower import ParamInfo, symbol_names

CONCEPTS = ["CurveHandle", "SunkenDoor"]


def random_params(params: list[ParamInfo], rng: np.random.Generator) -> np.ndarray:
    values = []
    for p in params:
        if p.type.kind == "choice":
            values.append([float(rng.integers(len(p.type.choices)))])
        elif p.lo is not None:
            values.append(rng.uniform(np.atleast_1d(p.lo), np.atleast_1d(p.hi)))
        else:
            values.append(np.atleast_1d(p.default) * rng.uniform(0.5, 1.5))
    return np.concatenate(values)


def sympy_value(expr: object, subs: dict[sp.Symbol, float]) -> float:
    if isinstance(expr, (int, float)):
        return float(expr)
    exact = {k: sp.Float(float(v), 30) for k, v in subs.items()}
    return float(expr.xreplace(exact).evalf(30))  # type: ignore[attr-defined]


@pytest.mark.parametrize("name", CONCEPTS)
def test_backends_agree(stdlib_front_end, name: str) -> None:  # type: ignore[no-untyped-def]
    _, checked = stdlib_front_end
    compiled = casadi_functions(checked, name)
    exact = sympy_model(checked, name)
    low = compiled.lowered
    rng = np.random.default_rng(7)
    p_syms = [sp.Symbol(n, real=True) for p in low.params for n in symbol_names(p)]
    q_syms = [sp.Symbol(f"q_{j.name}", real=True) for j in low.joints if j.kind != "fixed"]
    for _ in range(10):
        p = random_params(low.params, rng)
        q = rng.uniform(0.0, 1.5, len(q_syms))
        subs = dict(zip(p_syms, p)) | dict(zip(q_syms, q))
        for link, pose in exact.links.items():
            got = np.asarray(compiled.functions[f"link:{link}"](p, q))
            want = np.array([[sympy_value(v, subs) for v in row] for row in pose])
            np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)
        for gname, g in exact.grasps.items():
            lo, hi, _ = (
                np.atleast_1d(np.asarray(x)).reshape(-1)
                for x in compiled.functions[f"grasp_range:{gname}"](p)
            )
            gv = rng.uniform(lo, hi)
            gsubs = subs | dict(zip(g.symbols, gv))
            want_lo = [sympy_value(f.lo, subs) for f in g.free]
            np.testing.assert_allclose(lo, want_lo, atol=1e-9, rtol=0)
            got = np.asarray(compiled.functions[f"grasp:{gname}"](p, q, gv))
            want = np.array([[sympy_value(v, gsubs) for v in row] for row in g.pose])
            np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)
        residuals, holds = (
            np.atleast_1d(np.asarray(x)).reshape(-1) for x in compiled.functions["requires"](p)
        )
        want_r = [sympy_value(r.residual, subs) for r in exact.requires]
        np.testing.assert_allclose(residuals, want_r, atol=1e-9, rtol=0)
        want_h = [sympy_value(r.holds, subs) for r in exact.requires]
        np.testing.assert_array_equal(holds, want_h)


def test_sympy_keeps_exact_forms(stdlib_front_end) -> None:  # type: ignore[no-untyped-def]
    """90deg becomes pi/2 exactly, so the paper's handle grasp has no floating-point noise."""
    _, checked = stdlib_front_end
    pose = sympy_matrix(sympy_model(checked, "CurveHandle").grasps["pull"].pose)
    theta, r_out = sp.Symbol("theta", real=True), sp.Symbol("r_out", real=True)
    assert sp.Matrix([[r_out * sp.sin(theta), -r_out * sp.cos(theta), 0, 1]]) == pose[:, 3].T
    assert pose[2, :3] == sp.Matrix([[0, 1, 0]])
