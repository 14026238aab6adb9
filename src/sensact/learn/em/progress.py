"""How many iterations EM will take, projected from how fast its likelihood is converging, for a progress
bar's ETA. EM stops ``patience`` iterations after its last new best (sec. 4.4.1), and near its fixed point it
converges linearly: each iteration's gain in the best log-likelihood is about ``r`` times the one before. So
the gap left to the limit is about ``gain * r / (1 - r)``, and EM's best stops moving, to within ``TOL``, after
``log(TOL / gap) / log(r)`` more iterations; it ends ``patience`` iterations after that. A projection for
display only: it never steers the fit, and ``max_iterations`` is only its ceiling."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

TOL = 0.05  # a log-likelihood gain below this is within an approximate E-step's fluctuation
WINDOW = 20  # the recent iterations the rate is measured over


class ConvergenceEta:
    """Feed it each iteration's ``(it, best)``; ``total(it, since, patience, cap)`` is the projected count."""

    def __init__(self) -> None:
        self.best: list[float] = []

    def total(self, it: int, best: float, since: int, patience: int, cap: int | None = None) -> int:
        """The iterations EM is projected to run, more than ``it + 1`` and at most ``cap`` (but for that)."""
        if it == 0:  # a fit (a restart, the next stage's race) begins again
            self.best = []
        self.best.append(best)
        done = it + 1
        projected = done + max(patience - since, 1)
        gains = [b - a for a, b in itertools.pairwise(self.best[-WINDOW - 1 :])]
        if since == 0 and len(gains) >= 4 and gains[-1] > TOL:
            first, last = sum(gains[: len(gains) // 2]), sum(gains[len(gains) // 2 :])
            if first > 0 and 0 < last < first:
                r = (last / first) ** (1.0 / (len(gains) // 2))  # the mean rate over the window's halves
                gap = gains[-1] * r / (1.0 - r)
                if gap > TOL:
                    projected += math.ceil(math.log(TOL / gap) / math.log(r))
            else:  # not yet slowing down: at least as long again as it has run
                projected += done
        return max(done + 1, min(projected, cap)) if cap is not None else max(done + 1, projected)


def iteration_progress(
    progress: Callable[[str, int, int | None], None] | None, describe: Callable[[int, float, float], str], thesis: Any
) -> Callable[[int, float, float, int], None]:
    """EM's ``progress(it, ll, best, since)`` as a progress bar's ``(description, done, total)``, the total
    projected from the convergence rate (``thesis``: the fit's ``ThesisSettings``, for patience and the cap)."""
    eta = ConvergenceEta()

    def on_iteration(it: int, ll: float, best: float, since: int) -> None:
        if progress is not None:
            total = eta.total(it, best, since, thesis.patience, thesis.max_iterations)
            progress(describe(it, ll, best), it + 1, total)

    return on_iteration
