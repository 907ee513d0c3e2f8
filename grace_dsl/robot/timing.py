"""Time-optimal parameterization of a joint path under velocity and acceleration limits.

A path ``q(s)`` (here a cubic spline through the waypoints over their chord length, or the
polyline itself) is traversed at path speed ``ṡ`` with path acceleration ``s̈``; the joints then
move at ``q'(s) ṡ`` and accelerate at ``q'(s) s̈ + q''(s) ṡ²``. With ``x = ṡ²`` and ``u = s̈``
every limit is linear in ``(x, u)``:

    q'_i² x ≤ v_i²            −a_i ≤ q'_i u + q''_i x ≤ a_i            x ≥ 0

and on a grid ``s_0 < … < s_N`` with ``u`` constant on each interval, ``x_{k+1} = x_k + 2 Δs_k u_k``
(the exact integration of a constant path acceleration). This is the reachability analysis of
TOPP-RA (Pham & Pham 2018): a backward pass computes at each grid point the interval of ``x`` from
which the path's end can still be reached at rest, each step a two-variable linear program; a
forward pass then takes the largest feasible ``u`` at every point, staying inside those intervals.
The result is time-optimal for the discretized problem and meets every limit at every grid point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from grace_dsl.runtime.errors import GraceError

FloatArray = np.ndarray
GRID = 0.01  # radians of path (joint-space chord length) between grid points
MAX_POINTS = 4000  # grid points per path, however long


class TimingError(GraceError):
    """The path cannot be timed (non-finite waypoints or limits, or a limit that is not > 0)."""


@dataclass(frozen=True)
class Trajectory:
    """Joint positions ``q`` (M, n) at times ``t`` (M,) from rest to rest; ``extra`` (M, m) the
    unconstrained coordinates carried along the same path (e.g. an object's joint value)."""

    q: FloatArray
    t: FloatArray
    extra: FloatArray

    @property
    def duration(self) -> float:
        return float(self.t[-1])


def time_optimal(
    waypoints: FloatArray,
    velocity: FloatArray,
    acceleration: float | FloatArray,
    *,
    extra: FloatArray | None = None,
    smooth: bool = True,
    grid: float = GRID,
) -> Trajectory:
    """The fastest rest-to-rest traversal of the path through ``waypoints`` (K, n) whose joint
    speeds stay within ``velocity`` and accelerations within ``acceleration`` (per joint, or one
    bound for all). ``smooth`` follows a cubic spline through the waypoints (no stop at corners,
    but the path bends between them: re-check it for collisions); otherwise the polyline, which
    stops at every corner. ``extra`` (K, m) is interpolated along the same path parameter."""
    q = np.asarray(waypoints, dtype=float)
    n = q.shape[1]
    v = _limit(velocity, n, "velocity")
    a = _limit(acceleration, n, "acceleration")
    if not np.all(np.isfinite(q)):
        raise TimingError("the waypoints are not finite")
    carry = np.zeros((len(q), 0)) if extra is None else np.asarray(extra, float).reshape(len(q), -1)
    keep = np.concatenate([[True], np.any(np.abs(np.diff(q, axis=0)) > 1e-12, axis=1)])
    q, carry = q[keep], carry[keep]
    if len(q) == 1:
        return _frozen(Trajectory(q, np.zeros(1), carry))
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q, axis=0), axis=1))])
    if smooth and len(q) > 2:
        s, path, t = _timed(*_spline(q, chord, grid), v, a)
    else:  # each straight piece rest to rest: a corner of a polyline must be a stop
        parts = [
            _timed(*_straight(q[k], q[k + 1], chord[k], chord[k + 1], grid), v, a)
            for k in range(len(q) - 1)
        ]
        offsets = np.cumsum([0.0] + [p[2][-1] for p in parts[:-1]])
        s = np.concatenate([parts[0][0]] + [p[0][1:] for p in parts[1:]])
        path = np.concatenate([parts[0][1]] + [p[1][1:] for p in parts[1:]])
        t = np.concatenate([parts[0][2]] + [p[2][1:] + o for p, o in zip(parts[1:], offsets[1:])])
    t = t * _sample_excess(path, t, v, a)
    moved = np.column_stack([np.interp(s, chord, c) for c in carry.T]) if carry.size else None
    return _frozen(Trajectory(path, t, moved if moved is not None else np.zeros((len(s), 0))))


