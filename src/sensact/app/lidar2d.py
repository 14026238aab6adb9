"""``sensact learn em`` on a wheels-and-2-D-lidar log folder (docs/lidar2d.md): the calibration, its health, its
JSON (``lidar.mount.*``, ``drive.wheel_radius_*``, ``drive.axle_mm``, ``lidar.range_sigma_mm``, each with its
``_sd``), scored against a simulator's truth, and saved with its report page."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sensact import __version__
from sensact.app.em import FitEvents
from sensact.app.opened import FittedInSeconds, OpenedFolder
from sensact.app.save import Saved, save_model
from sensact.health import Health, HealthFlag
from sensact.io.lidar2d_folder import KIND as LIDAR2D_KIND
from sensact.learn.wheel_lidar import (
    MOUNT_SD_MM,
    MOUNT_SD_RAD,
    PARAMETERS,
    WHEEL_SD_SHARE,
    WheelLidarFit,
    WheelLidarResult,
    learn_wheel_lidar,
)
from sensact.logs.lidar2d_log import Lidar2DLog
from sensact.outputs import EM_MODEL, OUTPUT_KEY
from sensact.progress import Progress
from sensact.records import JsonObject

MIN_INTERVALS = 20


@dataclass(frozen=True, eq=False)
class OpenedLidar2DLog(OpenedFolder):
    """A wheels-and-2-D-lidar log folder, opened (``app.log_kinds``)."""

    data: Lidar2DLog

    def describe(self) -> str:
        data = self.data
        return (
            f"{self.path}: {data.scan_t.size} scans of {data.beams} beams over {data.scan_t[-1] - data.scan_t[0]:.1f} "
            f"s, the robot's motion from {data.drive} ({data.drive_t.size} rows)"
        )


def open_lidar2d_log(path: Path) -> OpenedLidar2DLog:
    from sensact.io.lidar2d_folder import read_lidar2d_log

    return OpenedLidar2DLog(Path(path), read_lidar2d_log(path))


@dataclass(frozen=True, eq=False)
class Lidar2DCalibration(FittedInSeconds[Lidar2DLog, WheelLidarResult]):
    PARAMETERS = PARAMETERS

    def to_json(self) -> JsonObject:
        p, sd, fit, log = self.params, self.sds, self.result.fit, self.log

        def pair(name: str, key: str | None = None) -> JsonObject:
            key = key or name
            return {key: p[name], f"{key}_sd": sd[name]}

        noise = fit.noise.rep103()  # x forward, y left
        match = {"x_mm": np.sqrt(noise.a[0]), "y_mm": np.sqrt(noise.a[1]), "yaw_rad": np.sqrt(noise.a[2])}
        n_used = int(fit.used.sum())
        m = fit.matches
        used_s = max(float(np.sum(log.scan_t[m.j[fit.used]] - log.scan_t[m.i[fit.used]])), 1e-9)
        drive: JsonObject = {
            "source": log.drive,
            **pair("wheel_radius_left_mm"),
            **pair("wheel_radius_right_mm"),
            **pair("axle_mm"),
            **pair("delay_s"),
            # the drive's noise: variance of the lidar's displacement (x, y in mm^2, yaw in rad^2) per mm
            # travelled and per rad turned, beyond the scan matcher's own
            "noise": {"variance_per_mm": noise.b.tolist(), "variance_per_rad": noise.c.tolist()},
        }
        if self.result.track.virtual:
            r0, b0 = log.urdf.wheel_radius_mm or 1.0, log.urdf.axle_mm or 1.0
            mean_r = (p["wheel_radius_left_mm"] + p["wheel_radius_right_mm"]) / 2
            b = p["axle_mm"]
            cov = fit.cov[:3, :3]
            grads = {  # each gain's gradient in (r_left, r_right, axle): its sd by the delta method
                "gain_forward": (mean_r / r0, np.array([0.5, 0.5, 0.0]) / r0),
                "gain_turn": (mean_r / r0 * b0 / b, np.array([0.5 * b0 / b, 0.5 * b0 / b, -mean_r * b0 / b**2]) / r0),
            }
            for key, (value, g) in grads.items():
                drive[key] = value
                drive[f"{key}_sd"] = float(np.sqrt(max(g @ cov @ g, 0.0)))
            drive["nominal"] = {"wheel_radius_mm": r0, "axle_mm": b0}
        censi = dict(zip(PARAMETERS[:6], map(float, self.result.closed_form[:6]), strict=True))
        doc: JsonObject = {
            "sensact_version": __version__,
            OUTPUT_KEY: EM_MODEL,  # learn em wrote it: its --out replaces it
            "kind": LIDAR2D_KIND,
            "log": log.source,
            "drive": drive,
            "lidar": {
                "mount": {**pair("forward_mm"), **pair("left_mm"), **pair("yaw_rad")},
                "range_sigma_mm": self.result.range.sigma_mm,
                "range_sigma_mm_sd": self.result.range.sd_mm,
                # the scan matcher's noise per matched interval, each with its sd (a variance's, sigma / sqrt(2n))
                "match_sd": {k: float(v) for k, v in match.items()}
                | {f"{k}_sd": float(v) / np.sqrt(2 * max(n_used, 1)) for k, v in match.items()},
            },
            "urdf": log.urdf.to_dict(),
            "censi": censi,
            "fit": {
                "scans": int(log.scan_t.size),
                "consecutive_matched": len(self.result.consecutive.i),
                "intervals": len(fit.matches.i),
                "intervals_used": n_used,
                "chi2_per_dof": fit.chi2_per_dof,
                "distance_m": fit.distance_mm / 1000,
                "turn_rad": fit.turn_rad,
                # the log's mean speed and turn rate over the intervals used: robot_localization's noise per second
                "speed_mm_s": fit.distance_mm / used_s,
                "turn_rate_rad_s": fit.turn_rad / used_s,
                "seconds": self.seconds,
                "notes": list(self.result.notes),
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
        d, li = truth.get("drive", {}), truth.get("lidar", {})
        mount = li.get("mount", {})
        want = {
            "wheel_radius_left_mm": d.get("wheel_radius_left_mm"),
            "wheel_radius_right_mm": d.get("wheel_radius_right_mm"),
            "axle_mm": d.get("axle_mm"),
            "forward_mm": mount.get("forward_mm"),
            "left_mm": mount.get("left_mm"),
            "yaw_rad": mount.get("yaw_rad"),
        }
        p, sd = self.params, self.sds
        out: JsonObject = {}
        for k, v in want.items():
            if isinstance(v, int | float):
                out[k] = {
                    "error": p[k] - v,
                    "error_sd": (p[k] - v) / sd[k],
                    "censi_error": self.result.closed_form[PARAMETERS.index(k)] - v,
                }
        rs = li.get("range_sigma_mm")
        if isinstance(rs, int | float) and rs > 0:
            out["range_sigma_mm"] = {
                "ratio": self.result.range.sigma_mm / rs,
                "error_sd": (self.result.range.sigma_mm - rs) / self.result.range.sd_mm,
            }
        return out


def health_of(res: WheelLidarResult) -> Health:
    """A fit the log cannot pin down is flagged, not answered: the mount shows only in turns, the wheels only
    in driving."""
    flags = fit_flags(res.fit)
    if not np.isfinite(res.range.sigma_mm):
        flags.append(HealthFlag("range_noise_unknown", "too few flat surfaces in the scans to learn the range noise."))
    return Health.of(*flags)


def fit_flags(fit: WheelLidarFit) -> list[HealthFlag]:
    """The wheels-and-mount fit's own flags (the scan route's and the intervals')."""
    sd = dict(zip(PARAMETERS, fit.sd, strict=True))
    p = dict(zip(PARAMETERS, fit.params, strict=True))
    flags = []
    if int(fit.used.sum()) < MIN_INTERVALS:
        flags.append(
            HealthFlag(
                "too_few_intervals",
                f"only {int(fit.used.sum())} matched intervals (of {MIN_INTERVALS} needed): record longer, "
                "driving and turning.",
            )
        )
    if not (sd["forward_mm"] <= MOUNT_SD_MM and sd["left_mm"] <= MOUNT_SD_MM and sd["yaw_rad"] <= MOUNT_SD_RAD):
        flags.append(
            HealthFlag(
                "mount_not_observable",
                f"the lidar's mount is not pinned down (sd {sd['forward_mm']:.3g} mm forward, "
                f"{sd['left_mm']:.3g} mm left, "
                f"{np.degrees(sd['yaw_rad']):.3g} deg; the robot turned {fit.turn_rad:.3g} rad and drove "
                f"{fit.distance_mm / 1000:.3g} m): the mount shows only when the robot turns and drives; "
                "record turns both ways.",
            )
        )
    worst = max(
        sd["wheel_radius_left_mm"] / abs(p["wheel_radius_left_mm"]),
        sd["wheel_radius_right_mm"] / abs(p["wheel_radius_right_mm"]),
        sd["axle_mm"] / abs(p["axle_mm"]),
    )
    if not worst <= WHEEL_SD_SHARE:
        flags.append(
            HealthFlag(
                "drive_not_observable",
                f"the wheels' radii or axle are known only to {100 * worst:.3g} %: record the robot driving and "
                "turning for longer.",
            )
        )
    return flags


