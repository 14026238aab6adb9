"""Scoring a model learned on a real planar robot against its ground truth (Vicon), with From-Truth.

From-Truth fits the *same model families* directly to the truth, so it is the best those families can
do on that data; the learned model is judged next to it:

* **action model:** judged over windows of ``window`` steps (default 1 s, half-overlapping) with valid
  truth, so over the commands actually used. In each window the model's velocities ``A(c_t)`` are
  integrated (eq. 2.28) into a displacement and compared with the true ``D(w_start, w_end)``; the error
  over the window length is a velocity error. Windows, not single steps, because a real robot's motion
  lags its commands (about 0.17 s on MRCLAM) and Vicon noise over one 1/30 s step is several mm/s: both
  would otherwise dominate every model's error. Each model's error is the RMS over windows,
  translational (mm/s, v_x and v_y together) and rotational (rad/s). From-Truth is the least-squares
  fit of the true window displacements on the window sums of ``Phi(c_t) dt`` (exact for windows
  without turning; it is scored the same way as the learned model), with the command delay (up to
  ``max_delay_steps``) that fits best.
* **range function:** From-Truth is the function of the learned family (the polynomial's degree and the
  number of bearing terms) fitted to (true distance, measured bearing, reading) after outlier trimming.
  Each model's error is the RMS residual ``reading - f(d_true) - d_true g(b)`` over the trimmed
  sightings; the learned function's gap to From-Truth's is reported too.
* **the sensor's pose:** a sensor's residuals are taken at the sensor, not at the truth's origin. The
  truth (Vicon) tracks its markers' frame, and a camera sits elsewhere on the robot: MRCLAM robot 4's
  is 115 mm ahead of its markers' origin and yawed 0.014 rad, which alone makes its bearing residual
  0.017 rad RMS against 0.007 at the camera. EM's pose is the sensor's own (its readings are all it
  sees), so From-Truth fits the sensor's mount, ``(lateral mm, forward mm, yaw rad)`` in the truth's
  robot frame, to the bearings by least squares (``fit_sensor_mount``), and both sensor scores use
  the truth's poses moved by it. The residuals at the truth's origin are reported beside them.
  A sensor that reads no bearing (ranges alone, as radio beacons give) has neither a bearing score
  nor a pose fitted by its bearings: ``bearing`` and ``sensor_mount`` are None, its range scored at
  the truth's origin.
* **sigmas:** the truth residual sigma is the RMS of the trimmed residuals (range: about From-Truth's f;
  bearing: about zero at the sensor's pose, as eq. 4.28 has no bearing bias). Trimming drops
  residuals beyond ``trim`` robust sigmas (1.4826 MAD) of the median, repeated until nothing
  changes.
* **the path** (``path_offset``): how far EM's smoothed path is from the truth, in the truth's robot
  frame. On MRCLAM the camera looks forward, so a path shifted back along the view and a range
  function with a larger constant explain the ranges almost equally well; the forward offset shows
  which basin a run ended in.
* **the truth's noise** (``truth_noise_structure``): how much the heading drifts at rest and while
  turning, whether the bearing residuals of nearby frames are correlated, and how much of a frame's
  bearing residual its sightings share; the things a constant Sigma_m and eq. 4.28's independent
  bearings cannot express, which bear on the sigma ratios. And how much of the bearing residual is
  the truth's own heading error (``truth_heading_error``), which the truth residual sigma counts
  and no learner of the sensor could.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from sensact.core.angles import wrap_angle
from sensact.core.polyfit import weighted_lstsq
from sensact.core.pose_models import (
    dead_reckon,
    landmark_bearing,
    landmark_distance,
    relative_displacement,
    sensor_poses,
)
from sensact.errors import LogFormatError
from sensact.io.unit_checks import groundtruth_heading_doubt
from sensact.learn.em.actions import turning_variance
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import reading_features
from sensact.models.linear_action import LinearActionModel, delayed
from sensact.models.linear_action_fit import linear_coefficients
from sensact.records import JsonObject


def valid_throughout(valid: np.ndarray, first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Whether the truth is valid at every step from ``first`` to ``last`` (inclusive), per pair."""
    bad = np.concatenate([[0], np.cumsum(~np.asarray(valid, dtype=bool))])
    return bad[last + 1] - bad[first] == 0


