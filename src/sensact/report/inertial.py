"""The report page of an outdoor robot's calibration (docs/inertial.md): the path over the GNSS fixes, the gyro's
bias over time with its band, and the residuals against N(0, 1)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from sensact.report.page import Section, report_path, write_report


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    _pyplot().close(fig)
    return path


def figure_path(cal: Any, path: Path) -> Path:
    res = cal.result
    fig, ax = _pyplot().subplots(figsize=(6.5, 6))
    if res.has_gnss:
        inl = res.gnss_inlier > 0.5
        ax.plot(res.gnss_enu_m[inl, 0], res.gnss_enu_m[inl, 1], ".", ms=2, color="0.6", label="GNSS fixes")
        ax.plot(res.gnss_enu_m[~inl, 0], res.gnss_enu_m[~inl, 1], "x", ms=4, color="tab:red", label="outliers")
    ax.plot(res.path_enu_m[:, 0], res.path_enu_m[:, 1], "-", lw=1, color="tab:blue", label="learned path (base_link)")
    if cal.log.truth_xy_m is not None:
        ax.plot(cal.log.truth_xy_m[:, 0], cal.log.truth_xy_m[:, 1], "--", lw=0.8, color="k", label="truth")
    ax.set_xlabel("east (m)" if res.has_gnss else "x (m)")
    ax.set_ylabel("north (m)" if res.has_gnss else "y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8)
    return _save(fig, path)


def figure_bias(cal: Any, path: Path) -> Path:
    res = cal.result
    t = res.t_s[1:] - res.t_s[0]
    b, sd = np.degrees(res.bias_rad_s), np.degrees(res.bias_sd_rad_s)
    fig, ax = _pyplot().subplots(figsize=(7, 3.2))
    ax.fill_between(t, b - 2 * sd, b + 2 * sd, color="tab:blue", alpha=0.25, lw=0, label="95 % band")
    ax.plot(t, b, color="tab:blue", lw=1, label="gyro bias (smoothed)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("bias (deg/s)")
    ax.legend(fontsize=8)
    return _save(fig, path)


def figure_residuals(cal: Any, path: Path) -> Path:
    res = cal.result
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2 if res.has_gnss else 1, figsize=(8 if res.has_gnss else 4.5, 3.2), squeeze=False)
    x = np.linspace(-4, 4, 200)
    series = [("gyro", res.gyro_z)]
    if res.has_gnss:
        z = res.gnss_z[res.gnss_inlier > 0.5].ravel()
        series.append(("GNSS (inliers, east and north)", z))
    for ax, (name, z) in zip(axes[0], series, strict=True):
        z = z[np.isfinite(z)]
        ax.hist(np.clip(z, -4, 4), bins=60, density=True, color="0.7")
        ax.plot(x, np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi), color="tab:red", lw=1, label="N(0, 1)")
        ax.set_title(f"{name}: sd {np.std(z):.2f}", fontsize=9)
        ax.legend(fontsize=8)
    return _save(fig, path)


def write_inertial_report(cal: Any, out: Path) -> tuple[Path, list[str]]:
    """report.html beside ``out`` with its figures; a figure that cannot be drawn is named, never the run's end."""
    stem = out.with_suffix("")
    failed: list[str] = []
    figures = []
    for draw, suffix, caption in (
        (figure_path, "_path.png", "The learned path of base_link over the GNSS fixes (outliers crossed)."),
        (figure_bias, "_bias.png", "The gyro's bias about base_link's z over the run, with its 95 % band."),
        (figure_residuals, "_residuals.png", "Each sensor's residual in its own sd: N(0, 1) where the model holds."),
    ):
        png = stem.with_name(stem.name + suffix)
        try:
            figures.append((draw(cal, png), caption))
        except Exception as exc:  # matplotlib on a degenerate fit
            failed.append(f"{png.name}: {type(exc).__name__}: {exc}")
    rows = []
    for key, e in cal.result.estimates.items():
        if e.value is None:
            continue
        rows.append((key, f"{e.value:.6g}", "" if e.sd is None else f"{e.sd:.3g}"))
    doc = cal.to_json()
    flags = tuple(f"{f['code']}: {f['message']}" for f in doc["health"]["flags"])
    fit = doc["fit"]
    sections = [
        Section(
            "Learned",
            (
                f"EM over {fit['distance_m']:.4g} m of driving, {fit['turn_left_rad']:.3g} rad turned left and "
                f"{fit['turn_right_rad']:.3g} rad right, {fit['gnss_fixes']} GNSS fixes; {fit['iterations']} passes.",
            ),
            (("", "learned", "sd"), tuple(rows)),
            flags,
            True,
        ),
        Section("Pictures", (), None, (), False, tuple(figures)),
    ]
    page = write_report(
        report_path(out),
        f"Wheel odometry, IMU and GNSS: {Path(cal.log.source).name}",
        "What the robot's own log says of its odometry, its IMU and its GNSS antenna (docs/inertial.md).",
        sections,
    )
    return page, failed
