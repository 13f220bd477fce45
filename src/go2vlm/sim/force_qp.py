"""Ground-reaction-force distribution: a small QP solved with OSQP.

minimise ||A f - w||_S^2 + alpha ||f||^2 over the 12 foot forces (world frame)
subject to friction pyramids and fz in [fz_min, fz_max] on stance feet and
f = 0 on swing feet.  A maps foot forces to the net wrench about the CoM.
"""

from __future__ import annotations

import numpy as np
import osqp
import scipy.sparse as sp


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


class ForceQP:
    def __init__(
        self,
        mu: float = 0.6,
        fz_min: float = 5.0,
        fz_max: float = 250.0,
        weights: tuple[float, ...] = (1.0, 1.0, 5.0, 20.0, 20.0, 10.0),
        alpha: float = 1e-4,
    ) -> None:
        self.mu, self.fz_min, self.fz_max, self.alpha = mu, fz_min, fz_max, alpha
        self.S = np.diag(weights)
        self._rows, self._cols = np.triu_indices(12)
        order = np.lexsort((self._rows, self._cols))  # CSC order: by column, then row
        self._rows, self._cols = self._rows[order], self._cols[order]
        p_pattern = sp.csc_matrix((np.ones(len(self._rows)), (self._rows, self._cols)), shape=(12, 12))
        c = np.zeros((20, 12))
        for i in range(4):
            r, k = 5 * i, 3 * i
            c[r, [k, k + 2]] = [1.0, -mu]
            c[r + 1, [k, k + 2]] = [-1.0, -mu]
            c[r + 2, [k + 1, k + 2]] = [1.0, -mu]
            c[r + 3, [k + 1, k + 2]] = [-1.0, -mu]
            c[r + 4, k + 2] = 1.0
        self._l = np.tile([-np.inf, -np.inf, -np.inf, -np.inf, fz_min], 4)
        self._u = np.tile([0.0, 0.0, 0.0, 0.0, fz_max], 4)
        self._solver = osqp.OSQP()
        self._solver.setup(
            p_pattern,
            np.zeros(12),
            sp.csc_matrix(c),
            self._l,
            self._u,
            verbose=False,
            warm_starting=True,
            polishing=False,
            eps_abs=1e-3,
            eps_rel=1e-3,
            max_iter=400,
            adaptive_rho=True,
        )

    def solve(self, r_feet: np.ndarray, stance: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        """Forces (4, 3) for feet at ``r_feet`` (4, 3, relative to CoM, world frame)."""
        a = np.zeros((6, 12))
        for i in range(4):
            if stance[i]:
                a[0:3, 3 * i : 3 * i + 3] = np.eye(3)
                a[3:6, 3 * i : 3 * i + 3] = skew(r_feet[i])
        h = a.T @ self.S @ a + self.alpha * np.eye(12)
        q = -(a.T @ self.S @ wrench)
        lo, up = self._l.copy(), self._u.copy()
        for i in range(4):
            if not stance[i]:
                lo[5 * i + 4] = up[5 * i + 4] = 0.0
        self._solver.update(Px=h[self._rows, self._cols], q=q, l=lo, u=up)
        res = self._solver.solve(raise_error=False)
        x = res.x
        if x is None or not np.all(np.isfinite(x)):
            return self._fallback(stance, wrench)
        return np.asarray(x).reshape(4, 3)

    def _fallback(self, stance: np.ndarray, wrench: np.ndarray) -> np.ndarray:
        n = max(int(np.sum(stance)), 1)
        f = np.zeros((4, 3))
        f[stance, 2] = np.clip(wrench[2] / n, self.fz_min, self.fz_max)
        return f
