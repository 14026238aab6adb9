"""Bounds checked before anything is allocated (docs/errors.md): a bogus time, step or size in an input must be
refused by name, not turned into an array the machine cannot hold.

Each limit is settable by an environment variable, which the error names, for the rare real input beyond it.
"""

from __future__ import annotations

import math
import os


def _env_int(name: str, default: int) -> int:
    text = os.environ.get(name)
    try:
        return int(float(text)) if text else default
    except ValueError:
        return default


# time steps in one log or simulation: 2 million is 18.5 h at 30 Hz; EM's posteriors take about 400 bytes a step
MAX_STEPS = _env_int("SENSACT_MAX_STEPS", 2_000_000)


def steps_problem(n_steps: float, what: str) -> str | None:
    """Why ``n_steps`` time steps cannot be allocated (not finite, or over ``MAX_STEPS``), or None."""
    if not math.isfinite(n_steps):
        return f"{what} is not a finite number of steps"
    if n_steps > MAX_STEPS:
        return (
            f"{what} would be {n_steps:.3g} steps, over the limit of {MAX_STEPS:,} "
            "(check the times' unit and the step; SENSACT_MAX_STEPS raises it)"
        )
    return None


# the largest magnitude a command, reading, position or pose may have, in its own unit (a millimetre, a pixel,
# a raw count): 1e9 mm is 1,000 km. Times are bounded by MAX_STEPS instead (a Unix time is 1.7e9 s).
MAX_VALUE = float(_env_int("SENSACT_MAX_VALUE", 1_000_000_000))


def value_problem(values: object, what: str) -> str | None:
    """Why ``values`` cannot be taken as numbers in a unit (one is beyond ``MAX_VALUE``), or None."""
    import numpy as np

    v = np.abs(np.asarray(values, dtype=float))
    v = v[np.isfinite(v)]
    if v.size and float(v.max()) > MAX_VALUE:
        return f"{what} holds {float(v.max()):.3g}, beyond {MAX_VALUE:.3g} in any unit (SENSACT_MAX_VALUE raises it)"
    return None


# trials of one experiment (`reproduce --trials`): a mistyped count is refused, not run for days
MAX_TRIALS = _env_int("SENSACT_MAX_TRIALS", 10_000)

# worker processes started on this machine (`--workers`): each is a Python with numpy, about 150 MB
MAX_WORKERS = _env_int("SENSACT_MAX_WORKERS", 256)

# actions a continuous 1-D command is binned into (`--bins`): each has its own velocity and noise to learn
MAX_BINS = _env_int("SENSACT_MAX_BINS", 1_000)


def thread_budget() -> int:
    """Threads one process keeps busy (a start race's trials): ``SENSACT_THREADS``, which the engine sets to
    a Dask worker's allocation (two one-thread workers on two cores must not run four threads), else
    this machine's cores."""
    return max(_env_int("SENSACT_THREADS", os.cpu_count() or 1), 1)
