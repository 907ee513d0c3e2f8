"""A small box-constrained QP on OSQP, set up once and warm-started for every later solve.

Each inverse-kinematics step solves ``min ½ xᵀ P x + cᵀ x  s.t.  lo <= x <= hi`` with a dense
``P`` of fixed size. OSQP needs its matrices in compressed-column form; the sparsity pattern
(a full upper triangle, an identity constraint matrix) never changes, so the solver is set up
once and each step only updates the numbers, keeping OSQP's factorization workspace and the
previous solution as a warm start.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp

FloatArray = np.ndarray


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
            warm_starting=True,
        )
        return solver
