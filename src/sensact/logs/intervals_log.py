"""Scan-matched intervals as Censi et al.'s calibration tool and OdomLaserCalibraTool hold them (docs/lidar2d.md):
each interval's length, the two wheels' angular velocities over it (constant within it) and the scan matcher's
displacement of the lidar over it, in the lidar's own frame at the interval's start (REP 103: x forward, y
left, metres and radians)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class IntervalsLog:
    source: str
    t_s: np.ndarray  # (n,) each interval's length T
    phi_rad_s: np.ndarray  # (n, 2) left and right wheels' angular velocities
    sm_m: np.ndarray  # (n, 3) the lidar's displacement: x, y (m), theta (rad), its own frame at the start
    truth: dict | None = None  # the simulator's parameters (scoring only)

    @property
    def n(self) -> int:
        return int(self.t_s.size)
