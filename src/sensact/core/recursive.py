"""Recursive weighted polynomial regression with exponential forgetting (sec. 3.2.1 and 3.2.3).

The fit keeps only the sums ``G = X'DX`` and ``h = X'Dy`` with ``D_ii = gamma**(n-i)`` (eq. 3.3), updated
in O(d^2) per point via ``sum_{k<=n+1} gamma^(n+1-k) z_k = gamma * sum_{k<=n} gamma^(n-k) z_k + z_{n+1}``.
The coefficients come from a small Cholesky solve. The kernels are numba functions so that the
learners' compiled loops can call them; ``RecursivePolyFit`` is the plain-Python face of the same code.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensact.core.smallmat import cholesky_shifted, cholesky_solve_vec


@njit(cache=True)
def accumulate_poly(G, h, u, y, gamma, p):
    """``G <- gamma G + x x'``, ``h <- gamma h + y x`` with ``x = (1, u, ..., u**(p-1))``."""
    xi = 1.0
    for i in range(p):
        h[i] = gamma * h[i] + y * xi
        xj = 1.0
        for j in range(p):
            G[i, j] = gamma * G[i, j] + xi * xj
            xj *= u
        xi *= u


@njit(cache=True)
def accumulate_vector(G, h, x, y, gamma, p):
    """``G <- gamma G + x x'``, ``h <- gamma h + y x`` for a general feature vector ``x[:p]``."""
    for i in range(p):
        h[i] = gamma * h[i] + y * x[i]
        for j in range(p):
            G[i, j] = gamma * G[i, j] + x[i] * x[j]


@njit(cache=True)
def solve_spd(G, h, p, ridge, L, out):
    """Solve ``(G + ridge * mean(diag G) * I) beta = h`` on the leading ``p`` block by Cholesky.

    ``L`` is a ``(>=p, >=p)`` work array. Writes ``beta`` into ``out[:p]`` and returns True, or returns
    False (leaving ``out`` untouched) when the block is not numerically positive definite. A hand-written
    solve because LAPACK's call overhead dominates at p <= 7 inside a per-step loop.
    """
    tr = 0.0
    for i in range(p):
        tr += G[i, i]
    if not cholesky_shifted(G, ridge * tr / p, L, p, 1e-300 * (tr + 1.0)):
        return False
    z0 = np.empty(p)
    cholesky_solve_vec(L, h, z0, p)
    for i in range(p):
        if not np.isfinite(z0[i]):
            return False
    for i in range(p):
        out[i] = z0[i]
    return True


@njit(cache=True)
def solve_normal_equations(G, h, p, ridge, L, out):
    """Eq. 3.3 as the thesis solves it (no regularization); only when the block is numerically
    singular, retry with the relative ``ridge`` so that the estimate stays finite."""
    if solve_spd(G, h, p, 0.0, L, out):
        return True
    return solve_spd(G, h, p, ridge, L, out)


@njit(cache=True)
def shift_features(G, h, s, p):
    """Re-express the sums for features ``x'_j = x_j - s_j x_0`` (``j >= 1``, ``x_0 == 1``), exactly.

    With ``x' = M x`` the sums become ``M G M'`` and ``M h``. Used to keep eq. 3.2's cumulative command
    sums near zero: the intercept ``w_0`` absorbs the shift, every other coefficient is unchanged.
    """
    g00 = G[0, 0]
    row0 = np.empty(p)
    for j in range(p):
        row0[j] = G[0, j]
    for i in range(1, p):
        for j in range(1, p):
            G[i, j] = G[i, j] - s[i] * row0[j] - s[j] * row0[i] + s[i] * s[j] * g00
    for j in range(1, p):
        G[0, j] = row0[j] - s[j] * g00
        G[j, 0] = G[0, j]
    h0 = h[0]
    for j in range(1, p):
        h[j] = h[j] - s[j] * h0


@njit(cache=True)
def poly_eval(coef, u, p):
    """Horner evaluation of ``coef[:p]`` (ascending) at scalar ``u``."""
    v = 0.0
    for i in range(p - 1, -1, -1):
        v = v * u + coef[i]
    return v


class RecursivePolyFit:
    """Weighted polynomial regression that forgets old points by ``gamma`` per new point (eq. 3.3).

    >>> fit = RecursivePolyFit(degree=2, gamma=0.999, center=0.0, scale=10.0)
    >>> for x in range(20): fit.update(x, 3.0 + 0.5 * x**2)
    >>> round(float(fit.predict(4.0)), 6)
    11.0
    """

    def __init__(
        self, degree: int, gamma: float = 1.0, *, center: float = 0.0, scale: float = 1.0, ridge: float = 1e-12
    ) -> None:
        if degree < 0:
            raise ValueError("degree must be >= 0")
        if not 0.0 < gamma <= 1.0:
            raise ValueError("gamma must be in (0, 1]")
        if scale <= 0:
            raise ValueError("scale must be > 0")
        self.degree, self.gamma, self.center, self.scale, self.ridge = degree, gamma, center, scale, ridge
        p = degree + 1
        self.G = np.zeros((p, p))
        self.h = np.zeros(p)
        self._L = np.zeros((p, p))
        self._coef = np.full(p, np.nan)
        self.n = 0

    def update(self, x: float, y: float) -> None:
        u = (float(x) - self.center) / self.scale
        accumulate_poly(self.G, self.h, u, float(y), self.gamma, self.degree + 1)
        self.n += 1
        solve_normal_equations(self.G, self.h, self.degree + 1, self.ridge, self._L, self._coef)

    @property
    def coef(self) -> np.ndarray:
        """Ascending coefficients in ``u = (x - center) / scale`` (NaN until the fit is determined)."""
        return self._coef.copy()

    def predict(self, x: np.ndarray | float) -> np.ndarray:
        from sensact.core.polyfit import polyval

        return polyval(self._coef, (np.asarray(x, dtype=float) - self.center) / self.scale)
