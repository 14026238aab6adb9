"""Chapter 3's models of a real 1-D robot scored against measured models built from the log's recorded
positions (never used for learning): the sensor over its datasheet range in 10-cm bins, the action model
against the timed velocities (``sensact learn bootstrap`` on a log with truth, and ``reproduce turtlebot``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.evaluate.measured import MeasuredAction, MeasuredSensor, measure_action, measure_sensor
from sensact.evaluate.scaled import ModelPairScore, fit_scale, score_models
from sensact.io.logfolder import TrackLog
from sensact.io.turtlebot import SPEC_RANGE_M
from sensact.learn.bootstrap import BootstrapConfig, BootstrapResult

# the measured sensor's bins (sec. 3.3.2 measured the Aibo's every 10 cm), whatever the log's distance unit
SENSOR_BIN_M = 0.1
METRES_PER_UNIT = {"m": 1.0, "cm": 0.01, "mm": 0.001}
BINS_PER_SPAN = 32  # a distance in a unit not named above: the Turtlebot's 3.2 m span in 10-cm bins


def sensor_bin_width(position_unit: str, positions: np.ndarray) -> float:
    """10 cm in the log's distance unit; in a unit it does not name, 1/32 of the distances' span."""
    if position_unit in METRES_PER_UNIT:
        return SENSOR_BIN_M / METRES_PER_UNIT[position_unit]
    return float(np.nanmax(positions) - np.nanmin(positions)) / BINS_PER_SPAN


@dataclass(frozen=True)
class RealRun:
    log: TrackLog
    result: BootstrapResult
    score: ModelPairScore
    measured_sensor: MeasuredSensor
    measured_action: MeasuredAction
    learned_gain: float  # slope through the origin of the learned A, in distance units by S's scale b
    true_gain: float  # slope through the origin of the timed velocities

    @property
    def sensor_span(self) -> float:
        """The distances the sensor is scored over: the span of its measured bins' centres."""
        p = self.measured_sensor.positions
        return float(np.ptp(p)) if p.size else float("nan")


def evaluate_real(log: TrackLog, result: BootstrapResult, config: BootstrapConfig) -> RealRun:
    """Score against measured models built from the log's true positions (never used for learning).

    The sensor is compared over its datasheet range, at 10 cm bins whose median reading is inside the
    learner's observation window.
    """
    if log.true_position is None:
        raise ValueError(f"{log.source} has no ground truth column to evaluate against")
    lo = -np.inf if config.observation_min is None else config.observation_min
    hi = np.inf if config.observation_max is None else config.observation_max
    d_lo, d_hi = SPEC_RANGE_M.get(log.observation_name, (-np.inf, np.inf))
    x = log.true_position
    in_spec = (x >= d_lo) & (x <= d_hi)
    ms = measure_sensor(
        np.where(in_spec, log.observations, np.nan),
        x,
        bin_width=sensor_bin_width(log.position_unit, x),
        window=(lo, hi),
    )
    ma = measure_action(log.times_s, log.commands, log.true_position)
    score = score_models(
        result.sensor,
        result.action,
        observations=ms.observations,
        distances=ms.positions,
        commands=ma.commands,
        velocities=ma.velocities,
    )
    # S and A share the learned unit w (sec. 3.2), and distance = a + b S(o), so the learned velocity in
    # distance units is b A(c). A's own optimal scale k (sec. 3.3.2's action error) is fitted to the
    # timed velocities, so through it a straight A would match the timed gain exactly, however wrong.
    learned_gain = score.sensor_scale_b * fit_scale(ma.commands, result.action(ma.commands)).scale
    return RealRun(log, result, score, ms, ma, learned_gain, fit_scale(ma.commands, ma.velocities).scale)
