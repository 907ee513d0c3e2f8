"""The lower pass: flattening parts into qualified links, joints, grasps and lifted parameters."""

from __future__ import annotations

import casadi as ca
import numpy as np

from grace_dsl.compiler.backends import CASADI, NUMPY
from grace_dsl.compiler.lower import lower


def test_door_flattens_its_handle(stdlib_front_end) -> None:  # type: ignore[no-untyped-def]
    _, checked = stdlib_front_end
    low = lower(checked, "SunkenDoor", CASADI, lambda kind, name: ca.SX.sym(name))
    assert [p.name for p in low.params] == [
        "size",
        "rim",
        "rim_depth",
        "handle_at",
        "hinge_side",
        "handle.radian",
        "handle.r_in",
        "handle.r_out",
        "handle.height",
    ]
    assert [p.size for p in low.params] == [3, 1, 1, 2, 1, 1, 1, 1, 1]
    assert len(low.p) == 12 and len(low.q) == 1
    assert list(low.links) == ["base", "leaf"]
    assert [(j.name, j.parent, j.child) for j in low.joints] == [("hinge", "base", "leaf")]
    assert {"handle.pull", "handle.push", "push_edge"} <= set(low.grasps)
    assert {g.link for g in low.grasps.values()} == {"leaf"}
    assert [s.name for s in low.shapes] == ["panel", "frame", "handle.bar"]
    assert low.parts == {"handle": "CurveHandle"}
    assert low.actions["open"].sign == 1 and low.actions["close"].sign == -1
    assert low.actions["open"].using == ("handle.pull",)


def test_numpy_lowering_gives_numbers(stdlib_front_end) -> None:  # type: ignore[no-untyped-def]
    """Lowering over plain numbers: the handle's grasp at theta = 0 sits on the outer rim."""
    _, checked = stdlib_front_end
    values = {"radian": 2.0, "r_in": 0.04, "r_out": 0.05, "height": 0.01, "keep_clear": 0.0}

    def number(kind: str, name: str) -> float:  # every free grasp parameter at 0
        return np.float64(values[name.split(":")[-1]] if kind != "g" else 0.0)

    low = lower(checked, "CurveHandle", NUMPY, number)
    pose = np.array(low.grasps["pull"].pose, dtype=float)
    np.testing.assert_allclose(pose[:3, 3], [0.0, -0.05, 0.0], atol=1e-15)
    assert float(low.grasps["pull"].free[0].hi) == 1.0