def _timed(
    s: FloatArray, path: FloatArray, d1: FloatArray, d2: FloatArray, v: FloatArray, a: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    speed = np.sqrt(_parameterize(s, d1, d2, v, a))
    dt = 2.0 * np.diff(s) / np.maximum(speed[:-1] + speed[1:], 1e-300)
    return s, path, np.concatenate([[0.0], np.cumsum(dt)])


def _sample_excess(q: FloatArray, t: FloatArray, v: FloatArray, a: FloatArray) -> float:
    """The factor (>= 1) by which to stretch time so that the samples themselves, differenced
    as an executor would (velocity per interval, acceleration between interval midpoints), meet
    the limits: the grid enforces them on the path's derivatives, which differ by O(grid)."""
    if len(t) < 2:
        return 1.0
    vel = np.diff(q, axis=0) / np.diff(t)[:, None]
    ratio = float(np.max(np.abs(vel) / v))
    if len(t) > 2:
        mid = (t[1:] + t[:-1]) / 2
        acc = np.diff(vel, axis=0) / np.diff(mid)[:, None]
        ratio = max(ratio, math.sqrt(float(np.max(np.abs(acc) / a))))
    return max(1.0, ratio * (1.0 + 1e-9))


def _limit(value: float | FloatArray, n: int, what: str) -> FloatArray:
    out = np.broadcast_to(np.asarray(value, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(out)) or np.any(out <= 0):
        raise TimingError(f"the {what} limits must be finite and > 0, not {out}")
    return out


def _spline(
    q: FloatArray, chord: FloatArray, grid: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """A grid over the chord length (every waypoint on it) and the natural cubic spline through
    the waypoints, with its first and second derivatives, there."""
    spline = CubicSpline(chord, q, bc_type="natural")
    count = min(MAX_POINTS, max(len(q), math.ceil(chord[-1] / grid) + 1))
    s = np.unique(np.concatenate([np.linspace(0.0, chord[-1], count), chord]))
    return s, spline(s), spline(s, 1), spline(s, 2)


def _straight(
    a: FloatArray, b: FloatArray, s0: float, s1: float, grid: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    count = min(MAX_POINTS, max(2, math.ceil((s1 - s0) / grid) + 1))
    s = np.linspace(s0, s1, count)
    w = (s - s0) / (s1 - s0)
    d1 = np.tile((b - a) / (s1 - s0), (count, 1))
    return s, a + w[:, None] * (b - a), d1, np.zeros_like(d1)


def _parameterize(
    s: FloatArray, d1: FloatArray, d2: FloatArray, v: FloatArray, a: FloatArray
) -> FloatArray:
    """``x = ṡ²`` at every grid point: the backward reachability pass, then the greedy forward
    pass (rest at both ends)."""
    n_pts, n = d1.shape
    ds = np.diff(s)
    with np.errstate(divide="ignore"):
        x_cap = np.min(np.where(np.abs(d1) > 1e-12, (v / np.abs(d1)) ** 2, np.inf), axis=1)
    # Each point's constraints as rows [x, u] . row <= rhs: the joints' accelerations both ways,
    # x <= the velocity cap, x >= 0, and two rows for the next point's interval filled in later.
    rows = np.zeros((n_pts, 2 * n + 4, 2))
    rhs = np.zeros((n_pts, 2 * n + 4))
    rows[:, :n], rows[:, n : 2 * n] = np.stack([d2, d1], -1), -np.stack([d2, d1], -1)
    rhs[:, :n] = rhs[:, n : 2 * n] = a
    rows[:, 2 * n] = (1.0, 0.0)
    rhs[:, 2 * n] = np.minimum(x_cap, 1e12)
    rows[:, 2 * n + 1] = (-1.0, 0.0)
    rows[:-1, 2 * n + 2, 0], rows[:-1, 2 * n + 2, 1] = 1.0, 2 * ds
    rows[:-1, 2 * n + 3, 0], rows[:-1, 2 * n + 3, 1] = -1.0, -2 * ds
    i, j = np.triu_indices(2 * n + 4, 1)
    lo, hi = np.zeros(n_pts), np.zeros(n_pts)  # the controllable interval at each point
    for k in range(n_pts - 2, -1, -1):
        rhs[k, 2 * n + 2], rhs[k, 2 * n + 3] = hi[k + 1], -lo[k + 1]
        lo[k], hi[k] = _x_range(rows[k], rhs[k], i, j)
    x = np.zeros(n_pts)
    for k in range(n_pts - 1):
        u_lo, u_hi = _u_range(d1[k], d2[k], a, x[k])
        u_hi = min(u_hi, (hi[k + 1] - x[k]) / (2 * ds[k]))
        u_lo = max(u_lo, (lo[k + 1] - x[k]) / (2 * ds[k]))
        u = u_hi if u_hi >= u_lo else u_lo  # rounding: the reachable side wins
        x[k + 1] = min(max(x[k] + 2 * ds[k] * u, lo[k + 1]), hi[k + 1])
    x[-1] = 0.0
    return x


def _u_range(d1: FloatArray, d2: FloatArray, a: FloatArray, x: float) -> tuple[float, float]:
    """The path accelerations allowed at ``x`` by ``−a ≤ d1 u + d2 x ≤ a``."""
    moving = np.abs(d1) > 1e-12
    c = d1[moving]
    ends = np.stack([(-a[moving] - d2[moving] * x) / c, (a[moving] - d2[moving] * x) / c])
    return float(np.max(ends.min(axis=0), initial=-np.inf)), float(
        np.min(ends.max(axis=0), initial=np.inf)
    )


def _x_range(m: FloatArray, b: FloatArray, i: FloatArray, j: FloatArray) -> tuple[float, float]:
    """The interval of ``x`` over the polygon ``m @ [x, u] <= b``: a two-variable LP, solved by
    enumerating the polygon's vertices (``min x`` and ``max x`` are attained at vertices). An
    empty polygon (only by rounding: rest at the end is reachable from rest) gives (0, 0)."""
    det = m[i, 0] * m[j, 1] - m[i, 1] * m[j, 0]
    ok = np.abs(det) > 1e-14
    i, j, det = i[ok], j[ok], det[ok]
    xs = (b[i] * m[j, 1] - m[i, 1] * b[j]) / det
    us = (m[i, 0] * b[j] - b[i] * m[j, 0]) / det
    slack = 1e-9 * (1.0 + np.abs(b))
    feasible = np.all(np.column_stack([xs, us]) @ m.T <= b + slack, axis=1)
    if not np.any(feasible):
        return 0.0, 0.0
    good = xs[feasible]
    return max(0.0, float(good.min())), max(0.0, float(good.max()))


def _frozen(traj: Trajectory) -> Trajectory:
    for array in (traj.q, traj.t, traj.extra):
        array.setflags(write=False)
    return traj
