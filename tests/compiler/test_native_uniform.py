"""Uniform inputs of a native batch kernel: one value for every sample, read once."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from grace_dsl.compiler import native


def _function() -> ca.Function:
    a, b, y = ca.SX.sym("a", 3, 2), ca.SX.sym("b", 2), ca.SX.sym("y", 3)
    return ca.Function("uniform_probe", [a, b, y], [ca.sin(a.T @ y + b), ca.sumsqr(y) * b[0]])


def test_uniform_inputs_give_the_broadcast_result(tmp_path: Path) -> None:
    if native.find_compiler() is None:
        pytest.skip("no C compiler")
    fn = _function()
    once = native.fast_functions(
        {"uniform_probe": fn}, tmp_path, uniform={"uniform_probe": frozenset({0, 1})}
    )["uniform_probe"]
    assert once.backend == "native"
    rng = np.random.default_rng(0)
    a, b, y = rng.normal(size=(3, 2)), rng.normal(size=2), rng.normal(size=(2000, 3))
    got = once.batch(a, b, y)
    want = native.CasadiEvaluator(fn).batch(a, b, y)
    for g, w in zip(got, want, strict=True):
        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="one value for every sample"):
        once.batch(np.repeat(a[None], 2000, axis=0), b, y)
