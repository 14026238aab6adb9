"""Is an EM fit a result or a degenerate one? (docs/errors.md; beyond the thesis, whose fits all converge on
sensors that read something.)

Each check looks at what the fit cannot recover from by itself, on the log it was learned on:

- EM stopped by ``max_iterations`` or diverged (``EMResult.stop_reason``);
- a command that never varies: the action model's gain on it and its offset trade freely;
- a reading that never varies, or a sigma collapsed onto the M-step's floor (eq. 4.27 with every residual
  zero), where the likelihood grows without bound instead of converging;
- a reading whose learned f explains almost none of its variance (a sonar that reads noise), or whose
  gain changes sign between the log's halves, judged on the smoothed path: f is fitted to noise.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from sensact.health import MIN_EXPLAINED, MIN_READINGS, Health, HealthFlag
from sensact.learn.em.result import EMResult, smoothed_distances
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.models.wheel_drive import as_differential_drive

SIGMA_COLLAPSED = 1e-6  # a reading's sigma this small, relative to its readings' size, has collapsed
MAX_LAG1 = 0.5  # residuals' lag-1 autocorrelation beyond this and sigma is not the sensor's noise
TURN = "v_theta_rad_s"  # the planar state's turn rate (core.geometry's velocity names)
TURN_COMMANDS = ("omega_rad_s",)  # commanded turn rates, counterclockwise positive (REP 103)
MIN_HALF_SIGHTINGS = 10  # sightings in each half before their gains' signs are compared


def em_health(
    result: EMResult,
    data: LandmarkLog,
    autocorrelation: Mapping[str, float | None] | None = None,
    *,
    dist: np.ndarray | None = None,
) -> Health:
    """The flags of one fit on ``data`` (none: a result to report as one); ``autocorrelation``: each channel's
    residuals' lag-1 autocorrelation about the smoothed path (``lost_signs.residual_autocorrelation``);
    ``dist``: the used sightings' smoothed distances (``result.smoothed_distances``), when already taken."""
    flags: list[HealthFlag] = []
    if result.stop_reason == "max_iterations":
        flags.append(
            HealthFlag(
                "not_converged",
                "EM reached max_iterations while the likelihood was still rising; raise it (--set max_iterations=...).",
            )
        )
    elif result.stop_reason == "interrupted":
        flags.append(
            HealthFlag(
                "interrupted",
                "the fit was stopped (Ctrl-C or SIGTERM) before it converged; the model is the best so far: "
                "run it again to the end.",
            )
        )
    elif result.stop_reason == "diverged":
        flags.append(HealthFlag("diverged", "the filter diverged; the model is the best before it did."))
    if not np.isfinite(result.loglik_best):
        flags.append(HealthFlag("loglik_not_finite", "the log-likelihood is not finite."))
    flags += _commands(data)
    flags += _readings(result, data, dist)
    flags += _implausible(result, data, autocorrelation or {})
    return Health(tuple(flags))


def _implausible(result: EMResult, data: LandmarkLog, autocorrelation: Mapping[str, float | None]) -> list[HealthFlag]:
    """Fits that converge to the wrong robot: turning against its commands, a mount the path
    cannot tell apart from the path itself, or residuals so correlated that sigma is not what it says."""
    model, post = result.model, result.posteriors
    flags = []
    turn = _turn_gain(model, data)
    if turn is not None and turn[1] < 0.0:
        flags.append(
            HealthFlag(
                "turn_sign_flipped",
                f"the learned {turn[0]} is {turn[1]:.4g}: the robot turns against its commands' convention "
                "(counterclockwise positive, REP 103), so the fit mirrored the path; learn from a log that "
                "turns both ways, or give the start (thesis.start_prior_mean).",
            )
        )
    if post is not None and data.geometry.has_heading and data.n_steps > 1:
        xy = post.mean_gamma[:, :2]
        radius = float(np.sqrt(np.mean(np.sum((xy - xy.mean(axis=0)) ** 2, axis=1))))
        mount = model.sensor.mount
        offset = float(np.hypot(mount.forward_mm, mount.left_mm))
        if offset > radius:
            flags.append(
                HealthFlag(
                    "mount_not_identified",
                    f"the sensor is placed {offset:.0f} mm from the robot's point, farther than the path's own "
                    f"extent ({radius:.0f} mm RMS): the log cannot tell the mount from the path; hold it where it "
                    "is (sensor_mount: [forward_mm, left_mm, yaw_rad] in the settings) or record a log that turns "
                    "more.",
                )
            )
    for name, r in autocorrelation.items():
        if r is not None and abs(r) > MAX_LAG1:
            flags.append(
                HealthFlag(
                    "residuals_correlated",
                    f"{name}'s residuals have a lag-1 autocorrelation of {r:.2f} (beyond +-{MAX_LAG1}): the path "
                    "follows the readings or their errors persist, so its sigma is not the sensor's noise.",
                )
            )
    return flags


