"""The thesis's measured models for the 1-D track, taken from the simulator's truth (sec. 3.3.2).

The thesis timed every command that is a multiple of 20 mm/s from -300 to 300, and recorded the mean
beacon height at every multiple of 20 cm from 120 to 360 cm. We evaluate the true curves on that grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.evaluate.scaled import ModelPairScore, score_models
from sensact.models.polynomial import Polynomial1D
from sensact.sim.track1d import TrackTruth

COMMAND_GRID_MM_S = np.arange(-300.0, 300.0 + 1e-9, 20.0)
DISTANCE_GRID_MM = np.arange(1200.0, 3600.0 + 1e-9, 200.0)
VELOCITY_RANGE_MM_S = 600.0  # "the velocity range of 600 mm/s", sec. 3.3.2
DISTANCE_RANGE_MM = 2400.0  # "the distance range of 2400 mm", sec. 3.3.2


@dataclass(frozen=True)
class MeasuredModels:
    commands_mm_s: np.ndarray
    velocities_mm_s: np.ndarray
    heights_px: np.ndarray
    distances_mm: np.ndarray


def measured_models(truth: TrackTruth) -> MeasuredModels:
    return MeasuredModels(
        COMMAND_GRID_MM_S, truth.velocity_mm_s(COMMAND_GRID_MM_S), truth.height_px(DISTANCE_GRID_MM), DISTANCE_GRID_MM
    )


def score_track_models(sensor: Polynomial1D, action: Polynomial1D, truth: TrackTruth) -> ModelPairScore:
    m = measured_models(truth)
    return score_models(
        sensor,
        action,
        observations=m.heights_px,
        distances=m.distances_mm,
        commands=m.commands_mm_s,
        velocities=m.velocities_mm_s,
    )


def converged(score: ModelPairScore, status: str) -> bool:
    """A trial converged when it did not diverge and both scaled errors are within 10 % of the range.

    The thesis counts "trials resulting in the sensor and action models converging" without a formula;
    10 % of the range is about three times its own mean errors, and far below the error of models that
    collapsed or drifted. The same rule applies to every row.
    """
    return (
        status == "ok"
        and bool(np.isfinite(score.sensor_rms) and np.isfinite(score.action_rms))
        and score.sensor_rms <= 0.10 * DISTANCE_RANGE_MM
        and score.action_rms <= 0.10 * VELOCITY_RANGE_MM_S
    )
