"""EM at its fixed point (docs/em.md, "Stopping"; beyond the thesis, which stops by patience, sec. 4.4.1).

The deterministic (sigma-point) M-step makes EM a map ``lambda -> M(E(lambda))`` whose fixed point is the
fit. A step ``d`` of the learned parameters (``space.LearnedSpace``) is measured by its length in the
observed information, ``|d|_I = sqrt(d' I d)``, which one second difference of the likelihood along ``d``
gives (``Information.length``). No parameter moves more than ``|d|_I`` of its own standard error (the
observed information's inverse; Cauchy-Schwarz), so EM is at its fixed point when the rest of its way
there, estimated from its last two steps (``rest_of_the_way``), has ``|d|_I < STOP_SD``; an accelerated
step is bounded, and judged, in the same length (``loop.squarem_loop``), not by the likelihood, which EM
with an EKF E-step does not climb.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sensact.learn.em.space import LearnedSpace
from sensact.models.em_model import EMModel

STOP_SD = 0.05  # the rest of the way below this many standard errors in every parameter: the fixed point
# an accelerated step lands no further than this, in the observed information's length, from EM's own two steps
STEP_BOUND_SD = 10.0
MAX_RATE = 0.999  # EM's steps shrinking slower than this: not yet contracting, not stopped


@dataclass(frozen=True, eq=False)
class Information:
    """Lengths of steps about ``space``'s model in its observed information, by second differences of
    ``space``'s likelihood."""

    space: LearnedSpace
    loglik0: float  # the likelihood at ``space``'s model (its E-step's: the forward pass's, bit for bit)

    def step(self, a: EMModel, b: EMModel) -> np.ndarray:
        """The step from ``a`` to ``b`` in the learned parameters."""
        return self.space.p_of(b) - self.space.p_of(a)

    def length(self, d: np.ndarray) -> float:
        """``sqrt(d' I d)`` at the model, from ``2 l(p) - l(p + d) - l(p - d)`` (exact on a quadratic); inf
        where ``p +- d`` is no model. Where the likelihood bends up along ``d`` (the fit is not at a top
        there), the bend's size."""
        if not np.any(d):
            return 0.0
        p = self.space.p0
        up, down = self.space.loglik(p + d), self.space.loglik(p - d)
        if not (math.isfinite(up) and math.isfinite(down)):
            return math.inf
        return math.sqrt(abs(2.0 * self.loglik0 - up - down))


def rest_of_the_way(last: np.ndarray, now: np.ndarray) -> np.ndarray | None:
    """The way left to the fixed point after EM's step ``now`` (the one before it: ``last``): EM converges
    linearly, at a rate ``r`` the steps' lengths' ratio estimates, so the rest of the way is about
    ``now / (1 - r)`` (Aitken's estimate; exact on a linear map, whose steps shrink by ``r``: a step alone
    says little where EM crawls, at ``r`` near 1). None where EM is not contracting (``r >= MAX_RATE``)."""
    norm_now, norm_last = float(np.linalg.norm(now)), float(np.linalg.norm(last))
    if norm_now == 0.0:
        return now
    rate = norm_now / norm_last if norm_last > 0 else math.inf
    return now / (1.0 - rate) if rate < MAX_RATE else None
