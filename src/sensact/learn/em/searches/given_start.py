"""A start pose the user gave, for a sensor that cannot search for one (beyond the thesis, whose robots
started at a known pose).

The start search scores start poses by the bearings (``searches/start_race.py``), so a range-only log (UWB anchors,
sonar beacons) starts where the user says, ``start_prior_mean`` within ``start_prior_sd``. EM
re-estimates the prior from gamma_0 (sec. 4.3), and from a start a few metres off it can find the path
while the turn rate it learns is wrong: the heading noise carries the turns. Measured on 5 minutes of
the simulated radio robot (docs/em-real.md, section 2, "A sensor without bearings"): from 3.2 m off,
the path was 14 mm off the truth, the turn gain -1.12 against 0.92, and the learned start within
150 mm of the true one; EM from that learned start found the model (turn gain 0.925, 411 log-units
more likely). So when the start moved more than ``moved_start_sds`` of the start's position sd, EM
runs again from where the first run put it, and the more likely run is kept (``fit.fit_em``).
"""

from __future__ import annotations

import numpy as np

from sensact.learn.em.config import EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel


def start_moved_mm(start: EMModel, learned: EMModel, data: LandmarkLog, config: EMConfig) -> float | None:
    """How far (mm) EM moved a range-only log's given start, when that is more than ``moved_start_sds``
    of the prior's position sd; None otherwise, and for a log whose start was searched for or whose
    sensor reads bearings (they fix the heading, and the start search chose the start)."""
    if not data.geometry.has_heading or start.sensor.reads_bearing or config.search.start_s is not None:
        return None
    moved = float(np.hypot(*(learned.prior_mean[:2] - start.prior_mean[:2])))
    limit = config.search.moved_start_sds * float(np.sqrt(np.max(np.diag(start.prior_cov)[:2])))
    return moved if moved > limit else None
