"""Hypothesis strategies for valid primitive parameters, and a mesh containment test without rtree.

Sizes stay in [5 mm, 300 mm] so a 64-segment mesh's chords sag less than 0.4 mm, inside the
1 mm band the containment test ignores.
"""

from __future__ import annotations

import math
from typing import Any

from hypothesis import strategies as st

LEN = st.floats(0.005, 0.3)
ANGLE = st.one_of(st.just(2 * math.pi), st.floats(0.2, 2 * math.pi))


@st.composite
def _two_radii(draw: Any) -> tuple[float, float]:
    r_in = draw(st.floats(0.005, 0.25))
    return r_in, r_in + draw(st.floats(0.003, 0.1))


@st.composite
def params_for(draw: Any, name: str) -> dict[str, Any]:
    """Random valid SI parameters of primitive ``name``."""
    if name == "Cuboid":
        return {"size": (draw(LEN), draw(LEN), draw(LEN))}
    if name == "Cylinder":
        return {"radius": draw(LEN), "height": draw(LEN), "radian": draw(ANGLE)}
    if name == "Tube":
        r_in, r_out = draw(_two_radii())
        return {"r_in": r_in, "r_out": r_out, "height": draw(LEN)}
    if name == "Ring":
        r_in, r_out = draw(_two_radii())
        return {"r_in": r_in, "r_out": r_out, "height": draw(LEN), "radian": draw(ANGLE)}
    if name == "RectRing":
        outer = (draw(st.floats(0.02, 0.3)), draw(st.floats(0.02, 0.3)))
        inner = tuple(o * draw(st.floats(0.2, 0.9)) for o in outer)
        return {"outer": outer, "inner": inner, "depth": draw(LEN)}
    if name == "Sphere":
        return {"radius": draw(LEN)}
    if name == "Capsule":
        return {"radius": draw(LEN), "length": draw(LEN)}
    if name == "Frustum":
        r1, r2 = draw(st.sampled_from([(1, 1), (0, 1), (1, 0)]))
        return {"r_bottom": r1 * draw(LEN), "r_top": r2 * draw(LEN), "height": draw(LEN)}
    if name == "TaperedCuboid":
        size = (draw(LEN), draw(LEN), draw(LEN))
        scale = st.one_of(st.just(0.0), st.just(1.0), st.floats(0.0, 1.5))
        top = (size[0] * draw(scale), size[2] * draw(scale))
        shift = st.floats(-0.5, 0.5)
        return {"size": size, "top": top, "offset": (size[0] * draw(shift), size[2] * draw(shift))}
    if name == "SphericalCap":
        radius = draw(LEN)
        return {
            "radius": radius,
            "height": radius * draw(st.one_of(st.just(2.0), st.floats(0.05, 2))),
        }
    if name == "Torus":
        big = draw(st.floats(0.01, 0.25))
        return {"r_major": big, "r_minor": big * draw(st.floats(0.05, 0.9)), "radian": draw(ANGLE)}
    if name == "Prism":
        sides = draw(st.one_of(st.integers(3, 12), st.just(64)))
        return {"sides": sides, "radius": draw(LEN), "height": draw(LEN)}
    if name == "BoardBox":
        size = (draw(st.floats(0.02, 0.3)), draw(st.floats(0.02, 0.3)), draw(st.floats(0.02, 0.3)))
        board = min(size) / 2 * draw(st.floats(0.05, 0.9))
        return {
            "size": size,
            "board": board,
            "top": draw(st.booleans()),
            "front": draw(st.booleans()),
        }
    raise AssertionError(name)
