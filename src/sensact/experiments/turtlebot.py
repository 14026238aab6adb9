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

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sensact.config import config_to_dict
from sensact.errors import LogFormatError
from sensact.evaluate.real_track import RealRun, evaluate_real
from sensact.io.logfolder import read_track_log
from sensact.io.turtlebot import turtlebot_sensors
from sensact.learn.bootstrap import BootstrapConfig, learn_bootstrap
from sensact.presets import TURTLEBOT_LEARNER, learner_for
from sensact.records import JsonObject

DEFAULT_SENSORS = ("sonar1", "sonar2", "raw_ir4", "raw_ir3")


def run_turtlebot(
    csv_path: str | Path, sensors: tuple[str, ...] = DEFAULT_SENSORS, base: BootstrapConfig = TURTLEBOT_LEARNER
) -> tuple[JsonObject, dict[str, RealRun]]:
    t0 = time.perf_counter()
    rows: JsonObject = {}
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
) -> tuple[JsonObject, dict[str, dict[str, RealRun]]]:
    """``run_turtlebot`` on each training log (``shared_data.turtlebot_logs``). The first log that can be
    scored is the result itself (turtlebot.json as for ``training1.csv`` alone); the others go under
    ``more_logs`` by file stem, and a log that cannot be scored (a ``LogFormatError``: no range, none of
    the sensors) under ``skipped_logs`` while the others run. The runs are keyed by stem. When no log
    can be scored, the first log's error is raised."""
    t0 = time.perf_counter()
    out: JsonObject | None = None
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
