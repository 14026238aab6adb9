"""Algorithm 1 on a real robot: the Turtlebot driving toward and away from a wall (turtlebot1d).

The log is far from the Aibo's protocol: its first leg is one 0.04 m/s command held for 77 s, and it
uses only four speeds. Two settings follow from that, both model choices a user makes for a
differential-drive robot, not tuning to one file:

* an **affine action model** (degree 1): a wheel-speed controller tracks its command nearly linearly,
  and eq. 3.2 cannot identify a quartic from four speeds;
* **t_start = 60 s**: ``A_t`` replaces ``A0`` at ``2 t_start``; fit earlier, it would have seen a
  single command, for which eq. 3.2's regressors are collinear.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact.config import config_to_dict
from sensact.errors import LogFormatError
from sensact.evaluate.measured import MeasuredAction, MeasuredSensor, measure_action, measure_sensor
from sensact.evaluate.scaled import ModelPairScore, fit_scale, score_models
from sensact.io.logfolder import TrackLog, read_track_log
from sensact.io.turtlebot import LEARNER_SETTINGS, SPEC_RANGE_M, turtlebot_sensors
from sensact.learn.bootstrap import BootstrapConfig, BootstrapResult, learn_bootstrap

TURTLEBOT_LEARNER = BootstrapConfig(t_start_s=60.0, action_degree=1)
DEFAULT_SENSORS = ("sonar1", "sonar2", "raw_ir4", "raw_ir3")
# the measured sensor's bins (sec. 3.3.2 measured the Aibo's every 10 cm), whatever the log's distance unit
SENSOR_BIN_M = 0.1
METRES_PER_UNIT = {"m": 1.0, "cm": 0.01, "mm": 0.001}
BINS_PER_SPAN = 32  # a distance in a unit not named above: the Turtlebot's 3.2 m span in 10-cm bins


def sensor_bin_width(position_unit: str, positions: np.ndarray) -> float:
    """10 cm in the log's distance unit; in a unit it does not name, 1/32 of the distances' span."""
    if position_unit in METRES_PER_UNIT:
        return SENSOR_BIN_M / METRES_PER_UNIT[position_unit]
    return float(np.nanmax(positions) - np.nanmin(positions)) / BINS_PER_SPAN


def learner_for(sensor: str, base: BootstrapConfig = TURTLEBOT_LEARNER) -> BootstrapConfig:
    return dataclasses.replace(base, **LEARNER_SETTINGS.get(sensor, {}))


def track_learner(robust: bool) -> BootstrapConfig:
    """Chapter 3's settings for another 1-D robot's distance reading (``sensact convert track``): the
    Turtlebot's, with sonar1's outlier gate for a reading asked to be robust. Its windows in value are
    sonar1's datasheet in metres, not this reading's, and are left out."""
    gate = LEARNER_SETTINGS["sonar1"]["outlier_gate"] if robust else None
    return dataclasses.replace(TURTLEBOT_LEARNER, outlier_gate=gate)


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


def run_turtlebot(
    csv_path: str | Path, sensors: tuple[str, ...] = DEFAULT_SENSORS, base: BootstrapConfig = TURTLEBOT_LEARNER
) -> tuple[dict[str, Any], dict[str, RealRun]]:
    t0 = time.perf_counter()
    rows: dict[str, Any] = {}
    runs: dict[str, RealRun] = {}
    # a log without some of the default sensors runs the others; with none of them the reader says which
    present = turtlebot_sensors(csv_path)
    skipped = [s for s in sensors if s not in present]
    if len(skipped) < len(sensors):
        sensors = tuple(s for s in sensors if s in present)
    for sensor in sensors:
        log = read_track_log(csv_path, sensor=sensor)
        if log.true_position is None or not np.isfinite(log.true_position).any():  # before learning: nothing to score
            raise LogFormatError(
                "the log has no recorded range to score the learned models against.",
                file=csv_path,
                field="range",
                fix="add the range column (m), or learn from the log with `sensact learn bootstrap FILE` (no scores).",
            )
        cfg = learner_for(sensor, base)
        res = learn_bootstrap(
            log.times_s, log.commands, log.observations, cfg, units=(log.command_unit, log.observation_unit, "w")
        )
        run = evaluate_real(log, res, cfg)
        runs[sensor] = run
        span = run.sensor_span
        # A's own optimal scale fits any model exactly to one timed command, so its error needs two; the
        # gain (through S's scale) needs one
        timed = run.measured_action.commands.size
        vspan = float(np.ptp(run.measured_action.velocities)) if timed else 0.0
        rows[sensor] = {
            "status": res.status,
            "sensor_rms_m": run.score.sensor_rms,
            "sensor_rms_pct": 100.0 * run.score.sensor_rms / span,
            "sensor_best_rms_m": run.score.sensor_best_rms,
            "distance_span_m": span,
            "commands_timed": int(timed),
            "action_rms_m_s": run.score.action_rms if timed >= 2 else None,
            "action_rms_pct": 100.0 * run.score.action_rms / vspan if timed >= 2 and vspan > 0 else None,
            "learned_gain": run.learned_gain,
            "true_gain": run.true_gain,
            "gain_error_pct": 100.0 * abs(run.learned_gain / run.true_gain - 1.0) if timed else None,
            "consistency": run.score.consistency,
            "n_observations": res.n_observations,
            "n_gated": res.n_gated,
            "config": config_to_dict(cfg),
        }
    out = {"experiment": "turtlebot", "file": str(csv_path), "rows": rows, "skipped_sensors": skipped}
    return out | {"seconds": time.perf_counter() - t0}, runs


def run_turtlebot_logs(
    csv_paths: list[Path], progress: Callable[[str], None] | None = None
) -> tuple[dict[str, Any], dict[str, dict[str, RealRun]]]:
    """``run_turtlebot`` on each training log (``shared_data.turtlebot_logs``). The first log that can be
    scored is the result itself (turtlebot.json as for ``training1.csv`` alone); the others go under
    ``more_logs`` by file stem, and a log that cannot be scored (a ``LogFormatError``: no range, none of
    the sensors) under ``skipped_logs`` while the others run. The runs are keyed by stem. When no log
    can be scored, the first log's error is raised."""
    t0 = time.perf_counter()
    out: dict[str, Any] | None = None
    runs: dict[str, dict[str, RealRun]] = {}
    skipped: list[str] = []
    first_error: LogFormatError | None = None
    for path in csv_paths:
        if progress:
            progress(f"Algorithm 1 on {path.name}")
        try:
            res, by_sensor = run_turtlebot(path)
        except LogFormatError as exc:
            first_error = first_error or exc
            skipped.append(f"{path.name}: {exc}")
            continue
        runs[path.stem] = by_sensor
        if out is None:
            out = res
        else:
            out.setdefault("more_logs", {})[path.stem] = res
    if out is None:
        if first_error is None:
            raise ValueError("run_turtlebot_logs needs at least one log")
        raise first_error
    out["skipped_logs"] = skipped
    out["seconds"] = time.perf_counter() - t0
    return out, runs