def window_starts(valid: np.ndarray, window: int) -> np.ndarray:
    """Start steps of the half-overlapping windows of ``window`` steps whose truth is valid throughout."""
    T = len(valid)
    starts = np.arange(0, T - window, max(window // 2, 1))
    return starts[valid_throughout(valid, starts, starts + window)]


def frame_means(residuals: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each frame's step (sorted) and the mean of its sightings' residuals."""
    uniq, inv = np.unique(frames, return_inverse=True)
    return uniq, np.bincount(inv, weights=residuals) / np.bincount(inv)


def trimmed(residuals: np.ndarray, trim: float = 3.0) -> np.ndarray:
    """A mask of the residuals within ``trim`` robust sigmas of their median (iterated)."""
    keep = np.isfinite(residuals)
    for _ in range(20):
        r = residuals[keep]
        med = np.median(r)
        sd = 1.4826 * np.median(np.abs(r - med))
        new = np.isfinite(residuals) & (np.abs(residuals - med) <= trim * max(sd, 1e-12))
        if np.array_equal(new, keep):
            break
        keep = new
    return keep


def as_mount(lateral_forward_yaw: np.ndarray) -> tuple[float, float, float]:
    """A mount fitted as ``(lateral mm, forward mm, yaw rad)`` (sec. 2.5.1's robot frame, x to the right) as
    ``core.pose_models.sensor_poses`` reads one: ``(forward mm, left mm, yaw rad)``."""
    lateral, forward, yaw = (float(v) for v in lateral_forward_yaw)
    return forward, -lateral, yaw


def path_offset(path: np.ndarray, truth_poses: np.ndarray, truth_valid: np.ndarray) -> JsonObject:
    """How far a learned ``path`` (one pose per step) is from the truth, at the steps with valid truth.

    The point EM tracks (the one the action model describes: a differential drive's axle) need not be
    the point the truth tracks (a motion-capture marker): one fixed offset in the robot's frame,
    ``truth_xy = path_xy + R(theta_path) o``, is fitted (``fitted_offset``: forward and left, mm; the
    median of the truth's point seen from the path, robust to a stretch where the path is lost) and
    ``median_mm`` is the median distance after it. ``median_raw_mm`` is before, and
    ``right_median_mm``, ``forward_median_mm`` the median raw offset in the truth's robot frame (sec.
    2.5.1). A path that stays behind the robot by a fixed distance while the sensor is modelled at the
    robot's point has taken the range function's constant."""
    ok = np.asarray(truth_valid, dtype=bool) & np.all(np.isfinite(path), axis=1)
    if not ok.any():
        nan = float("nan")
        return {
            "median_mm": nan,
            "median_raw_mm": nan,
            "right_median_mm": nan,
            "forward_median_mm": nan,
            "fitted_offset": None,
        }
    off = relative_displacement(truth_poses[ok], path[ok])  # the path's pose in the truth's robot frame
    # the truth's point in the path's robot frame (x right, y forward); its mean would be the least-squares
    # o, but a stretch where the path is lost (a filter locking on) would drag it: the median is robust
    seen = relative_displacement(path[ok], truth_poses[ok])[:, :2]
    o = np.median(seen, axis=0)
    c, s_ = np.cos(path[ok, 2]), np.sin(path[ok, 2])
    moved_x = path[ok, 0] + c * o[0] - s_ * o[1]
    moved_y = path[ok, 1] + s_ * o[0] + c * o[1]
    return {
        "median_mm": float(np.median(np.hypot(truth_poses[ok, 0] - moved_x, truth_poses[ok, 1] - moved_y))),
        "median_raw_mm": float(np.median(np.hypot(*(path[ok, :2] - truth_poses[ok, :2]).T))),
        "right_median_mm": float(np.median(off[:, 0])),
        "forward_median_mm": float(np.median(off[:, 1])),
        "fitted_offset": {"forward_mm": float(o[1]), "left_mm": float(-o[0])},
    }


def fit_sensor_mount(
    poses: np.ndarray, landmarks_xy: np.ndarray, bearings: np.ndarray, trim: float = 3.0
) -> np.ndarray:
    """The sensor's pose on the robot, ``(lateral mm, forward mm, yaw rad)`` (right and counterclockwise
    positive, sec. 2.5.1's robot frame) relative to the truth's ``poses`` (one per sighting), that best
    explains the measured ``bearings`` of ``landmarks_xy``: least squares over the trimmed bearing
    residuals, retrimmed until nothing changes. Zero when fewer than 10 bearings are finite."""
    poses = np.asarray(poses, dtype=float)
    ok = np.isfinite(bearings) & np.all(np.isfinite(poses), axis=1)
    mount = np.zeros(3)
    if ok.sum() < 10:
        return mount
    poses, lm, b = poses[ok], np.asarray(landmarks_xy, dtype=float)[ok], np.asarray(bearings)[ok]

    def residuals(m: np.ndarray) -> np.ndarray:
        return wrap_angle(b - landmark_bearing(sensor_poses(poses, as_mount(m)), lm))

    keep = trimmed(residuals(mount), trim)
    for _ in range(20):
        mount = least_squares(lambda m, k=keep: residuals(m)[k], mount, x_scale=np.array([100.0, 100.0, 0.01])).x
        new = trimmed(residuals(mount), trim)
        if np.array_equal(new, keep):
            break
        keep = new
    return mount


def frame_shared_bearing_error(residuals: np.ndarray, frames: np.ndarray) -> tuple[float, float]:
    """Over the frames with two or more sightings: the sd of a sighting's bearing residual about its
    frame's mean (the part eq. 4.28's independent noise can be; unbiased, ``n / (n - 1)``), and the
    fraction of the residuals' variance that a frame's sightings share (a heading error between
    sensor and truth, which only the truth's residual counts). NaN without such frames."""
    _, inv, count = np.unique(frames, return_inverse=True, return_counts=True)
    n = count[inv]
    multi = n >= 2
    if multi.sum() < 3:
        return float("nan"), float("nan")
    frame_mean = np.bincount(inv, weights=residuals) / count
    within = np.sum((residuals - frame_mean[inv])[multi] ** 2) / np.sum((n[multi] - 1) / n[multi])
    return float(np.sqrt(within)), float(1.0 - within / residuals[multi].var())


# What the robot does around a sighting, by the truth over the window centred on it. "still" is
# below what Vicon's own jitter and a creeping robot give over 1 s; "turning" is where the truth's
# heading drift has grown well past its value at rest (the report's turning percentile is 0.2-0.3 rad/s).
STILL_TURN_RAD_S = 0.01
STILL_SPEED_MM_S = 5.0
TURNING_RAD_S = 0.1
MOTIONS = ("still", "straight", "turning")


def sighting_motion(truth_poses: np.ndarray, steps: np.ndarray, dt: float, window: int) -> np.ndarray:
    """Each sighting's motion, an index into ``MOTIONS``: the truth's mean speed and turn rate over the
    ``window`` steps centred on its step."""
    last = len(truth_poses) - 1
    lo = np.clip(steps - window // 2, 0, last)
    hi = np.clip(steps + window // 2, 0, last)
    span = np.maximum(hi - lo, 1) * dt
    D = relative_displacement(truth_poses[lo], truth_poses[hi])
    turn = np.abs(D[:, 2]) / span
    speed = np.hypot(D[:, 0], D[:, 1]) / span
    motion = np.ones(len(steps), dtype=np.int64)
    motion[(turn < STILL_TURN_RAD_S) & (speed < STILL_SPEED_MM_S)] = 0
    motion[turn >= TURNING_RAD_S] = 2
    return motion


# The truth's heading against its own direction of travel: only where the chord of a window points
# along the heading at the window's middle, which holds exactly on an arc of constant curvature. In
# turns a changing turn rate adds a gap of its own that the residual's timing part follows (on MRCLAM
# the estimate there exceeds the residual's whole variance), so only nearly straight windows count.
TRAVEL_STRAIGHT_RAD_S = 0.03
TRAVEL_MIN_CHORD_MM = 30.0
# A direction of travel further than this from the heading (about the median gap) is a side-step, as a
# legged robot takes, not a heading error; on MRCLAM the gaps' sd is 0.02 rad
TRAVEL_MAX_GAP_RAD = 0.1
TRAVEL_MIN_FRAMES = 20
TRAVEL_BLOCK_WINDOWS = 10


def truth_heading_error(
    truth_poses: np.ndarray,
    truth_valid: np.ndarray,
    bearing_res: np.ndarray,
    steps: np.ndarray,
    dt: float,
    window: int,
    *,
    seed: int = 0,
) -> JsonObject:
    """How much of the bearing residual is the truth's own heading error, from the truth's positions.

    An error ``e`` in the truth's heading enters a frame's mean bearing residual as ``+e`` and the gap
    between the truth's direction of travel (the chord of its positions over the ``window`` steps
    centred on the frame) and its heading as ``-e``. The sensor's own error and a sway of the body enter
    only one of the two, so minus their covariance estimates ``e``'s variance. For a robot that travels
    along its heading (a differential drive, a car), over the frames whose window is valid, nearly
    straight (``TRAVEL_STRAIGHT_RAD_S``), long enough to have a direction and not a side-step:
    that variance, a 90 % block-bootstrap interval (``seed``), its share of the frame means' variance and the
    median gap (a constant angle between the truth's frame and the wheels' direction, which a sensor
    mount fit does not see). NaN with fewer than ``TRAVEL_MIN_FRAMES`` frames."""
    uniq, mean_res = frame_means(bearing_res, steps)
    half = max(window // 2, 1)
    lo, hi = uniq - half, uniq + half
    T = len(truth_poses)
    inside = (lo >= 0) & (hi < T)
    lo, hi, mid, mean_res = lo[inside], hi[inside], uniq[inside], mean_res[inside]
    valid = valid_throughout(truth_valid, lo, hi)
    # the chord in the frame of the heading at the middle: (right, forward), as relative_displacement has it
    chord = relative_displacement(np.column_stack([truth_poses[lo, :2], truth_poses[mid, 2]]), truth_poses[hi])
    gap = np.arctan2(-chord[:, 0], chord[:, 1])  # counterclockwise, like a heading
    turn = np.abs(wrap_angle(truth_poses[hi, 2] - truth_poses[lo, 2])) / (2 * half * dt)
    use = valid & (turn < TRAVEL_STRAIGHT_RAD_S) & (np.hypot(chord[:, 0], chord[:, 1]) > TRAVEL_MIN_CHORD_MM)
    if use.any():
        use &= np.abs(wrap_angle(gap - np.median(gap[use]))) < TRAVEL_MAX_GAP_RAD
    n = int(use.sum())
    nan = float("nan")
    if n < TRAVEL_MIN_FRAMES:
        return {"frames": n, "variance_rad2": nan, "interval_rad2": [nan, nan], "share": nan, "median_gap_rad": nan}
    r, g = mean_res[use], gap[use]
    # the bootstrap resamples blocks of TRAVEL_BLOCK_WINDOWS windows, not frames: neighbouring frames share
    # their windows and the errors persist for seconds, so frames drawn one by one would narrow the interval
    _, block = np.unique(mid[use] // (TRAVEL_BLOCK_WINDOWS * window), return_inverse=True)
    sums = np.stack([np.bincount(block, weights=w) for w in (np.ones(n), r, g, r * g)])

    def error_variance(counts: np.ndarray) -> float:
        k, sr, sg, srg = sums @ counts
        return float(-(srg / k - (sr / k) * (sg / k)))

    nb = sums.shape[1]
    rng = np.random.default_rng(seed)
    boot = [error_variance(np.bincount(rng.integers(0, nb, nb), minlength=nb)) for _ in range(400)]
    var = error_variance(np.ones(nb))
    return {
        "frames": n,
        "variance_rad2": var,
        "interval_rad2": np.percentile(boot, [5, 95]).tolist(),
        "share": var / float(r.var()),
        "median_gap_rad": float(np.median(g)),
    }


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _action_errors(e: np.ndarray) -> dict[str, float]:
    """RMS of the velocity errors ``e`` (N, 3): translational (x and y together) and rotational."""
    return {"translation_rms_mm_s": _rms(np.hypot(e[:, 0], e[:, 1])), "rotation_rms_rad_s": _rms(e[:, 2])}


def truth_noise_structure(
    v_ft: np.ndarray,
    D_true: np.ndarray,
    dt: float,
    bearing_res: np.ndarray,
    frames: np.ndarray,
    window: int,
    motion: np.ndarray | None = None,
) -> JsonObject:
    """What the truth says about the noise that a constant Sigma_m and eq. 4.28 assume away.

    * The sideways and forward miss of the same windows' dead reckoning (``translation_drift``), RMS:
      what a learned Sigma_m's translational sds should not exceed over a window, as the miss holds
      them and From-Truth's own misfit.
    * The heading drift of From-Truth's windows (``v_ft``: ``(N, W, 3)`` velocities) as ``a + b |turn|``
      in variance (``actions.turning_variance`` on the squared drifts), ``|turn|`` the
      window's mean predicted turn rate: its RMS at rest and at the 90th percentile of turning. A
      constant Sigma_m has them equal.
    * The correlation of the mean truth bearing residual of sighting frames 1 to 5 windows apart.
      Eq. 4.28's independent bearings have 0; a correlated error is one the smoother can only explain
      as heading, so the learned bearing sigma leaves it out while the truth residual sigma counts it.
    * The same within a frame (``frame_shared_bearing_error``): a sighting's sd about its frame's mean,
      and the share of the variance that a frame's sightings have in common; with ``motion``
      (``sighting_motion``), that share again for the sightings taken still, driving straight and
      turning. A shared part that only motion brings is a heading error between sensor and truth
      in motion (camera timing, body sway), not the landmark map or the camera's own noise.
    """
    turn, drift = heading_drift(v_ft, D_true, dt)
    # the fit EM's "turning" Sigma_m makes of its steps, here on whole windows
    a, b = turning_variance(drift**2, turn, 1e-6 * drift.var(), (drift.var(), 0.0))
    busy = float(np.percentile(turn, 90))
    uniq, mean_res = frame_means(bearing_res, frames)
    nxt = np.searchsorted(uniq, uniq + window)  # the first frame at least one window later
    ok = (nxt < len(uniq)) & (uniq[np.minimum(nxt, len(uniq) - 1)] - uniq <= 5 * window)
    corr = float(np.corrcoef(mean_res[ok], mean_res[nxt[ok]])[0, 1]) if ok.sum() > 2 else float("nan")
    miss = translation_drift(v_ft, D_true, dt)
    within_sd, shared = frame_shared_bearing_error(bearing_res, frames)
    by_motion = {}
    if motion is not None:
        for i, name in enumerate(MOTIONS):
            m = motion == i
            by_motion[name] = {
                "sightings": int(m.sum()),
                "shared_fraction": frame_shared_bearing_error(bearing_res[m], frames[m])[1],
            }
    return {
        "heading_drift_rms_at_rest_rad": float(np.sqrt(max(a, 0.0))),
        "heading_drift_rms_turning_rad": float(np.sqrt(max(a + b * busy, 0.0))),
        "turning_rad_s": busy,
        "bearing_frame_correlation": corr,
        "bearing_within_frame_sd_rad": within_sd,
        "bearing_frame_shared_fraction": shared,
        "bearing_frame_shared_by_motion": by_motion,
        "heading_drift_variance_fit": [float(a), float(b)],
        "translation_drift_rms_mm": [_rms(miss[:, 0]), _rms(miss[:, 1])],  # sideways, forward
    }


def translation_drift(v_ft: np.ndarray, D_true: np.ndarray, dt: float) -> np.ndarray:
    """``(N, 2)``: what dead-reckoning ``v_ft`` over each window misses of the truth's displacement,
    sideways and forward in the window's starting frame (mm)."""
    return dead_reckon(v_ft, dt)[:, :2] - D_true[:, :2]


def heading_drift(v_ft: np.ndarray, D_true: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Each window's mean predicted turn rate ``|turn|`` (rad/s) and the truth's heading drift from
    the dead-reckoned ``v_ft`` (rad)."""
    drift = wrap_angle(dead_reckon(v_ft, dt)[:, 2] - D_true[:, 2])
    return np.abs(v_ft[:, :, 2]).mean(axis=1), drift


def from_truth_windows(
    data: LandmarkLog, truth_poses: np.ndarray, truth_valid: np.ndarray, action: LinearActionModel, window: int
) -> tuple[np.ndarray, np.ndarray, Callable[[int], np.ndarray]]:
    """The window starts with valid truth, the true ``D`` over each, and ``features(delay)``: the
    ``(N, window, F)`` features of ``action``'s family over the windows with that command delay."""
    starts = window_starts(truth_valid, window)
    if starts.size == 0:
        raise LogFormatError(
            f"no {window}-step window has recorded poses throughout, and the action model is scored over such "
            "windows (dead-reckoned from the truth at each one's start).",
            file=f"{data.source}/groundtruth.csv",
            field="t_s",
            fix=f"score on a log with at least {window} consecutive steps of recorded poses.",
        )
    idx = starts[:, None] + np.arange(window)  # (N, W)
    D_true = relative_displacement(truth_poses[starts], truth_poses[starts + window])
    Phi0 = action.step_features(data.step_commands, 0)

    def features(delay: int) -> np.ndarray:
        return delayed(Phi0, delay)[idx.ravel()].reshape(len(starts), window, -1)

    return starts, D_true, features


def _score_action(
    act: LinearActionModel,
    data: LandmarkLog,
    truth_poses: np.ndarray,
    truth_valid: np.ndarray,
    window: int,
    max_delay_steps: int,
) -> tuple[JsonObject, np.ndarray, np.ndarray, np.ndarray]:
    """The action model against the truth windows, next to From-Truth: the same family, its command
    delay included, fitted to them. Returns the score, the windows' starts, their true displacements
    and From-Truth's velocity in each window's steps."""
    starts, D_true, window_features = from_truth_windows(data, truth_poses, truth_valid, act, window)

    def errors(beta: np.ndarray, Phi: np.ndarray) -> dict[str, float]:
        e = dead_reckon(Phi @ beta, data.dt_s) - D_true
        e[:, 2] = wrap_angle(e[:, 2])
        return _action_errors(e / (window * data.dt_s))

    best = None
    for delay in range(max_delay_steps + 1):
        Phi = window_features(delay)
        sums = Phi.sum(axis=1)
        zero = np.zeros_like(act.coefficients)
        beta = linear_coefficients(
            sums, D_true, np.ones_like(D_true), data.dt_s, zero, act.free_coefficients, act.combined_inputs
        )
        sse = float(np.sum((sums @ beta * data.dt_s - D_true) ** 2 / D_true.var(axis=0)))
        if best is None or sse < best[0]:
            best = (sse, delay, beta, Phi)
    _, delay_ft, beta_ft, Phi_ft = best
    learned = errors(act.coefficients, window_features(act.delay_steps))
    from_truth = errors(beta_ft, Phi_ft)
    score = {
        "learned": learned,
        "from_truth": from_truth,
        "ratio_translation": learned["translation_rms_mm_s"] / from_truth["translation_rms_mm_s"],
        "ratio_rotation": learned["rotation_rms_rad_s"] / from_truth["rotation_rms_rad_s"],
        "learned_coefficients": act.coefficients.tolist(),
        "from_truth_coefficients": beta_ft.tolist(),
        "learned_delay_s": act.delay_steps * data.dt_s,
        "from_truth_delay_s": delay_ft * data.dt_s,
    }
    return score, starts, D_true, Phi_ft @ beta_ft


def _score_range(chan: Any, reading: np.ndarray, d: np.ndarray, bearing: np.ndarray, trim: float) -> JsonObject:
    """The range channel against From-Truth: its family fitted to (true distance, bearing, reading),
    trimmed about its own fit until nothing changes."""
    deg, m = chan.function.degree, len(chan.bearing_terms)
    center, scale = float(d.mean()), float(d.std()) or 1.0
    X = reading_features(d, bearing, deg, m, center, scale)
    has = np.isfinite(reading) & np.all(np.isfinite(X), axis=1)
    X[~has] = 0.0
    keep = has.copy()
    for _ in range(20):  # trim about the From-Truth function, refitted on what is kept
        sol = weighted_lstsq(X[keep], reading[keep])
        pred_ft = X @ sol
        new = trimmed(np.where(has, reading - pred_ft, np.nan), trim)
        if np.array_equal(new, keep):
            break
        keep = new
    ft = chan.with_solution(sol, center, scale, m)
    sr_true = _rms(reading[keep] - pred_ft[keep])
    learned_keep = chan.predict(d[keep], bearing[keep])
    return {
        "sightings_scored": int(keep.sum()),
        "sightings_trimmed": int(has.sum() - keep.sum()),
        "learned_residual_rms_mm": _rms(reading[keep] - learned_keep),
        "from_truth_residual_rms_mm": sr_true,
        "learned_vs_from_truth_rms_mm": _rms(learned_keep - pred_ft[keep]),
        "sigma_learned_mm": chan.sigma,
        "sigma_truth_mm": sr_true,
        "sigma_ratio": chan.sigma / sr_true,
        "from_truth_function": ft.function.to_dict(),
        "from_truth_bearing_terms": list(ft.bearing_terms),
    }


@dataclass(frozen=True, eq=False)
class SeenFromTruth:
    """Each sighting as the truth sees it: the landmark's distance from the sensor (at ``mount`` on the truth's
    poses) and its bearing from there, and from the truth's own point."""

    distance: np.ndarray
    bearing: np.ndarray
    bearing_at_origin: np.ndarray

    @classmethod
    def of(cls, at_origin: np.ndarray, lm: np.ndarray, mount: np.ndarray) -> SeenFromTruth:
        poses = sensor_poses(at_origin, as_mount(mount))
        return cls(landmark_distance(poses, lm), landmark_bearing(poses, lm), landmark_bearing(at_origin, lm))


def _score_bearing(
    sigma: float, bearing: np.ndarray, seen: SeenFromTruth, trim: float
) -> tuple[JsonObject, np.ndarray, np.ndarray]:
    """The bearing sigma against the trimmed truth residuals at the sensor's pose (and, beside them, at
    the truth's origin); returns the score, the residuals and which were kept."""
    b_res = wrap_angle(bearing - seen.bearing)
    b_keep = trimmed(b_res, trim)
    sb_true = _rms(b_res[b_keep])
    b_res0 = wrap_angle(bearing - seen.bearing_at_origin)
    b_keep0 = trimmed(b_res0, trim)
    sb_origin = _rms(b_res0[b_keep0])
    score = {
        "sightings_trimmed": int(np.isfinite(b_res).sum() - b_keep.sum()),
        "sigma_learned_rad": sigma,
        "sigma_truth_rad": sb_true,
        "sigma_ratio": sigma / sb_true,
        "truth_median_rad": float(np.median(b_res[b_keep])),
        # the same residuals at the truth's origin, where the sensor is not
        "truth_origin_sigma_rad": sb_origin,
        "truth_origin_mean_rad": float(np.mean(b_res0[b_keep0])),
        "truth_origin_sigma_ratio": sigma / sb_origin,
    }
    return score, b_res, b_keep


def _learned_drift(model: EMModel, window: int, turning_rad_s: float) -> JsonObject:
    """The learned Sigma_m's drift over the truth windows, to set beside the truth's own:
    ``window * (a + b |turn|)`` in heading variance."""
    a_step = float(np.mean(model.motion_sd[:, 2] ** 2))
    b_step = model.turn_var or 0.0
    # a random walk of Sigma_m's translational sds over the window; the part a heading error carries
    # into position is left out (on MRCLAM at most 1.2 mm over 1 s: 86 mm/s, 0.0043 rad per step)
    xy_var = np.mean(model.motion_sd[:, :2] ** 2, axis=0)
    return {
        "learned_heading_variance_per_step": [a_step, float(b_step)],  # a, b of a + b |turn|
        "learned_heading_drift_at_rest_rad": float(np.sqrt(window * a_step)),
        "learned_translation_drift_mm": np.sqrt(window * xy_var).tolist(),
        "learned_heading_drift_turning_rad": float(np.sqrt(window * (a_step + b_step * turning_rad_s))),
    }


def heading_removed_ratio(sigma_learned: float, sigma_truth: float, heading_error: JsonObject | None) -> float:
    """The learned bearing sigma over the truth's bearing residual sd with the truth's own heading error
    (``truth_heading_error``'s variance) taken out: that error is noise in the reference, not in the
    camera, and no learner can put it in a sigma (docs/em-real.md, Known limits). The plain ratio
    when the error was not estimated; NaN when it is as large as the residual itself."""
    var = (heading_error or {}).get("variance_rad2")
    if var is None or not np.isfinite(var):
        return float(sigma_learned / sigma_truth)
    rest = sigma_truth**2 - max(float(var), 0.0)
    return float(sigma_learned / np.sqrt(rest)) if rest > 0 else float("nan")


def score_against_positions(
    model: EMModel, data: LandmarkLog, truth_poses: np.ndarray, truth_valid: np.ndarray, *, window: int, trim: float
) -> JsonObject:
    """``score_against_truth`` for a truth of positions alone (a UWB or GNSS track, no heading): what
    needs the truth's heading is not scored and says so (``no_heading``): the rotation, the bearing, the
    sensor's pose fitted to the truth and the truth's noise structure. The translation is scored free of
    heading, on each window's chord: ``| |D_xy| - |p_end - p_start| |`` is the translation error with the
    window's starting heading chosen best; From-Truth is the same family fitted to the chords (at the
    learned command delay). The range is read from the truth's point."""
    from scipy.optimize import least_squares

    act = model.action
    starts = window_starts(truth_valid, window)
    if starts.size == 0:
        raise LogFormatError(
            f"no {window}-step window has recorded positions throughout.",
            file=f"{data.source}/groundtruth.csv",
            field="t_s",
            fix=f"score on a log with at least {window} consecutive steps of recorded positions.",
        )
    idx = starts[:, None] + np.arange(window)
    chord = np.hypot(*(truth_poses[starts + window, :2] - truth_poses[starts, :2]).T)
    Phi = act.step_features(data.step_commands, act.delay_steps)[idx.ravel()].reshape(len(starts), window, -1)
    free = act.free_coefficients
    span = window * data.dt_s

    def chord_errors(beta: np.ndarray) -> np.ndarray:
        return np.hypot(*dead_reckon(Phi @ beta, data.dt_s)[:, :2].T) - chord

    def with_free(x: np.ndarray) -> np.ndarray:
        beta = act.coefficients.copy()
        beta[free] = x
        return beta

    fit = least_squares(lambda x: chord_errors(with_free(x)), act.coefficients[free])
    learned = {"translation_rms_mm_s": _rms(chord_errors(act.coefficients)) / span, "rotation_rms_rad_s": None}
    from_truth = {"translation_rms_mm_s": _rms(chord_errors(with_free(fit.x))) / span, "rotation_rms_rad_s": None}
    action = {
        "learned": learned,
        "from_truth": from_truth,
        "ratio_translation": learned["translation_rms_mm_s"] / from_truth["translation_rms_mm_s"],
        "ratio_rotation": None,  # no heading to score it against
        "learned_coefficients": act.coefficients.tolist(),
        "from_truth_coefficients": with_free(fit.x).tolist(),
        "learned_delay_s": act.delay_steps * data.dt_s,
        "from_truth_delay_s": act.delay_steps * data.dt_s,
        "scored_on": "window chords (the truth has no heading)",
    }
    rows = np.flatnonzero(truth_valid[data.obs_step] > 0)
    lm = data.landmarks_xy[data.obs_landmark[rows]]
    d = landmark_distance(truth_poses[data.obs_step[rows]], lm)
    range_score = _score_range(
        model.sensor.channels[0], data.obs_readings[rows, 0], d, data.obs_bearing_rad[rows], trim
    )
    return {
        "windows_scored": int(starts.size),
        "window_s": span,
        "action": action,
        "range": range_score,
        "bearing": None,
        "sensor_mount": {"learned": model.sensor.mount.to_dict(), "fitted_to_truth": None},
        "truth_noise": None,
        "no_heading": "the truth has positions and no heading: the rotation, the bearing, the sensor's pose on the "
        "robot and the truth's noise are not scored; the translation is scored on each window's chord",
    }


def score_against_truth(
    model: EMModel,
    data: LandmarkLog,
    truth_poses: np.ndarray,
    truth_valid: np.ndarray,
    *,
    window: int = 30,
    trim: float = 3.0,
    max_delay_steps: int = 15,
    fit_mount: bool = True,
) -> JsonObject:
    """Learned and From-Truth errors of ``model`` on ``data`` (see the module docstring). Without
    ``fit_mount`` the sensor is taken to sit at the truth's origin."""
    if model.action.linear() is None or data.step_commands is None:
        raise ValueError("scoring against truth needs a continuous action model and per-step commands")
    if not np.isfinite(truth_poses[np.asarray(truth_valid, dtype=bool), 2]).any():
        return score_against_positions(model, data, truth_poses, truth_valid, window=window, trim=trim)
    action, starts, D_true, v_ft = _score_action(model.action, data, truth_poses, truth_valid, window, max_delay_steps)

    # sensor: the sightings at steps with valid truth, seen from the sensor's pose
    rows = np.flatnonzero(truth_valid[data.obs_step] > 0)
    at_origin = truth_poses[data.obs_step[rows]]
    lm = data.landmarks_xy[data.obs_landmark[rows]]
    bearing = data.obs_bearing_rad[rows]
    # a range-only sensor (radio beacons) has no bearing to score, nor to fit its pose on the robot by
    reads_bearing = model.sensor.reads_bearing and bool(np.isfinite(bearing).any())
    mount = fit_sensor_mount(at_origin, lm, bearing, trim) if fit_mount and reads_bearing else np.zeros(3)
    seen = SeenFromTruth.of(at_origin, lm, mount)
    range_score = _score_range(model.sensor.channels[0], data.obs_readings[rows, 0], seen.distance, bearing, trim)
    b_res, b_keep = np.empty(0), np.zeros(0, dtype=bool)
    bearing_score = None
    if reads_bearing:
        bearing_score, b_res, b_keep = _score_bearing(model.sensor.sigma_bearing_rad, bearing, seen, trim)
    b_steps = data.obs_step[rows][b_keep]
    structure = truth_noise_structure(
        v_ft,
        D_true,
        data.dt_s,
        b_res[b_keep],
        b_steps,
        window,
        sighting_motion(truth_poses, b_steps, data.dt_s, window),
    )
    structure["truth_heading_error"] = truth_heading_error(
        truth_poses, truth_valid, b_res[b_keep], b_steps, data.dt_s, window
    )
    structure.update(_learned_drift(model, window, structure["turning_rad_s"]))
    if bearing_score is not None:
        bearing_score["sigma_ratio_truth_heading_removed"] = heading_removed_ratio(
            bearing_score["sigma_learned_rad"], bearing_score["sigma_truth_rad"], structure["truth_heading_error"]
        )
    heading_doubt = groundtruth_heading_doubt(truth_poses, truth_valid, data.dt_s)
    return {
        "windows_scored": int(starts.size),
        "window_s": window * data.dt_s,
        "action": action,
        "range": range_score,
        "bearing": bearing_score,  # None: the sensor reads no bearing
        "sensor_mount": {
            "learned": model.sensor.mount.to_dict(),  # from the point EM tracks (learn/em/mount.py)
            # from the point the truth tracks, fitted to the bearings (None: no bearings to fit it by)
            "fitted_to_truth": (
                {"forward_mm": float(mount[1]), "left_mm": float(-mount[0]), "yaw_rad": float(mount[2])}
                if reads_bearing
                else None
            ),
        },
        "truth_noise": structure,
    } | ({"truth_heading_doubt": heading_doubt} if heading_doubt else {})
