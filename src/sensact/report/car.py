"""The report page of a car's calibration (docs/ackermann.md): the scans laid on the path before (the first look)
and after (a map that sharpens), the steering curve (the servo's command against the wheels' learned angle, and
where the log's own yaml puts straight ahead), and the residuals."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import apply_displacement, from_rep103, sensor_poses, to_rep103
from sensact.learn.car_lidar import bend, deskewed, interval_size, old_straight_ahead, poses_at, predicted
from sensact.report.lidar2d import MAX_POINTS, _pyplot, _save, draw_residuals, draw_scans
from sensact.report.page import Section, report_path, write_report


def _cloud(cal: Any, params: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    log = cal.log.from_its_start()
    drive = cal.result.drive
    at = poses_at(drive, params, log.scan_t)
    mount = params[5:8]
    pts = deskewed(log, drive, params, keys)
    clouds = []
    for k in keys.tolist():
        xy = pts[k][np.isfinite(pts[k][:, 0])]
        sensor = sensor_poses(at[k], mount)
        clouds.append(apply_displacement(sensor, from_rep103(np.column_stack([xy, np.zeros(len(xy))])))[:, :2])
    cloud = np.vstack(clouds) if clouds else np.zeros((0, 2))
    if len(cloud) > MAX_POINTS:
        cloud = cloud[np.random.default_rng(0).choice(len(cloud), MAX_POINTS, replace=False)]
    return to_rep103(cloud) / 1000, to_rep103(at[:, :2]) / 1000


def figure_scans(cal: Any, path: Path) -> Path:
    keys = np.unique(np.concatenate([cal.result.fit.matches.i, cal.result.fit.matches.j]))
    panels = [(*_cloud(cal, params, keys), title) for params, title in
              ((cal.result.first.params, "before: the first look (no calibration)"),
               (cal.result.fit.params, "after: learned"))]  # fmt: skip
    title = "Every keyframe's scan laid on the car's dead-reckoned path: a map that sharpens is a calibration"
    return draw_scans(panels, title, path)


def figure_steering(cal: Any, path: Path) -> Path:
    """The wheels' angle the learned numbers give for every servo command the log sent, with the log's own yaml's
    angle (what /drive commanded) beside it."""
    plt = _pyplot()
    log, st, p = cal.log, cal.steering, cal.params
    servo = np.linspace(log.servo.min(), log.servo.max(), 200)
    fig, ax = plt.subplots(figsize=(7, 5))
    if math.isfinite(st.gain):
        learned = np.degrees((servo - p["steering_angle_to_servo_offset"]) / st.gain)
        ax.plot(servo, learned, color="tab:red", label="learned: the wheels' angle")
    # the curvature the learned model gives, as the angle of a bicycle with the learned (or product) numbers
    kappa = bend(servo - p["steering_angle_to_servo_offset"], p["inverse_gain_squared"]) / st.product
    ax2 = ax.twinx()
    ax2.plot(servo, kappa, color="tab:green", lw=0.8, ls=":", label="learned curvature (1/m)")
    ax2.set_ylabel("curvature (1/m)")
    old = old_straight_ahead(log)
    if old is not None:
        ax.plot(servo, np.degrees((servo - old[1]) / old[0]), color="tab:blue", ls="--", label="the yaml's angle")
        ax.axvline(old[1], color="tab:blue", lw=0.6)
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_xlabel("servo command")
    ax.set_ylabel("steering angle (deg, left positive)")
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("The steering curve: where the yaml's straight ahead (blue line) really points", fontsize=10)
    return _save(fig, path)


def figure_residuals(cal: Any, path: Path) -> Path:
    fit, drive = cal.result.fit, cal.result.drive
    scan_t = cal.log.from_its_start().scan_t
    m = fit.matches
    r = predicted(fit.params, drive, scan_t, m.i, m.j) - m.s
    r[:, 2] = wrap_angle(r[:, 2])
    dist, turn = interval_size(fit.params, drive, scan_t, m)
    title = f"Residuals: the VESC's prediction minus scan match, {int(fit.used.sum())} of {len(m.i)} kept"
    return draw_residuals(to_rep103(r / fit.noise.sd(dist, turn)), title, path)


def write_car_report(cal: Any, out: Path) -> tuple[Path, list[str]]:
    """report.html beside ``out`` with its figures; a figure that cannot be drawn is named, never the run's end."""
    stem = out.with_suffix("")
    failed: list[str] = []
    figures = []
    for draw, suffix, caption in (
        (figure_scans, "_scans.png", "Scans on the car's path, before and after calibration."),
        (figure_steering, "_steering.png", "The servo's command against the wheels' learned angle."),
        (figure_residuals, "_residuals.png", "Each interval's residual in its own sd: N(0, 1) if the model holds."),
    ):
        png = stem.with_name(stem.name + suffix)
        try:
            figures.append((draw(cal, png), caption))
        except Exception as exc:  # matplotlib on a degenerate fit
            failed.append(f"{png.name}: {type(exc).__name__}: {exc}")
    doc = cal.to_json()
    v, c, mount = doc["vesc"], doc["car"], doc["lidar"]["mount"]
    um = doc["urdf"].get("lidar_mount") or {}
    old = c["yaml_before"]
    rows = []
    for label, node, key, before, unit in (
        ("speed to ERPM gain", v, "speed_to_erpm_gain", old["speed_to_erpm_gain"], "ERPM per m/s"),
        ("speed to ERPM offset", v, "speed_to_erpm_offset", old["speed_to_erpm_offset"], "ERPM"),
        (
            "steering angle to servo gain",
            v,
            "steering_angle_to_servo_gain",
            old["steering_angle_to_servo_gain"],
            "per rad",
        ),
        (
            "steering angle to servo offset",
            v,
            "steering_angle_to_servo_offset",
            old["steering_angle_to_servo_offset"],
            "",
        ),
        ("wheelbase", c, "wheelbase_mm", old["wheelbase_mm"], "mm"),
        ("steering gain x wheelbase", c, "steering_gain_times_wheelbase_m", None, "m per rad"),
        ("steering delay", c, "steering_delay_s", None, "s"),
        ("VESC's clock behind the lidar's", c, "speed_delay_s", None, "s"),
        ("lidar forward", mount, "forward_mm", um.get("forward_mm"), "mm"),
        ("lidar left", mount, "left_mm", um.get("left_mm"), "mm"),
        ("lidar yaw", mount, "yaw_rad", um.get("yaw_rad"), "rad"),
    ):
        value, sd = node[key], node[key + "_sd"]
        rows.append(
            (
                label,
                "" if value is None or not math.isfinite(value) else f"{value:.6g}",
                "" if sd is None or not math.isfinite(sd) else f"{sd:.3g}",
                "" if before is None else f"{before:.6g}",
                unit,
            )
        )
    ahead = c.get("straight_ahead")
    lines = [
        f"From {doc['fit']['intervals_used']} keyframe intervals of {doc['fit']['scans']} scans; the car drove "
        f"{doc['fit']['distance_m']:.3g} m and turned {doc['fit']['turn_rad']:.3g} rad.",
        *doc["fit"]["notes"],
    ]
    if ahead is not None:
        lines.append(
            f"Commanded straight ahead through the log's yaml, the wheels point {ahead['wheel_angle_deg']:+.2f} deg "
            f"(sd {ahead['wheel_angle_deg_sd']:.2f}; positive: left)."
        )
    flags = tuple(f"{f['code']}: {f['message']}" for f in doc["health"]["flags"])
    sections = [
        Section(
            "Learned",
            tuple(lines),
            (("", "learned", "sd", "before (the log's yaml; /tf_static)", "unit"), tuple(rows)),
            flags,
            True,
        ),
        Section("Pictures", (), None, (), False, tuple(figures)),
    ]
    page = write_report(
        report_path(out),
        f"Car and 2-D lidar: {Path(cal.log.source).name}",
        "sensact learn em on a car's log (docs/ackermann.md).",
        sections,
    )
    return page, failed
