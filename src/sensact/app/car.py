"""``sensact learn em`` on a car log folder (docs/ackermann.md): the VESC's four numbers, the wheelbase, the delays
and the lidar's mount, each with its ``_sd``, the fit's health, scored against a simulator's truth, and saved with
its report page."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from sensact import __version__
from sensact.app.em import FitEvents
from sensact.app.opened import FittedInSeconds, OpenedFolder
from sensact.app.save import Saved, save_model
from sensact.health import Health, HealthFlag
from sensact.io.car_folder import KIND as CAR_KIND
from sensact.learn.car_lidar import (
    GAIN_SD_SHARE,
    MOUNT_SD_MM,
    MOUNT_SD_RAD,
    PARAMETERS,
    WHEELBASE_SD_SHARE,
    CarLidarResult,
    Steering,
    learn_car_lidar,
    old_straight_ahead,
    steering,
    yaml_before,
)
from sensact.logs.car_log import CarLog
from sensact.outputs import EM_MODEL, OUTPUT_KEY
from sensact.progress import Progress
from sensact.records import JsonObject


@dataclass(frozen=True, eq=False)
class OpenedCarLog(OpenedFolder):
    """A car log folder, opened (``app.log_kinds``)."""

    data: CarLog

    def describe(self) -> str:
        d = self.data
        return (
            f"{self.path}: {d.scan_t.size} scans of {d.beams} beams over {d.scan_t[-1] - d.scan_t[0]:.1f} s, "
            f"{d.erpm_t.size} VESC reports, {d.servo_t.size} servo commands"
        )


def open_car_log(path: Path) -> OpenedCarLog:
    from sensact.io.car_folder import read_car_log

    return OpenedCarLog(Path(path), read_car_log(path))


@dataclass(frozen=True, eq=False)
class CarCalibration(FittedInSeconds[CarLog, CarLidarResult]):
    PARAMETERS = PARAMETERS

    @cached_property
    def old_yaml(self) -> JsonObject:
        """The yaml the log was driven with (``yaml_before``: a least squares over /odom's rows)."""
        return yaml_before(self.log)

    @cached_property
    def steering(self) -> Steering:
        """The steering gain and the wheelbase; where the log's curves do not part them (``1 / gain^2`` not known
        to be positive), their product split by the wheelbase the log's own yaml gives (/odom's), the wheelbase's
        sd infinite: it is the yaml's, not learned. Flagged either way (``health_of``)."""
        st = steering(self.result.fit.params, self.result.fit.cov)
        old = self.old_yaml["wheelbase_mm"]
        if math.isfinite(st.gain) or old is None:
            return st
        length = old / 1000
        return Steering(st.product / length, st.product_sd / length, length, math.inf, st.product, st.product_sd)

    def notes(self) -> list[str]:
        notes = list(self.result.first.notes)
        if not math.isfinite(steering(self.result.fit.params, self.result.fit.cov).gain) and math.isfinite(
            self.steering.gain
        ):
            notes.append(
                "the curves did not part the steering gain from the wheelbase: their product is split by the "
                "wheelbase of the log's own yaml (from /odom)"
            )
        return notes

    def straight_ahead(self) -> JsonObject | None:
        """The wheels' angle while the log's own yaml commands straight ahead: its servo offset through the
        learned numbers (positive: left), with its sd."""
        old = old_straight_ahead(self.log)
        st, p, cov = self.steering, self.params, self.result.fit.cov
        if old is None or not math.isfinite(st.gain):
            return None
        angle = (old[1] - p["steering_angle_to_servo_offset"]) / st.gain
        # d angle / d (offset, gain): the gain's variance from the delta method's, the offset's from the fit
        var = (cov[3, 3] + (angle * st.gain_sd) ** 2) / st.gain**2
        return {
            "yaml_servo_gain": old[0],
            "yaml_servo_offset": old[1],
            "wheel_angle_deg": math.degrees(angle),
            "wheel_angle_deg_sd": math.degrees(math.sqrt(max(var, 0.0))),
        }

    def to_json(self) -> JsonObject:
        p, sd, fit, log, st = self.params, self.sds, self.result.fit, self.log, self.steering

        def pair(key: str, value: float, value_sd: float) -> JsonObject:
            return {key: value, f"{key}_sd": value_sd}

        noise = fit.noise.rep103()
        m = fit.matches
        used_s = max(float(np.sum(log.scan_t[m.j[fit.used]] - log.scan_t[m.i[fit.used]])), 1e-9)
        doc: JsonObject = {
            "sensact_version": __version__,
            OUTPUT_KEY: EM_MODEL,
            "kind": CAR_KIND,
            "log": log.source,
            # vesc.yaml's convention: ERPM = gain * speed + offset, servo = gain * angle + offset (m/s, rad)
            "vesc": {
                **pair("speed_to_erpm_gain", p["speed_to_erpm_gain"], sd["speed_to_erpm_gain"]),
                **pair("speed_to_erpm_offset", p["speed_to_erpm_offset"], sd["speed_to_erpm_offset"]),
                **pair("steering_angle_to_servo_gain", st.gain, st.gain_sd),
                **pair(
                    "steering_angle_to_servo_offset",
                    p["steering_angle_to_servo_offset"],
                    sd["steering_angle_to_servo_offset"],
                ),
            },
            "car": {
                **pair("wheelbase_mm", st.wheelbase_m * 1000, st.wheelbase_m_sd * 1000),
                # what the servo and the curvature say where the wheelbase is not told apart from the gain
                **pair("steering_gain_times_wheelbase_m", st.product, st.product_sd),
                **pair("steering_delay_s", p["steering_delay_s"], sd["steering_delay_s"]),
                **pair("speed_delay_s", p["speed_delay_s"], sd["speed_delay_s"]),
                "straight_ahead": self.straight_ahead(),
                "yaml_before": self.old_yaml,
                # the drive's noise beyond the scan matcher's: variance of the lidar's displacement (x forward,
                # y left in mm^2, yaw in rad^2) per mm travelled and per rad turned
                "noise": {"variance_per_mm": noise.b.tolist(), "variance_per_rad": noise.c.tolist()},
            },
            "lidar": {
                "mount": {
                    **pair("forward_mm", p["forward_mm"], sd["forward_mm"]),
                    **pair("left_mm", p["left_mm"], sd["left_mm"]),
                    **pair("yaw_rad", p["yaw_rad"], sd["yaw_rad"]),
                },
                "range_sigma_mm": self.result.range.sigma_mm,
                "range_sigma_mm_sd": self.result.range.sd_mm,
            },
            "urdf": log.urdf.to_dict(),
            "fit": {
                "scans": int(log.scan_t.size),
                "intervals": len(m.i),
                "intervals_used": int(fit.used.sum()),
                "chi2_per_dof": fit.chi2_per_dof,
                "distance_m": fit.distance_mm / 1000,
                "turn_rad": fit.turn_rad,
                "speed_mm_s": fit.distance_mm / used_s,
                "inverse_gain_squared": p["inverse_gain_squared"],
                "inverse_gain_squared_sd": sd["inverse_gain_squared"],
                "seconds": self.seconds,
                "notes": self.notes(),
            },
            "health": self.health.to_dict(),
        }
        ev = self.evaluation()
        if ev is not None:
            doc["evaluation"] = ev
        return doc

    def evaluation(self) -> JsonObject | None:
        """Each learned number against the simulator's truth: error, and error in sds."""
        truth = self.log.truth
        if not truth:
            return None
        vesc, car = truth.get("vesc", {}), truth.get("car", {})
        mount = truth.get("lidar", {}).get("mount", {})
        doc = self.to_json_values()
        want = {
            "speed_to_erpm_gain": vesc.get("speed_to_erpm_gain"),
            "speed_to_erpm_offset": vesc.get("speed_to_erpm_offset"),
            "steering_angle_to_servo_gain": vesc.get("steering_angle_to_servo_gain"),
            "steering_angle_to_servo_offset": vesc.get("steering_angle_to_servo_offset"),
            "wheelbase_mm": car.get("wheelbase_mm"),
            "forward_mm": mount.get("forward_mm"),
            "left_mm": mount.get("left_mm"),
            "yaw_rad": mount.get("yaw_rad"),
        }
        out: JsonObject = {}
        for k, v in want.items():
            if isinstance(v, int | float) and k in doc:
                value, value_sd = doc[k]
                out[k] = {"error": value - v, "error_sd": (value - v) / value_sd if value_sd > 0 else math.inf}
                if k in ("speed_to_erpm_gain", "steering_angle_to_servo_gain", "wheelbase_mm") and v:
                    out[k]["error_share"] = (value - v) / v
        yaml_, ahead = truth.get("yaml", {}), self.straight_ahead()
        so, sg = vesc.get("steering_angle_to_servo_offset"), vesc.get("steering_angle_to_servo_gain")
        if ahead is not None and isinstance(yaml_.get("steering_angle_to_servo_offset"), int | float) and so and sg:
            true_deg = math.degrees((yaml_["steering_angle_to_servo_offset"] - so) / sg)
            out["straight_ahead_deg"] = {"error": ahead["wheel_angle_deg"] - true_deg, "truth": true_deg}
        return out

    def to_json_values(self) -> dict[str, tuple[float, float]]:
        p, sd, st = self.params, self.sds, self.steering
        values = {k: (p[k], sd[k]) for k in PARAMETERS}
        values["steering_angle_to_servo_gain"] = (st.gain, st.gain_sd)
        values["wheelbase_mm"] = (st.wheelbase_m * 1000, st.wheelbase_m_sd * 1000)
        return values


def health_of(res: CarLidarResult) -> Health:
    """A fit the log cannot pin down is flagged, not answered."""
    fit = res.fit
    sd = dict(zip(PARAMETERS, fit.sd, strict=True))
    p = dict(zip(PARAMETERS, fit.params, strict=True))
    st = steering(fit.params, fit.cov)
    flags = []
    if not (sd["forward_mm"] <= MOUNT_SD_MM and sd["left_mm"] <= MOUNT_SD_MM and sd["yaw_rad"] <= MOUNT_SD_RAD):
        flags.append(
            HealthFlag(
                "mount_not_observable",
                f"the lidar's mount is not pinned down (sd {sd['forward_mm']:.3g} mm forward, {sd['left_mm']:.3g} mm "
                f"left, {math.degrees(sd['yaw_rad']):.3g} deg): record the car turning both ways as well as driving.",
            )
        )
    if not sd["speed_to_erpm_gain"] <= GAIN_SD_SHARE * abs(p["speed_to_erpm_gain"]):
        flags.append(
            HealthFlag(
                "speed_gain_not_observable",
                f"the speed gain is known only to {100 * sd['speed_to_erpm_gain'] / abs(p['speed_to_erpm_gain']):.3g} "
                "%: record the car driving longer, at several speeds.",
            )
        )
    share = st.wheelbase_m_sd / st.wheelbase_m if math.isfinite(st.wheelbase_m) else math.inf
    if not share <= WHEELBASE_SD_SHARE:
        flags.append(
            HealthFlag(
                "wheelbase_not_identified",
                f"the wheelbase is known only to {100 * share:.3g} % (the curves were gentle: only the steering "
                "gain times the wheelbase shows, car.steering_gain_times_wheelbase_m): record tighter turns both "
                "ways, near full steering.",
            )
        )
    if p["speed_to_erpm_gain"] < 0:
        flags.append(
            HealthFlag(
                "erpm_sign_reversed",
                "the VESC's ERPM falls as the car drives forward (vesc.speed_to_erpm_gain is negative): reverse the "
                "motor's direction in VESC Tool, or keep the negative gain in vesc.yaml.",
            )
        )
    if not np.isfinite(res.range.sigma_mm):
        flags.append(HealthFlag("range_noise_unknown", "too few flat surfaces in the scans to learn the range noise."))
    return Health.of(*flags)


def calibrate_car(log: CarLog, progress: Progress | None = None) -> CarCalibration:
    t0 = time.monotonic()
    res = learn_car_lidar(log, progress)
    return CarCalibration(log, res, health_of(res), time.monotonic() - t0)


def calibrate_opened_car(
    log: OpenedCarLog,
    preset: str | None = None,
    config: Any = None,
    *,
    sets: Any = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> CarCalibration:
    """The kind's learner (``app.log_kinds``): it takes no EM settings (the door refuses them)."""
    return calibrate_car(log.data, None if events is None else events.progress)


def save_car(cal: CarCalibration, out: Path, report: bool = True) -> Saved:
    """model.json (with the version stamp), and the report page with its figures beside it."""

    def page() -> tuple[Path, list[str]]:
        from sensact.report.car import write_car_report

        return write_car_report(cal, out)

    return save_model(out, cal.to_json(), page if report else None)
