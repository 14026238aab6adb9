"""``sensact learn em`` on a folder of scan-matched intervals (``convert intervals``; docs/lidar2d.md): the
wheels' radii, the axle and the lidar's mount with error bars, under the scan route's keys, from the
intervals Censi et al.'s tool or OdomLaserCalibraTool already computed."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sensact import __version__
from sensact.app.em import FitEvents
from sensact.app.lidar2d import fit_flags
from sensact.app.opened import FittedInSeconds, OpenedFolder
from sensact.app.save import Saved, save_model
from sensact.health import Health
from sensact.io.intervals import KIND
from sensact.learn.wheel_lidar import PARAMETERS, IntervalsResult, learn_intervals
from sensact.logs.intervals_log import IntervalsLog
from sensact.outputs import EM_MODEL, OUTPUT_KEY
from sensact.records import JsonObject

CONVENTIONS = {
    "phi_l, phi_r": "the wheels' angular velocities in rad/s, constant over each interval of T seconds",
    "sm": "the lidar's displacement over the interval in its own frame at the start (x forward, y left; m, rad)",
    "drive.delay_s": "not learned: intervals come without a clock to shift",
}


@dataclass(frozen=True, eq=False)
class OpenedIntervalsLog(OpenedFolder):
    """A folder of intervals, opened (``app.log_kinds``)."""

    data: IntervalsLog

    def describe(self) -> str:
        d = self.data
        return f"{self.path}: {d.n} scan-matched intervals over {float(d.t_s.sum()):.1f} s (from {d.source})"


def open_intervals_log(path: Path) -> OpenedIntervalsLog:
    from sensact.io.intervals import read_intervals_log

    return OpenedIntervalsLog(Path(path), read_intervals_log(path))


@dataclass(frozen=True, eq=False)
class IntervalsCalibration(FittedInSeconds[IntervalsLog, IntervalsResult]):
    PARAMETERS = PARAMETERS

    def to_json(self) -> JsonObject:
        fit, p, sd = self.result.fit, self.params, self.sds

        def pair(key: str) -> JsonObject:
            return {key: p[key], f"{key}_sd": sd[key]}

        noise = fit.noise.rep103()
        return {
            "sensact_version": __version__,
            OUTPUT_KEY: EM_MODEL,
            "kind": KIND,
            "log": self.log.source,
            "drive": {
                "source": "wheels",
                **pair("wheel_radius_left_mm"),
                **pair("wheel_radius_right_mm"),
                **pair("axle_mm"),
                # the lidar's displacement's variance (x, y in mm^2, yaw in rad^2) per interval, per mm and per rad
                "noise": {
                    "variance": noise.a.tolist(),
                    "variance_per_mm": noise.b.tolist(),
                    "variance_per_rad": noise.c.tolist(),
                },
            },
            "lidar": {"mount": {**pair("forward_mm"), **pair("left_mm"), **pair("yaw_rad")}},
            "censi": dict(zip(PARAMETERS[:6], map(float, self.result.closed_form[:6]), strict=True)),
            "conventions": CONVENTIONS,
            "fit": {
                "intervals": self.log.n,
                "intervals_used": int(fit.used.sum()),
                "chi2_per_dof": fit.chi2_per_dof,
                "distance_m": fit.distance_mm / 1000,
                "turn_rad": fit.turn_rad,
                "notes": list(self.result.notes),
                "seconds": self.seconds,
            },
            "evaluation": self.evaluation(),
            "health": self.health.to_dict(),
        }

    def evaluation(self) -> JsonObject | None:
        """Against a simulator's truth (``truth`` in meta.json, PARAMETERS' keys): each error in its own sd."""
        truth = self.log.truth
        if not truth:
            return None
        fit = self.result.fit
        out: JsonObject = {}
        for k, key in enumerate(PARAMETERS[:6]):
            if isinstance(truth.get(key), int | float):
                err = float(fit.params[k] - truth[key])
                out[key] = {"error": err, "error_sd": err / fit.sd[k] if fit.sd[k] > 0 else None}
        return out


def calibrate_intervals(log: IntervalsLog) -> IntervalsCalibration:
    t0 = time.monotonic()
    res = learn_intervals(log)
    return IntervalsCalibration(log, res, Health.of(*fit_flags(res.fit)), time.monotonic() - t0)


def calibrate_opened_intervals(
    log: OpenedIntervalsLog,
    preset: str | None = None,
    config: Any = None,
    *,
    sets: Any = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> IntervalsCalibration:
    """The kind's learner (``app.log_kinds``): it takes no EM settings (the door refuses them)."""
    return calibrate_intervals(log.data)


def save_intervals(cal: IntervalsCalibration, out: Path, report: bool = True) -> Saved:
    """model.json (no report page: intervals carry no scans or path to draw)."""
    return save_model(out, cal.to_json(), None)


def rows(cal: IntervalsCalibration) -> list[list[str]]:
    """The console's table: each learned number, its sd, and Censi et al.'s closed form on the same intervals."""
    fit, censi = cal.result.fit, cal.result.closed_form
    labels = (
        "left wheel radius (mm)",
        "right wheel radius (mm)",
        "axle (mm)",
        "lidar forward (mm)",
        "lidar left (mm)",
        "lidar yaw (rad)",
    )
    return [[label, f"{fit.params[k]:.6g}", f"{fit.sd[k]:.2g}", f"{censi[k]:.6g}"] for k, label in enumerate(labels)]
