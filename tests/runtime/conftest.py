"""Fixtures of the runtime tests: the standard library and a concept built to break formulas."""

from __future__ import annotations

from typing import Any

import pytest

import grace_dsl as eac
from tests.conftest import write

# Unbounded parameters make formulas non-finite (gain: overflow at 1e200, NaN below 0; bend: a
# NaN free-parameter range below 0), and member names collide with the runtime's arguments.
POISON = """use primitives.{Cuboid}

/// Formulas that overflow or turn NaN for extreme values of unbounded parameters, and member
/// names that collide with the runtime's own arguments.
concept Poison {
    param gain : scalar = 1
    param bend : scalar = 1
    param joints : length in [10mm, 100mm] = 50mm
    param pose : scalar in [0, 2] = 1
    shape body = Cuboid(size: (100mm, 100mm, 100mm))
    link lid {
        shape plate = Cuboid(size: (100mm, 100mm, 10mm)) at trans(0, 0, 60mm)
        /// Free parameters named like grasp()'s own arguments.
        grasp far(reference in [0, 1] = 0, name in [0, sqrt(bend)] = 0) =
            trans(gain * gain * 1mm + reference * joints, name * 1mm, 70mm) * roty(180deg)
            width 20mm
    }
    link flap {
        shape leaf = Cuboid(size: (10mm, 100mm, 100mm)) at trans(0, 0, 0)
        grasp edge = trans(0, 0, 60mm) * roty(180deg) width 10mm
    }
    joint slide : prismatic(base -> lid) axis (1, 0, 0) range [0, sqrt(gain) * 10mm]
    joint swing : revolute(base -> flap) axis (0, 1, 0) at (gain * gain * 1mm, 0, 0)
        range [0, 90deg]
    action open = pull along slide using far
    action turn = pull along swing using edge
}
"""


@pytest.fixture(scope="session")
def poison(tmp_path_factory: pytest.TempPathFactory) -> eac.Concept:
    path = write(tmp_path_factory.mktemp("poison"), "poison.eac", POISON)
    return eac.compile_paths([path])["Poison"]


# A stack of n drawers with a bar or ring handle each: one compiled unit for every count, shared by
# the tests of repeated members (test_repeat_runtime.py) and of masked listings (test_masks.py).
STACK = """use primitives.{Cuboid}
use handles.{StraightHandle, RingPull}

concept Stack {
    param n : int in [1, 4] = 3
    param kind : choice{"bar", "ring"} = "bar"
    param h : length in [100mm, 200mm] = 150mm
    shape body = Cuboid(size: (400mm, 4 * h, 300mm))
    for i in 0..n {
        require (i + 1) * h <= 650mm "the drawer fits in the carcass"
        link drawer[i] {
            shape front[i] = Cuboid(size: (380mm, h - 10mm, 18mm)) at trans(0, i * h, 160mm)
            part handle[i] = match kind {
                "bar" => StraightHandle(standoff: 32mm),
                "ring" => RingPull()
            } at trans(0, i * h, 200mm)
        }
        joint slide[i] : prismatic(base -> drawer[i]) axis (0, 0, 1) range [0, 250mm]
        action open[i] = pull along slide[i] using handle[i].pull
    }
}
"""


@pytest.fixture(scope="session")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """``Stack`` compiled once (CasADi's VM, no C): the tests that use it are marked slow."""
    from grace_dsl.compiler.build import build
    from grace_dsl.runtime.library import Library

    root = tmp_path_factory.mktemp("stack")
    (root / "stack.eac").write_text(STACK, encoding="utf-8")
    result = build([root / "stack.eac"], root / "cache", use_native=False)
    assert result.ok, result.diagnostics
    return Library(result.units, result)["Stack"]