def calibrate_lidar2d(log: Lidar2DLog, progress: Progress | None = None) -> Lidar2DCalibration:
    t0 = time.monotonic()
    res = learn_wheel_lidar(log, progress)
    return Lidar2DCalibration(log, res, health_of(res), time.monotonic() - t0)


def calibrate_opened_lidar2d(
    log: OpenedLidar2DLog,
    preset: str | None = None,
    config: Any = None,
    *,
    sets: Any = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> Lidar2DCalibration:
    """The kind's learner (``app.log_kinds``): it takes no EM settings (the door refuses them)."""
    return calibrate_lidar2d(log.data, None if events is None else events.progress)


def save_lidar2d(cal: Lidar2DCalibration, out: Path, report: bool = True) -> Saved:
    """model.json (with the version stamp), and the report page with its figures beside it."""

    def page() -> tuple[Path, list[str]]:
        from sensact.report.lidar2d import write_lidar2d_report

        return write_lidar2d_report(cal, out)

    return save_model(out, cal.to_json(), page if report else None)


def convert_lidar_bag(
    bag: Path,
    out: Path,
    reader: Any,
    topics: list[Any],
    roles: Any,
    *,
    wheel_joints: tuple[str, str] | None = None,
    receive_times: bool = False,
    progress: Progress | None = None,
) -> Any:
    """A wheels-and-lidar bag as a log folder at ``out`` (nothing left behind if it fails); the URDF's wheels are
    what /odom was computed with, fitted on the encoders where the bag has both (``io.rosbag_lidar2d``)."""
    import dataclasses

    from sensact.io.atomic import nothing_half_written
    from sensact.io.lidar2d_folder import write_lidar2d_log
    from sensact.io.rosbag_lidar2d import read_lidar2d_bag
    from sensact.learn.wheel_lidar import drive_of_odometry

    lb = read_lidar2d_bag(
        bag, reader, topics, roles, wheel_joints=wheel_joints, receive_times=receive_times, progress=progress
    )
    log, notes = lb.log, list(lb.notes)
    if "wheels" in lb.tables and "odom" in lb.tables:
        (wt, phi), (ot, pose) = lb.tables["wheels"], lb.tables["odom"]
        nominal = drive_of_odometry(wt, phi, ot, pose)
        if nominal is not None:
            r = (nominal[0] + nominal[1]) / 2
            log = dataclasses.replace(log, urdf=dataclasses.replace(log.urdf, wheel_radius_mm=r, axle_mm=nominal[2]))
            notes.append(
                f"{roles.odom} was computed with wheels of {r:.6g} mm and an axle of {nominal[2]:.6g} mm per unit of "
                f"the wheels' positions: the URDF's guess to compare with"
            )
    with nothing_half_written(out):
        write_lidar2d_log(out, log, lb.tables)
    return dataclasses.replace(lb, log=log, notes=tuple(notes))
