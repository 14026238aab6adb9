"""A 1-D log on one time grid (``TrackLog``), as the native log folder (``io/logfolder.py``) and a Turtlebot CSV
(``io/turtlebot.py``) both read it: its own module, so that neither reader imports the other's."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sensact.records import JsonObject


@dataclass(frozen=True)
class TrackLog:
    """A 1-D log on one time grid: the command in force from each step, and the observation at it."""

    times_s: np.ndarray  # (T,) strictly increasing
    commands: np.ndarray  # (T,) zero-order hold of the logged commands
    observations: np.ndarray  # (T,) NaN where there is no observation
    command_unit: str
    observation_name: str
    observation_unit: str
    source: str
    meta: JsonObject = field(default_factory=dict)
    true_position: np.ndarray | None = None  # (T,) only for evaluation
    position_unit: str = ""

    @property
    def duration_s(self) -> float:
        return float(self.times_s[-1] - self.times_s[0])

    @property
    def n_observations(self) -> int:
        return int(np.isfinite(self.observations).sum())
