"""A small box-constrained QP: solved exactly by an active-set iteration, OSQP behind it.

Each inverse-kinematics step solves ``min ½ xᵀ P x + cᵀ x  s.t.  lo <= x <= hi`` with a dense
positive definite ``P`` of 7 to 10 unknowns. :func:`active_set` solves it exactly in one or two
Cholesky solves when its guess of the bound constraints settles (99% of the IK steps that meet a
limit); :class:`BoxQP` hands the rest to OSQP. OSQP needs its matrices in compressed-column form;
the sparsity pattern (a full upper triangle, an identity constraint matrix) never changes, so
the solver is set up once and each step only updates the numbers, keeping OSQP's factorization
workspace; each solve starts cold with the same step size, so it is a function of its problem
alone, not of the solves before it (an episode is the same whatever the process ran before).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.linalg.lapack import dposv

FloatArray = np.ndarray


def active_set(
    p: FloatArray,
    c: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    x: FloatArray | None = None,
    rounds: int = 8,
) -> FloatArray | None:
    """The exact minimizer by the primal-dual active-set method for box constraints
    (Hintermüller, Ito and Kunisch 2002), or None when the sets do not settle within ``rounds``.

    Each round fixes the unknowns guessed at a bound, solves for the others (a Cholesky solve of
    their block of ``P``) and guesses again from the multipliers ``μ = −(P x + c)``; ``x`` is the
    unconstrained minimizer when the caller has it. When a guess repeats, the point satisfies the
    KKT conditions by construction (the free unknowns within their bounds with ``μ = 0``,
    ``μ ≤ 0`` at a lower bound, ``μ ≥ 0`` at an upper one), which for a positive definite ``P``
    make it the QP's unique solution.
    """
    if x is None:
        x = spd_solve(p, -c)
        if x is None:
            return None
    at_lo, at_hi = x < lo, x > hi  # the first guess, with μ = 0
    for _ in range(rounds):
        free = ~(at_lo | at_hi)
        x = np.where(at_lo, lo, np.where(at_hi, hi, 0.0))
        if free.any():
            sub = spd_solve(p[free][:, free], -c[free] - p[free] @ x)
            if sub is None:
                return None
            x[free] = sub
        mu = -(p @ x + c)
        mu[free] = 0.0
        new_lo, new_hi = mu + (x - lo) < 0.0, mu + (x - hi) > 0.0
        if not ((new_lo ^ at_lo).any() or (new_hi ^ at_hi).any()):
            return x
        at_lo, at_hi = new_lo, new_hi & ~new_lo
    return None


def spd_solve(a: FloatArray, b: FloatArray) -> FloatArray | None:
    """``a⁻¹ b`` for a symmetric positive definite ``a`` (LAPACK's Cholesky ``posv``)."""
    _, x, info = dposv(a, b)
    return x if info == 0 else None


RHO = 0.1  # OSQP's default initial ADMM step size, restored before every solve


@dataclass
class BoxQP:
    """``min ½ xᵀ P x + cᵀ x`` over a box, for ``n`` unknowns; :meth:`solve` returns ``x``."""

    n: int
    eps: float = 1e-7
    max_iter: int = 4000
    _solver: osqp.OSQP | None = field(default=None, repr=False)
    _rows: tuple[np.ndarray, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        cols, rows = zip(*[(j, i) for j in range(self.n) for i in range(j + 1)])
        self._rows = (np.asarray(rows), np.asarray(cols))  # CSC order of the upper triangle

    def solve(self, p: FloatArray, c: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
        """The minimizer; ``p`` must be symmetric positive definite (damping makes it so)."""
        values = p[self._rows]
        if self._solver is None:
            self._solver = self._setup(p, c, lo, hi)
        else:
            self._solver.update(Px=values, q=c, l=lo, u=hi)
            self._solver.update_settings(rho=RHO)  # not the last solve's adapted step size
        result = self._solver.solve(raise_error=False)
        x = np.asarray(result.x, dtype=float)
        if not np.all(np.isfinite(x)):  # OSQP gave up: stay put rather than jump
            return np.zeros(self.n)
        return np.clip(x, lo, hi)

    def _setup(self, p: FloatArray, c: FloatArray, lo: FloatArray, hi: FloatArray) -> osqp.OSQP:
        upper = sp.csc_matrix(np.triu(np.ones((self.n, self.n))))
        upper.data = p[self._rows]
        solver = osqp.OSQP()
        solver.setup(
            upper,
            c,
            sp.identity(self.n, format="csc"),
            lo,
            hi,
            verbose=False,
            eps_abs=self.eps,
            eps_rel=self.eps,
            max_iter=self.max_iter,
            polishing=False,  # the outer iteration refines; polishing only prints here
            # a solve depends on its problem alone, not on whichever solve came before it (OSQP
            # 1.x adapts rho by iteration counts, its time limit is off: nothing timed)
            warm_starting=False,
            rho=RHO,
        )
        return solver
