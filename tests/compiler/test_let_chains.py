"""Long chains of ``let``s cost no Python recursion: check, build and evaluation all work.

Regression: 130 chained lets passed ``check`` and crashed ``build`` with RecursionError in
lower.py; declared last-first they crashed ``check`` too."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from grace_dsl.compiler.build import front_end
from grace_dsl.runtime.library import compile_paths
from tests.conftest import write

N = 1000


def chain(n: int, backwards: bool, step: str = "l{p} + 1mm") -> str:
    """A concept whose grasp height is a chain of ``n`` lets, each reading the previous one."""
    lets = ["    let l0 = a"] + [f"    let l{i} = " + step.format(p=i - 1) for i in range(1, n)]
    if backwards:
        lets.reverse()
    return (
        "\n".join(
            [
                "concept Chain {",
                "    param a : length in [1mm, 10mm] = 5mm",
                f"    require l{n - 1} > 0mm",
                f"    grasp g = trans(0mm, 0mm, l{n - 1}) width 10mm",
                *lets,
                "}",
            ]
        )
        + "\n"
    )


@pytest.mark.parametrize("backwards", [False, True])
def test_a_thousand_chained_lets_check(tmp_path: Path, backwards: bool) -> None:
    path = write(tmp_path, "chain.eac", chain(N, backwards))
    _, checked, diags = front_end([path])
    assert diags == []
    assert checked.concepts["Chain"].ok


@pytest.mark.slow
def test_a_thousand_chained_lets_build_and_evaluate(tmp_path: Path) -> None:
    path = write(tmp_path, "chain.eac", chain(N, backwards=True))
    lib = compile_paths([path])
    inst = lib["Chain"].instantiate(a=0.007)
    g = inst.grasp("g")
    assert np.isclose(g[2, 3], 0.007 + (N - 1) * 0.001)


def test_a_nonlinear_chain_evaluates(tmp_path: Path) -> None:
    """Each let wraps the previous one in a function, so the formula itself is deep."""
    n = 150
    path = write(tmp_path, "chain.eac", chain(n, backwards=True, step="max(l{p}, 1mm) + 1mm"))
    lib = compile_paths([path])
    g = lib["Chain"].instantiate(a=0.002).grasp("g")
    assert np.isclose(g[2, 3], 0.002 + (n - 1) * 0.001)
