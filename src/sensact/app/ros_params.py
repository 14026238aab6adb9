"""What a ROS parameter file of robot_localization's holds, shared by every model's export (``app/export.py``,
``app/export_lidar2d.py``): its 15 states and their defaults, the process noise from a per-second noise, and
the refusal of a value that is not finite."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sensact.errors import ModelFormatError

RL_STATES = ("x", "y", "z", "roll", "pitch", "yaw", "vx", "vy", "vz", "vroll", "vpitch", "vyaw", "ax", "ay", "az")
# robot_localization's own defaults (its ekf.yaml template) for the states a planar EM model says nothing of
RL_DEFAULT_DIAG = (0.05, 0.05, 0.06, 0.03, 0.03, 0.06, 0.025, 0.025, 0.04, 0.01, 0.01, 0.02, 0.01, 0.01, 0.015)


def process_noise(sigma_step: np.ndarray, dt_s: float) -> np.ndarray:
    """robot_localization's 15x15 process_noise_covariance, which it scales by the time step (per second).
    Its x and y are the world's: Sigma_m's body-frame forward and sideways variances averaged over headings
    (the mean of a covariance rotated through every heading is its trace over 2 on both axes); yaw is
    Sigma_m's own. The states a planar model does not learn keep robot_localization's defaults."""
    q = np.diag(np.array(RL_DEFAULT_DIAG, dtype=float))
    per_s = sigma_step / dt_s  # eq. 4.1's per-step noise as a rate: a random walk's variance grows with time
    horizontal = 0.5 * (per_s[0, 0] + per_s[1, 1])
    q[0, 0] = q[1, 1] = horizontal
    q[5, 5] = per_s[2, 2]
    return q


def refuse_non_finite(values: Any, source: Path, where: str = "") -> None:
    """An export never holds NaN or inf: a model whose numbers make one is refused, naming the field."""
    if isinstance(values, dict):
        for k, v in values.items():
            refuse_non_finite(v, source, f"{where}.{k}" if where else str(k))
    elif isinstance(values, list | tuple):
        for v in values:
            refuse_non_finite(v, source, where)
    elif isinstance(values, float) and not math.isfinite(values):
        raise ModelFormatError(
            f"its export's {where} would be {values} (a model field out of range).",
            file=source,
            field="model",
            fix="learn it again with `sensact learn em`.",
        )
