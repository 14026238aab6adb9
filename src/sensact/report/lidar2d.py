"""The report page of a wheels-and-2-D-lidar calibration (docs/lidar2d.md): the scans laid on the wheels' path before
and after (a map that sharpens), the learned mount beside the URDF's, and the residuals."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import apply_displacement, from_rep103, sensor_poses, to_rep103
from sensact.learn.wheel_lidar import PARAMETERS, odometry, poses_at, predicted, scan_points
from sensact.report.page import Section, report_path, write_report

MAX_POINTS = 80_000


def _before(cal: Any) -> tuple[np.ndarray, str]:
    """What the robot was believed to be before: the URDF's wheels and mount where it gives them, else the
    closed form's start."""
    u, fit = cal.log.urdf, cal.result.fit
    if u.wheel_radius_mm and u.axle_mm and not cal.result.track.virtual:
        m = (0.0, 0.0, 0.0) if u.mount is None else (u.mount.forward_mm, u.mount.left_mm, u.mount.yaw_rad)
        return np.array([u.wheel_radius_mm, u.wheel_radius_mm, u.axle_mm, *m, 0.0]), "the URDF's wheels and mount"
    return fit.start, "the closed form's start (no URDF wheels given)"


def _cloud(cal: Any, params: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    log, track = cal.log, cal.result.track
    rl, rr, b, fx, fy, yaw, delay = params
    at = poses_at(track, odometry(track, rl, rr, b), log.scan_t, delay)
    mount = np.array([fx, fy, yaw])
    pts = scan_points(log, None, mount)
    clouds = []
    for k in keys.tolist():
        xy = pts[k][np.isfinite(pts[k][:, 0])]  # the lidar's frame (REP 103)
        sensor = sensor_poses(at[k], mount)
        clouds.append(apply_displacement(sensor, from_rep103(np.column_stack([xy, np.zeros(len(xy))])))[:, :2])
    cloud = np.vstack(clouds) if clouds else np.zeros((0, 2))
    if len(cloud) > MAX_POINTS:
        cloud = cloud[np.random.default_rng(0).choice(len(cloud), MAX_POINTS, replace=False)]
    return to_rep103(cloud) / 1000, to_rep103(at[:, :2]) / 1000  # x along the start's heading, y to its left


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    fig.clf()
    _pyplot().close(fig)
    return path


def figure_scans(cal: Any, path: Path) -> Path:
    before, said = _before(cal)
    keys = np.unique(np.concatenate([cal.result.fit.matches.i, cal.result.fit.matches.j]))
    panels = [(*_cloud(cal, params, keys), title) for params, title in
              ((before, f"before: {said}"), (cal.result.fit.params, "after: learned"))]  # fmt: skip
    return draw_scans(
        panels, "Every keyframe's scan laid on the wheels' path: a map that sharpens is a calibration that holds", path
    )


def draw_scans(panels: list[tuple[np.ndarray, np.ndarray, str]], suptitle: str, path: Path) -> Path:
    """Side by side, each panel's scans (a cloud, m) on its path (m), titled."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, len(panels), figsize=(12, 6), sharex=True, sharey=True)
    for ax, (cloud, path_xy, title) in zip(axes, panels, strict=True):
        ax.scatter(cloud[:, 0], cloud[:, 1], s=0.2, c="k", alpha=0.25, linewidths=0)
        ax.plot(path_xy[:, 0], path_xy[:, 1], color="tab:red", lw=0.8)
        ax.set_title(title, fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m, where the log starts)")
    axes[0].set_ylabel("y (m)")
    fig.suptitle(suptitle)
    return _save(fig, path)


def figure_mount(cal: Any, path: Path) -> Path:
    plt = _pyplot()

    p = dict(zip(PARAMETERS, cal.result.fit.params, strict=True))
    cov = cal.result.fit.cov[3:5, 3:5]
    fig, ax = plt.subplots(figsize=(6, 6))
    half = p["axle_mm"] / 2
    for side, r in ((1, p["wheel_radius_left_mm"]), (-1, p["wheel_radius_right_mm"])):
        ax.add_patch(plt.Rectangle((-r, side * half - 8), 2 * r, 16, color="0.6"))
    ax.plot([0, 0], [-half, half], color="0.4", lw=1)
    arrows = [("learned", (p["forward_mm"], p["left_mm"], p["yaw_rad"]), "tab:red")]
    u = cal.log.urdf.mount
    if u is not None:
        arrows.insert(0, ("URDF", (u.forward_mm, u.left_mm, u.yaw_rad), "tab:blue"))
    arrows.append(("Censi et al.", tuple(cal.result.closed_form[3:6]), "tab:green"))
    for name, (x, y, yaw), color in arrows:
        ax.annotate(
            "",
            xy=(x + 40 * np.cos(yaw), y + 40 * np.sin(yaw)),
            xytext=(x, y),
            arrowprops={"color": color, "width": 1.5},
        )
        ax.plot(x, y, "o", color=color, label=f"{name}: {x:.1f} mm, {y:.1f} mm, {np.degrees(yaw):.2f} deg")
    w, v = np.linalg.eigh(cov) if np.all(np.isfinite(cov)) else (np.zeros(2), np.eye(2))
    t = np.linspace(0, 2 * np.pi, 100)
    ell = (v @ (2 * np.sqrt(np.maximum(w, 0))[:, None] * np.array([np.cos(t), np.sin(t)]))).T
    ax.plot(p["forward_mm"] + ell[:, 0], p["left_mm"] + ell[:, 1], color="tab:red", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("forward of the axle's middle (mm)")
    ax.set_ylabel("left (mm)")
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title("The lidar on the robot (arrows: its x axis; the ellipse: 2 sd)", fontsize=10)
    return _save(fig, path)


def figure_residuals(cal: Any, path: Path) -> Path:
    from sensact.learn.wheel_lidar import interval_size

    fit, log, track = cal.result.fit, cal.log, cal.result.track
    m = fit.matches
    r = predicted(fit.params, track, log.scan_t, m.i, m.j) - m.s
    r[:, 2] = wrap_angle(r[:, 2])
    dist, turn = interval_size(fit.params, track, log.scan_t, m)
    z = to_rep103(r / fit.noise.sd(dist, turn))  # x forward, y left
    title = f"Residuals: wheels' prediction minus scan match, {int(fit.used.sum())} of {len(m.i)} intervals kept"
    return draw_residuals(z, title, path)


def draw_residuals(z: np.ndarray, suptitle: str, path: Path) -> Path:
    """Each axis's residuals in their own sd (x forward, y left, yaw) against N(0, 1)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
    g = np.linspace(-5, 5, 200)
    for a, (ax, name) in enumerate(zip(axes, ("x (forward)", "y (left)", "yaw"), strict=True)):
        ax.hist(np.clip(z[:, a], -6, 6), bins=40, range=(-6, 6), density=True, color="0.6", label="intervals")
        ax.plot(g, np.exp(-0.5 * g**2) / np.sqrt(2 * np.pi), color="tab:red", label="N(0, 1)")
        ax.set_title(f"lidar displacement {name}, in sd", fontsize=10)
    axes[0].legend(fontsize=8)
    fig.suptitle(suptitle)
    return _save(fig, path)


def write_lidar2d_report(cal: Any, out: Path) -> tuple[Path, list[str]]:
    """report.html beside ``out`` with its figures (OUT_scans.png, OUT_mount.png, OUT_residuals.png); a figure
    that cannot be drawn is named, never the run's end."""
    stem = out.with_suffix("")
    failed: list[str] = []
    figures = []
    for draw, suffix, caption in (
        (figure_scans, "_scans.png", "Scans on the wheels' path, before and after calibration."),
        (figure_mount, "_mount.png", "The lidar's mount: the URDF's, Censi et al.'s closed form and the learned one."),
        (
            figure_residuals,
            "_residuals.png",
            "Each interval's residual in its own sd: N(0, 1) if the noise model holds.",
        ),
    ):
        png = stem.with_name(stem.name + suffix)
        try:
            figures.append((draw(cal, png), caption))
        except Exception as exc:  # matplotlib on a degenerate fit
            failed.append(f"{png.name}: {type(exc).__name__}: {exc}")
    doc = cal.to_json()
    d, li = doc["drive"], doc["lidar"]
    rows = []
    u = doc["urdf"]
    um = u.get("lidar_mount") or {}
    for label, node, key, urdf_value, unit in (
        ("left wheel radius", d, "wheel_radius_left_mm", u.get("wheel_radius_mm"), "mm"),
        ("right wheel radius", d, "wheel_radius_right_mm", u.get("wheel_radius_mm"), "mm"),
        ("axle", d, "axle_mm", u.get("axle_mm"), "mm"),
        ("lidar forward", li["mount"], "forward_mm", um.get("forward_mm"), "mm"),
        ("lidar left", li["mount"], "left_mm", um.get("left_mm"), "mm"),
        ("lidar yaw", li["mount"], "yaw_rad", um.get("yaw_rad"), "rad"),
        ("wheels' clock offset (delay)", d, "delay_s", None, "s"),
        ("range noise sd", li, "range_sigma_mm", None, "mm"),
    ):
        rows.append(
            (
                label,
                f"{node[key]:.6g}",
                f"{node[key + '_sd']:.3g}",
                "" if urdf_value is None else f"{urdf_value:.6g}",
                unit,
            )
        )
    flags = tuple(f"{f['code']}: {f['message']}" for f in doc["health"]["flags"])
    sections = [
        Section(
            "Learned",
            (
                f"From {doc['fit']['intervals_used']} keyframe intervals of {doc['fit']['scans']} scans; the robot "
                f"drove {doc['fit']['distance_m']:.3g} m and turned {doc['fit']['turn_rad']:.3g} rad. "
                f"Wheels read from {d['source']}.",
                *doc["fit"]["notes"],
            ),
            (("", "learned", "sd", "URDF", "unit"), tuple(rows)),
            flags,
            True,
        ),
        Section("Pictures", (), None, (), False, tuple(figures)),
    ]
    page = write_report(
        report_path(out),
        f"Wheels and 2-D lidar: {Path(cal.log.source).name}",
        "sensact learn em on a wheels-and-lidar log (docs/lidar2d.md).",
        sections,
    )
    return page, failed