def _turn_gain(model: EMModel, data: LandmarkLog) -> tuple[str, float] | None:
    """What says which way the learned robot turns: a differential drive's axle (on wheel speeds), or the slope
    of the model's own turn rate over the log on a commanded turn rate that varies, whatever the action
    model's form; None where neither is there."""
    action = model.action
    drive = as_differential_drive(action)
    if drive is not None:
        return None if drive.axle_mm is None else ("axle", drive.axle_mm)
    names = [n for n in data.command_names if n in TURN_COMMANDS]
    if TURN not in action.velocity_names or not names or data.step_commands is None:
        return None
    commanded = np.asarray(data.step_commands)[:, data.command_names.index(names[0])]
    if np.ptp(commanded) == 0.0:
        return None  # command_constant says it
    learned = action.step_velocity(data)[:, action.velocity_names.index(TURN)]
    return f"turn rate's slope on {names[0]}", float(np.polyfit(commanded, learned, 1)[0])


def _commands(data: LandmarkLog) -> list[HealthFlag]:
    if data.is_continuous:
        cmd = np.asarray(data.step_commands, dtype=float)
        return [
            HealthFlag(
                "command_constant",
                f"command {name} never varies (always {col[0]:g}), so its gain and the offset cannot be told apart.",
            )
            for name, col in zip(data.command_names, cmd.T, strict=True)
            if col.size and np.ptp(col) == 0.0
        ]
    used = np.unique(data.actions[data.actions >= 0])
    if used.size <= 1:
        return [HealthFlag("command_constant", "the log has one action throughout; no other is learned from it.")]
    return []


def _readings(result: EMResult, data: LandmarkLog, dist: np.ndarray | None) -> list[HealthFlag]:
    if not data.n_observations:
        return []
    model, post = result.model, result.posteriors
    use = np.ones(data.n_observations, bool) if post is None else np.asarray(post.obs_used, dtype=bool)
    cols = model.sensor.columns(data)
    if post is not None and dist is None:
        dist = smoothed_distances(model, post, data)
    flags = []
    for j, ch in enumerate(model.sensor.channels):
        y = data.obs_readings[use, cols[j]]
        ok = np.isfinite(y)
        if dist is not None:  # f is fitted, and judged, within its window only
            ok &= (dist >= ch.valid_min) & (dist <= ch.valid_max)
        if np.count_nonzero(ok) < MIN_READINGS:
            continue  # too few to learn f from: left at its start, and said so by the scores
        y = y[ok]
        if y.size < 2:
            continue
        if np.ptp(y) == 0.0:
            flags.append(HealthFlag("reading_constant", f"reading {ch.name} never varies (always {y[0]:g})."))
            continue
        scale = max(float(np.max(np.abs(y))), 1.0)
        if ch.sigma <= SIGMA_COLLAPSED * scale:
            flags.append(
                HealthFlag(
                    "sigma_collapsed", f"{ch.name}'s sigma collapsed to {ch.sigma:.3g}: f passes through every reading."
                )
            )
            continue
        explained = 1.0 - ch.sigma**2 / float(np.var(y))
        if explained < MIN_EXPLAINED:
            flags.append(
                HealthFlag(
                    "reading_explains_nothing",
                    f"{ch.name}'s learned f explains {max(explained, 0.0):.0%} of its readings' variance: "
                    "it reads noise, or the log never moved the robot enough to tell.",
                )
            )
            continue
        if dist is not None:
            flip = _sign_flips(dist[ok], y)
            if flip is not None:
                flags.append(
                    HealthFlag(
                        "gain_sign_flips",
                        f"{ch.name} rises with distance in one half of the log and falls in the other "
                        f"(slopes {flip[0]:.3g} and {flip[1]:.3g}): f is fitted to noise.",
                    )
                )
    return flags


def _sign_flips(d: np.ndarray, y: np.ndarray) -> tuple[float, float] | None:
    """The two halves' least-squares slopes of reading on distance, over the distances both halves span (an f
    that turns over reads a different slope on a different span), when their signs differ."""
    half = d.size // 2
    halves = [(d[:half], y[:half]), (d[half:], y[half:])]
    lo = max(float(np.min(h[0])) for h in halves) if half else 0.0
    hi = min(float(np.max(h[0])) for h in halves) if half else 0.0
    slopes = []
    for dd, yy in halves:
        inside = (dd >= lo) & (dd <= hi)
        dd, yy = dd[inside], yy[inside]
        if dd.size < MIN_HALF_SIGHTINGS or np.var(dd) == 0.0:
            return None
        slopes.append(float(np.mean((dd - dd.mean()) * (yy - yy.mean())) / np.var(dd)))
    return (slopes[0], slopes[1]) if slopes[0] * slopes[1] < 0 else None
