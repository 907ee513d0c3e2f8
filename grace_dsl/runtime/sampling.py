"""Deterministic spreads over a box of free grasp parameters.

Why a module of its own: the instance (``grasps``), the ranker and the verifier all sample the
same points, so the n-th grasp pose and the n-th free-parameter row always belong together.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

PRIMES = (2, 3, 5, 7, 11, 13, 17, 19)


def spread(ranges: Sequence[tuple[float, float]], n: int) -> np.ndarray:
    """Deterministic points over a box: a grid along one axis, a Halton sequence in more."""
    lows = np.array([r[0] for r in ranges], dtype=float)
    highs = np.array([r[1] for r in ranges], dtype=float)
    return spread_box(lows, highs, n)


def spread_box(lows: np.ndarray, highs: np.ndarray, n: int) -> np.ndarray:
    """``spread`` over the box [lows, highs] given as arrays, (n, d)."""
    d = lows.size
    if d == 0:
        return np.zeros((n, 0))
    if d == 1:  # Python floats: a third of the cost of size-1 array arithmetic
        lo = float(lows[0])
        return unit_points(n, 1) * (float(highs[0]) - lo) + lo
    return lows + unit_points(n, d) * (highs - lows)


@lru_cache(maxsize=128)
def unit_points(n: int, d: int) -> np.ndarray:
    """The spread over the unit box, computed once per (n, d) (read-only)."""
    if d == 1:
        pts = np.linspace(0.0, 1.0, n).reshape(n, 1)
    else:
        pts = np.array([[halton(i + 1, PRIMES[k]) for k in range(d)] for i in range(n)])
    pts.flags.writeable = False
    return pts


def halton(i: int, base: int) -> float:
    """The i-th element of the van der Corput sequence in ``base``."""
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r
