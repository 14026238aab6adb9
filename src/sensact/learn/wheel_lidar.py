"""A differential drive's wheels and its 2-D lidar's mount, learned together from encoders and scan matching,
with no ground truth and no map (docs/lidar2d.md).

The thesis's chapter 5 learns a car's motion from scan matching; Censi, Franchi, Marchionni and Oriolo (IEEE
T-RO 2013) calibrate wheel radii, axle and the lidar's pose from encoders and scan matching: the robot's
displacement ``o`` over an interval (from the wheels) and the lidar's ``s`` (from ICP) satisfy
``o (+) l = l (+) s`` for the lidar's pose ``l`` on the robot. Their closed form (``closed_form``) starts this
learner; the answer is the maximum-likelihood fit over the whole run (``fit``):

* intervals between keyframes a quarter metre or 20 degrees apart, each scan deskewed by the odometry
  (a LaserScan's beams are taken one after another, ``time_increment`` apart);
* each interval's residual (the lidar's displacement predicted from the wheels, minus the matched one)
  Gaussian with a variance per axis of ``a + b * distance + c * turn``: ``a`` the scan matcher's noise,
  ``b`` and ``c`` the drive's (its slip), learned from the residuals as chapter 4's M-step learns Sigma_m;
* the wheels' radii, axle, the lidar's mount and the clock offset (or a command's delay) by weighted least
  squares, intervals beyond 4 sd dropped, rounds until the variances settle;
* error bars from the fit's curvature (the inverse of J^T J, scaled by chi^2 per degree of freedom).

The lidar's range noise comes from the scans alone: a point off the chord of its two neighbours on a flat
surface is three beams' noise (``range_noise``).

Poses and displacements are sensact's one internal frame and ``core``'s pose algebra (``core.pose_models``: x to
the robot's right, y forward, theta counterclockwise, 0 where the log starts); the lidar's mount is
``(forward_mm, left_mm, yaw_rad)``, as ``sensor_poses`` reads a sensor's. The scans and the scan matcher stay in
the lidar's own frame (REP 103, as a LaserScan gives its beams): a matched displacement crosses into sensact's
axes where it is read, a guess back where it is given.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares, minimize_scalar, nnls

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import (
    apply_displacement,
    arc_poses,
    chords_of,
    from_rep103,
    relative_displacement,
    sensor_poses,
    to_rep103,
)
from sensact.errors import LogFormatError
from sensact.learn.scan_match2d import icp, reference_of, scan_xy
from sensact.logs.intervals_log import IntervalsLog
from sensact.logs.lidar2d_log import Lidar2DLog
from sensact.progress import Progress

KEYFRAME_MM, KEYFRAME_RAD = 250.0, 0.35
OUTLIER_SD = 4.0
# the fit converges to the answer its data give, not to where a loose stopping rule leaves it
TOL = 1e-12
STEP_OF_SCALE = 1e-6  # a finite-difference step, as a share of its parameter's scale (``fit``'s ``scale``)
PARAMETERS = ("wheel_radius_left_mm", "wheel_radius_right_mm", "axle_mm", "forward_mm", "left_mm", "yaw_rad", "delay_s")
# what a log must pin down for an answer: sd of the mount (mm, rad) and of the wheels (share of the radius)
MOUNT_SD_MM, MOUNT_SD_RAD, WHEEL_SD_SHARE = 20.0, 0.0175, 0.01
MIN_TURN_RAD = 1.0  # the closed form's turn regression needs the robot to have turned at least this much in all


# --- the drive ---
@dataclass(frozen=True, eq=False)
class WheelTrack:
    """Each wheel's accumulated turn (``phi``, (n, 2) left and right) at ``t``: an encoder's positions, or the
    wheel turns a nominal radius and axle give for /odom's or /cmd_vel's motion (``virtual``)."""

    t: np.ndarray
    phi: np.ndarray
    virtual: bool  # the turns are /odom's or /cmd_vel's motion on the nominal wheels, not an encoder's


def odometry(track: WheelTrack, rl: float, rr: float, b: float) -> np.ndarray:
    """(n, 3) poses at ``track.t`` from the wheels' turns (each step an arc)."""
    d = np.diff(track.phi, axis=0) * (rl, rr)
    return arc_poses(d.mean(axis=1), (d[:, 1] - d[:, 0]) / b)


def poses_at(track: WheelTrack, poses: np.ndarray, times: np.ndarray, delay_s: float) -> np.ndarray:
    """The odometry's poses at ``times``, the wheels' clock ``delay_s`` behind the lidar's."""
    t = track.t + delay_s
    return np.column_stack([np.interp(times, t, poses[:, j]) for j in range(3)])


def wheel_track(log: Lidar2DLog) -> WheelTrack:
    """What drives the robot as wheel turns: the encoders, or /odom's (or /cmd_vel's) motion on the URDF's wheels
    (a radius and axle of 1 mm where it gives none: the learned ones are then the gains)."""
    t, v = log.drive_t, log.drive_values
    if log.drive == "wheels":
        return WheelTrack(t, v.copy(), False)
    r0 = log.urdf.wheel_radius_mm or 1.0
    b0 = log.urdf.axle_mm or 1.0
    if log.drive == "odom":
        chord, dth = chords_of(from_rep103(v))  # /odom's poses, REP 103 in its frame
        ds = chord / np.maximum(np.sinc(dth / (2 * np.pi)), 1e-6)
    else:  # cmd_vel: each command holds until the next
        dt = np.diff(t)
        ds, dth = v[:-1, 0] * dt, v[:-1, 1] * dt
    dl, dr = (ds - dth * b0 / 2) / r0, (ds + dth * b0 / 2) / r0
    phi = np.vstack([[0.0, 0.0], np.column_stack([np.cumsum(dl), np.cumsum(dr)])])
    return WheelTrack(t, phi, True)


def drive_of_odometry(
    wheel_t: np.ndarray, phi: np.ndarray, odom_t: np.ndarray, odom_pose: np.ndarray
) -> tuple[float, float, float] | None:
    """The radii and axle /odom was computed with (``(r_left, r_right, axle)`` per unit of the wheels'
    positions): least squares of its motion on the wheels' turns, or None if it hardly moved."""
    if odom_t.size < 10 or wheel_t.size < 10:
        return None
    ph = np.column_stack([np.interp(odom_t, wheel_t, phi[:, j]) for j in range(2)])
    ds, dth = chords_of(from_rep103(odom_pose))  # /odom's poses, REP 103 in its frame
    dp = np.diff(ph, axis=0)
    (kl, kr), *_ = np.linalg.lstsq(dp, 2 * ds, rcond=None)  # ds = (r_l dphi_l + r_r dphi_r) / 2
    (jl, jr), *_ = np.linalg.lstsq(dp, dth, rcond=None)  # dth = (r_r dphi_r - r_l dphi_l) / b
    if not (kl > 0 and kr > 0 and jr > 0 and jl < 0):
        return None
    b = (kl / -jl + kr / jr) / 2
    return float(kl), float(kr), float(b)


# --- the scans ---
def scan_points(log: Lidar2DLog, lidar_at: np.ndarray | None, mount: np.ndarray) -> list[np.ndarray]:
    """Each scan's points ((beams, 2), NaN where no return) in the lidar's frame (REP 103) at its stamp; with
    ``lidar_at`` (the robot's pose at every beam's time, (scans * beams, 3)) each beam moved to where the lidar
    was at the stamp."""
    angles = log.scan.angles(log.beams)
    out = []
    for k in range(log.scan_t.size):
        xy = scan_xy(log.ranges_mm[k], angles)
        ok = np.isfinite(xy[:, 0])
        if lidar_at is not None:
            sensor = sensor_poses(lidar_at[k * log.beams : (k + 1) * log.beams], mount)
            rel = relative_displacement(sensor[0], sensor)
            xy = to_rep103(apply_displacement(rel, from_rep103(np.column_stack([xy, np.zeros(len(xy))]))))[:, :2]
        out.append(np.where(ok[:, None], xy, np.nan))
    return out


def beam_poses(log: Lidar2DLog, track: WheelTrack, params: np.ndarray) -> np.ndarray | None:
    """The robot's pose at every beam's time (None when the scan's beams share its stamp)."""
    if log.scan.time_increment_s <= 0:
        return None
    rl, rr, b, *_, delay = params
    times = (log.scan_t[:, None] + log.scan.time_increment_s * np.arange(log.beams)).ravel()
    return poses_at(track, odometry(track, rl, rr, b), times, delay)


@dataclass(frozen=True)
class Matches:
    """Scan-matched intervals: scan ``i[k]`` to ``j[k]``, the lidar's displacement ``s[k]`` (sensact's axes)."""

    i: np.ndarray
    j: np.ndarray
    s: np.ndarray
    tried: int


def predicted(params: np.ndarray, track: WheelTrack, scan_t: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """The lidar's displacement from scan ``i`` to ``j`` the wheels predict: ``l^-1 (+) o (+) l``."""
    rl, rr, b, *mount, delay = params
    at = poses_at(track, odometry(track, rl, rr, b), scan_t, delay)
    lidar = sensor_poses(np.zeros(3), mount)
    return relative_displacement(lidar, sensor_poses(relative_displacement(at[i], at[j]), mount))


def match_pairs(
    points: list[np.ndarray],
    increment: float,
    i: np.ndarray,
    j: np.ndarray,
    guess: np.ndarray | None,
    progress: Progress | None,
    what: str,
) -> Matches:
    """ICP of scan ``j[k]`` onto scan ``i[k]`` from ``guess[k]`` (None: each from the last match, a constant
    velocity, as for consecutive scans with nothing else to go on)."""
    refs: dict[int, object] = {}
    keep, s = [], []
    last = np.zeros(3)
    for k, (a, c) in enumerate(zip(i.tolist(), j.tolist(), strict=True)):
        if a not in refs:
            refs = {a: reference_of(points[a], increment)}
        ref = refs[a]
        cur = points[c][np.isfinite(points[c][:, 0])]
        if ref is not None and len(cur) >= 40:
            m = icp(ref, cur, last if guess is None else to_rep103(guess[k]))
            if m.ok:
                keep.append(k)
                s.append(m.pose)
                last = m.pose
        if progress is not None and (k % 50 == 0 or k == len(i) - 1):
            progress(what, k + 1, len(i))
    keep_ = np.array(keep, dtype=int)
    return Matches(i[keep_], j[keep_], from_rep103(np.array(s).reshape(-1, 3)), len(i))


# --- Censi et al.'s closed form ---
def _mount_fit(phi: float, o: np.ndarray, s: np.ndarray) -> tuple[float, np.ndarray]:
    """For a mount yaw ``phi``: the least-squares ``(l_x, l_y, b)`` of ``(R(o_theta) - I) l_t + b c = R(phi) s_t``
    (``o``: the turn and the translation per unit of axle) and its cost."""
    c, s_ = np.cos(phi), np.sin(phi)
    cth, sth = np.cos(o[:, 2]), np.sin(o[:, 2])
    A = np.zeros((2 * len(o), 3))
    A[0::2] = np.column_stack([cth - 1, -sth, o[:, 0]])
    A[1::2] = np.column_stack([sth, cth - 1, o[:, 1]])
    rhs = np.empty(2 * len(o))
    rhs[0::2] = c * s[:, 0] - s_ * s[:, 1]
    rhs[1::2] = s_ * s[:, 0] + c * s[:, 1]
    x, *_ = np.linalg.lstsq(A, rhs, rcond=None)
    return float(np.sum((A @ x - rhs) ** 2)), x


def closed_form(track: WheelTrack, scan_t: np.ndarray, m: Matches, delay_s: float = 0.0) -> np.ndarray:
    """Censi, Franchi, Marchionni and Oriolo (2013), sec. IV: the turn ``J21 dphi_l + J22 dphi_r`` by linear
    least squares on the matched rotations; then, for the axle ``b`` and the mount ``l``, the constrained
    quadratic ``sum |(R(o_theta) - I) l_t + b c - R(l_theta) s_t|^2``, solved here exactly over ``l_theta``
    (linear in the rest); outliers beyond 3 MADs dropped and both steps redone, three times. Returns the
    parameters in ``PARAMETERS``' order (the delay as given)."""
    ph = np.column_stack([np.interp(scan_t, track.t + delay_s, track.phi[:, j]) for j in range(2)])
    dphi = ph[m.j] - ph[m.i]
    keep = np.ones(len(m.i), dtype=bool)
    for _ in range(3):
        (j21, j22), *_ = np.linalg.lstsq(dphi[keep], m.s[keep, 2], rcond=None)
        unit = poses_at(track, odometry(track, -j21, j22, 1.0), scan_t, delay_s)
        o = relative_displacement(unit[m.i], unit[m.j])  # translation per unit of axle, rotation itself

        grid = np.linspace(-np.pi, np.pi, 73)
        o_k, s_k = o[keep], m.s[keep]
        costs = [_mount_fit(p, o_k, s_k)[0] for p in grid]
        p0 = grid[int(np.argmin(costs))]
        phi = minimize_scalar(
            lambda p, o_k=o_k, s_k=s_k: _mount_fit(p, o_k, s_k)[0], bounds=(p0 - 0.1, p0 + 0.1), method="bounded"
        ).x
        _, (lx, ly, b) = _mount_fit(phi, o_k, s_k)
        if b < 0:  # (l, b, phi) and (-l, -b, phi + pi) fit alike: the axle is positive (Censi et al., sec. IV)
            lx, ly, b, phi = -lx, -ly, -b, phi + np.pi
        # the mount (x right, y forward on the robot) as forward and left
        params = np.array([-j21 * b, j22 * b, b, ly, -lx, wrap_angle(phi), delay_s])
        r = predicted(params, track, scan_t, m.i, m.j) - m.s
        r[:, 2] = wrap_angle(r[:, 2])
        z = np.abs(r - np.median(r[keep], axis=0)) / (
            1.4826 * np.median(np.abs(r[keep] - np.median(r[keep], axis=0)), axis=0) + 1e-12
        )
        keep = (z < 3).all(axis=1)
    return params


# --- the maximum-likelihood fit ---
@dataclass(frozen=True)
class NoiseModel:
    """Per axis (x, y, theta of the lidar's displacement, sensact's axes): variance
    ``a + b * distance_mm + c * turn_rad``."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray

    def sd(self, dist: np.ndarray, turn: np.ndarray) -> np.ndarray:
        return np.sqrt(self.a + self.b * dist[:, None] + self.c * turn[:, None])

    def rep103(self) -> NoiseModel:
        """The same noise on REP 103's axes (forward, left, yaw), as a ROS user reads it: variances, so a swap."""
        order = [1, 0, 2]
        return NoiseModel(self.a[order], self.b[order], self.c[order])


@dataclass(frozen=True)
class WheelLidarFit:
    params: np.ndarray  # PARAMETERS' order
    cov: np.ndarray  # (7, 7)
    noise: NoiseModel
    used: np.ndarray  # which matches were kept (not outliers)
    chi2_per_dof: float
    matches: Matches
    start: np.ndarray  # the closed form's answer
    distance_mm: float  # travelled over the used intervals
    turn_rad: float

    @property
    def sd(self) -> np.ndarray:
        d = np.diag(self.cov)
        return np.where(d >= 0, np.sqrt(np.abs(d)), np.inf)  # a negative variance: a fit the log cannot pin down


def interval_size(
    params: np.ndarray, track: WheelTrack, scan_t: np.ndarray, m: Matches
) -> tuple[np.ndarray, np.ndarray]:
    rl, rr, b, *_, delay = params
    at = poses_at(track, odometry(track, rl, rr, b), scan_t, delay)
    o = relative_displacement(at[m.i], at[m.j])
    return np.hypot(o[:, 0], o[:, 1]), np.abs(o[:, 2])


def fit(
    track: WheelTrack, scan_t: np.ndarray, m: Matches, start: np.ndarray, rounds: int = 5, *, hold_delay: bool = False
) -> WheelLidarFit:
    """The maximum-likelihood wheels, mount and delay on the matched intervals, from ``start`` (``hold_delay``:
    the delay held at ``start``'s, for intervals that come without a clock to shift)."""
    scale = np.array([1.0, 1.0, 10.0, 10.0, 10.0, 0.01, 0.01]) * np.array(
        [max(abs(start[0]), 1e-9) / 30, max(abs(start[1]), 1e-9) / 30, max(abs(start[2]), 1e-9) / 150, 1, 1, 1, 1]
    )

    def predict(params: np.ndarray, rows: np.ndarray | slice) -> np.ndarray:
        return predicted(params, track, scan_t, m.i[rows], m.j[rows])

    def size(params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return interval_size(params, track, scan_t, m)

    return fit_intervals(predict, size, m, start, scale, 6 if hold_delay else 7, rounds)


def fit_intervals(
    predict: Any, size: Any, m: Matches, start: np.ndarray, scale: np.ndarray, free: int, rounds: int = 5
) -> WheelLidarFit:
    """The maximum-likelihood parameters of a drive and a lidar's mount on matched intervals, from ``start``:
    ``predict(params, rows)`` is the lidar's displacement over intervals ``rows`` (sensact's axes),
    ``size(params)`` every interval's distance (mm) and turn (rad) by the drive; the first ``free`` parameters
    are fitted (each finite-difference step sized to ``scale``), the rest held at ``start``'s."""
    held = start[free:].copy()

    def full(x: np.ndarray) -> np.ndarray:
        return np.concatenate([x, held])

    params = start.copy()
    dist, turn = size(params)
    every = slice(None)
    r0 = predict(params, every) - m.s
    r0[:, 2] = wrap_angle(r0[:, 2])
    spread = (1.4826 * np.median(np.abs(r0), axis=0)) ** 2 + 1e-12
    noise = NoiseModel(spread, np.zeros(3), np.zeros(3))
    used = np.ones(len(m.i), dtype=bool)
    scale = scale[:free]

    def residuals(x: np.ndarray, rows: np.ndarray, sd: np.ndarray) -> np.ndarray:
        r = predict(full(x), rows) - m.s[rows]
        r[:, 2] = wrap_angle(r[:, 2])
        return (r / sd).ravel()

    # each parameter's finite-difference step is sized to its own scale, not to its value: a step relative to a
    # delay near 0 s (or a mount near 0 mm) is a difference of rounding errors, and the fit wandered on it
    step = STEP_OF_SCALE * scale

    def jacobian(x: np.ndarray, rows: np.ndarray, sd: np.ndarray) -> np.ndarray:
        cols = []
        for k, h in enumerate(step):
            dx = np.zeros_like(x)
            dx[k] = h
            cols.append((residuals(x + dx, rows, sd) - residuals(x - dx, rows, sd)) / (2 * h))
        return np.column_stack(cols)

    def solve(x0: np.ndarray, rows: np.ndarray, sd: np.ndarray) -> Any:
        return least_squares(
            residuals,
            x0[:free],
            jac=jacobian,
            args=(rows, sd),
            x_scale=scale,
            method="lm",
            xtol=TOL,
            ftol=TOL,
            gtol=TOL,
        )

    for _ in range(rounds):
        sd = noise.sd(dist, turn)
        params = full(solve(params, used, sd[used]).x)
        dist, turn = size(params)
        r = predict(params, every) - m.s
        r[:, 2] = wrap_angle(r[:, 2])
        design = np.column_stack([np.ones(len(dist)), dist, turn])
        coef = np.array(
            [
                nnls(
                    design[used] / noise.sd(dist, turn)[used, a : a + 1] ** 2,
                    r[used, a] ** 2 / noise.sd(dist, turn)[used, a] ** 2,
                )[0]
                for a in range(3)
            ]
        )
        floor = np.array([0.01, 0.01, 1e-8])  # (0.1 mm)^2, (0.1 mrad)^2
        noise = NoiseModel(np.maximum(coef[:, 0], floor), coef[:, 1], coef[:, 2])
        used = (np.abs(r / noise.sd(dist, turn)) < OUTLIER_SD).all(axis=1)
    sd = noise.sd(dist, turn)
    sol = solve(params, used, sd[used])
    params = full(sol.x)
    J = sol.jac
    dof = max(1, J.shape[0] - J.shape[1])
    chi2 = float(np.sum(sol.fun**2)) / dof
    n = len(start)
    cov = np.zeros((n, n))  # a held parameter: no variance
    try:
        cov[:free, :free] = np.linalg.inv(J.T @ J) * chi2
    except np.linalg.LinAlgError:
        cov[:free, :free] = np.inf
    dist, turn = size(params)
    return WheelLidarFit(params, cov, noise, used, chi2, m, start, float(dist[used].sum()), float(turn[used].sum()))


def keyframes(
    track: WheelTrack, params: np.ndarray, scan_t: np.ndarray, usable: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of usable scans a quarter metre or 20 degrees apart by the odometry, each from the last."""
    rl, rr, b, *_, delay = params
    return keyframes_of(poses_at(track, odometry(track, rl, rr, b), scan_t, delay), usable, KEYFRAME_MM, KEYFRAME_RAD)


def keyframes_of(
    at: np.ndarray, usable: np.ndarray, apart_mm: float, apart_rad: float
) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of usable scans (poses ``at``) ``apart_mm`` or ``apart_rad`` apart, each from the last."""
    idx = np.flatnonzero(usable)
    i, j = [], []
    if idx.size == 0:
        return np.array([], int), np.array([], int)
    last = idx[0]
    for k in idx[1:]:
        d = relative_displacement(at[last], at[k])[0]
        if np.hypot(d[0], d[1]) >= apart_mm or abs(d[2]) >= apart_rad:
            i.append(last)
            j.append(k)
            last = k
    return np.array(i, int), np.array(j, int)


@dataclass(frozen=True)
class RangeNoise:
    sigma_mm: float
    sd_mm: float


def range_noise(ranges_mm: np.ndarray, angles: np.ndarray, window: int = 5) -> RangeNoise:
    """The lidar's range noise from its own scans: along a surface the range is a smooth function of the beam's
    angle, so a beam's range less the cubic through its ``window`` neighbours (a Savitzky-Golay filter's
    residual, whose gain on white noise is known) has the range's sd. Edges are what does not fit: a Gaussian
    and a broad uniform mixed, fitted by EM; grazing beams (incidence beyond 63 degrees) are left out. Its sd:
    the spread of the answers from near and far, square-on and oblique surfaces (how much it depends on
    which), and of ten blocks of scans (chance)."""
    from numpy.lib.stride_tricks import sliding_window_view
    from scipy.signal import savgol_coeffs

    smooth = savgol_coeffs(window, 3, use="dot")
    slope = savgol_coeffs(window, 3, deriv=1, use="dot") / abs(angles[1] - angles[0])
    kernel = -smooth
    kernel[window // 2] += 1.0
    win = sliding_window_view(ranges_mm, window, axis=1)  # (scans, beams - window + 1, window)
    with np.errstate(invalid="ignore"):
        z = (win @ kernel) / np.sqrt(np.sum(kernel**2))
        r = win[..., window // 2]
        tan_a = np.abs(win @ slope) / r
        ok = np.isfinite(z) & (tan_a < 2.0)
    rows = np.broadcast_to(np.arange(ranges_mm.shape[0])[:, None], z.shape)[ok]
    zz, rr, tt = z[ok], r[ok], tan_a[ok]
    if zz.size < 200:
        return RangeNoise(float("nan"), float("nan"))
    whole = _mixture_sd(zz)
    subsets = [rr < np.median(rr), rr >= np.median(rr), tt < np.median(tt), tt >= np.median(tt)]
    by = tuple(_mixture_sd(zz[m_]) for m_ in subsets)
    blocks = [_mixture_sd(zz[(rows * 10 // ranges_mm.shape[0]) == b]) for b in range(10)]
    chance = float(np.nanstd(blocks, ddof=1) / np.sqrt(10))
    systematic = float(np.nanstd(by, ddof=1))
    return RangeNoise(whole, float(np.hypot(chance, systematic)))


def _mixture_sd(z: np.ndarray, iterations: int = 60) -> float:
    z = z[np.abs(z) < 500]
    if z.size < 20:
        return float("nan")
    width = 1000.0
    sigma = max(1.4826 * float(np.median(np.abs(z))), 0.1)
    w = 0.1
    for _ in range(iterations):
        g = (1 - w) * np.exp(-0.5 * (z / sigma) ** 2) / (np.sqrt(2 * np.pi) * sigma)
        p = g / (g + w / width)
        sigma = max(float(np.sqrt(np.sum(p * z**2) / np.sum(p))), 0.05)
        w = float(np.clip(1 - p.mean(), 1e-4, 0.9))
    return sigma


@dataclass(frozen=True)
class WheelLidarResult:
    fit: WheelLidarFit
    closed_form: np.ndarray  # Censi et al.'s answer on consecutive scans (deskewed by the fit's odometry)
    range: RangeNoise
    track: WheelTrack
    consecutive: Matches
    notes: tuple[str, ...]


def _closed_form_start(
    track: WheelTrack, scan_t: np.ndarray, m: Matches
) -> tuple[WheelTrack, np.ndarray | None, list[str]]:
    """Censi et al.'s closed form to start the fit, its wheels read the right way round (``_oriented``); None
    where the matches hardly turn or the wheels did not turn as the scans did."""
    if np.abs(m.s[:, 2]).sum() < MIN_TURN_RAD:
        return track, None, []
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a degenerate log's closed form: judged below
        start = closed_form(track, scan_t, m)
    if not (np.isfinite(start).all() and start[2] > 0 and abs(start[0]) > 0 and abs(start[1]) > 0):
        return track, None, []
    track, start, notes = _oriented(track, start)
    if notes:
        start = closed_form(track, scan_t, m)
    return track, start, notes


def _oriented(track: WheelTrack, params: np.ndarray) -> tuple[WheelTrack, np.ndarray, list[str]]:
    """A wheel whose position counts down as it drives forward (its joint's axis the other way) shows as a
    negative radius in the closed form, and wheels whose names are swapped as two: read them the right way."""
    notes = []
    phi = track.phi.copy()
    rl, rr = params[:2]
    if rl < 0 and rr < 0:
        phi = phi[:, ::-1]
        rl, rr = -rr, -rl
        notes.append(
            "the wheels' positions turn the robot the other way: read left as right and right as left (or both "
            "count down as they drive forward)"
        )
    elif rl < 0 or rr < 0:
        side = 0 if rl < 0 else 1
        phi[:, side] *= -1
        notes.append(
            f"the {('left', 'right')[side]} wheel's position counts down as it drives forward: "
            "read with its sign turned"
        )
        rl, rr = abs(rl), abs(rr)
    return WheelTrack(track.t, phi, track.virtual), np.array([rl, rr, *params[2:]]), notes


def learn_wheel_lidar(log: Lidar2DLog, progress: Progress | None = None, rounds: int = 2) -> WheelLidarResult:
    """The whole calibration from no guess: consecutive scans matched from a constant velocity (or, when the
    URDF gives the wheels, from their odometry), Censi et al.'s closed form on them, then keyframes matched
    from that odometry and the maximum-likelihood fit, rounds of deskewing by the fit and matching again."""
    log = log.from_its_start()
    track = wheel_track(log)
    inc = abs(log.scan.angle_increment_rad)
    n = log.scan_t.size
    i, j = np.arange(n - 1), np.arange(1, n)
    urdf = log.urdf
    guess = nominal = None
    if urdf.wheel_radius_mm and urdf.axle_mm and not track.virtual:
        mount = urdf.mount
        m0 = np.zeros(3) if mount is None else np.array([mount.forward_mm, mount.left_mm, mount.yaw_rad])
        nominal = np.array([urdf.wheel_radius_mm, urdf.wheel_radius_mm, urdf.axle_mm, *m0, 0.0])
        guess = predicted(nominal, track, log.scan_t, i, j)
    elif track.virtual:  # /odom's or /cmd_vel's motion on nominal wheels: 1 is each gain's guess
        m0 = (
            np.zeros(3)
            if urdf.mount is None
            else np.array([urdf.mount.forward_mm, urdf.mount.left_mm, urdf.mount.yaw_rad])
        )
        nominal = np.array([urdf.wheel_radius_mm or 1.0, urdf.wheel_radius_mm or 1.0, urdf.axle_mm or 1.0, *m0, 0.0])
        guess = predicted(nominal, track, log.scan_t, i, j)
    points = scan_points(log, None, np.zeros(3))
    first = match_pairs(points, inc, i, j, guess, progress, "matching consecutive scans")
    if len(first.i) < 10:
        raise_too_few(log, len(first.i), first.tried)
    track, start, notes = _closed_form_start(track, log.scan_t, first)
    if start is not None:
        pass
    elif nominal is not None:  # the closed form needs turns: the URDF starts the fit, which will flag the mount
        start = nominal
        notes.append(
            "the closed form could not start the fit (the robot hardly turned, or its wheels did not turn "
            "as its scans did): the URDF's wheels and mount start it"
        )
    else:
        raise LogFormatError(
            f"the scans turned {np.abs(first.s[:, 2]).sum():.2g} rad in all, and the wheels do not say how (or the "
            "URDF gives no wheels to start from): the wheels' radii and axle show only in turns.",
            file=log.source,
            field="wheels",
            fix="record the robot turning both ways as well as driving.",
        )
    usable = np.array([np.isfinite(log.ranges_mm[k]).sum() >= 40 for k in range(n)])
    ki, kj = keyframes(track, start, log.scan_t, usable)
    result = None
    params = start
    for r in range(rounds + 1):
        pts = scan_points(log, beam_poses(log, track, params), params[3:6])
        m = match_pairs(
            pts,
            inc,
            ki,
            kj,
            predicted(params, track, log.scan_t, ki, kj),
            progress,
            f"matching keyframes, round {r + 1}",
        )
        if len(m.i) < 10:
            raise_too_few(log, len(m.i), m.tried)
        result = fit(track, log.scan_t, m, params)
        params = result.params
    pts = scan_points(log, beam_poses(log, track, params), params[3:6])
    consecutive = match_pairs(
        pts, inc, i, j, predicted(params, track, log.scan_t, i, j), progress, "Censi et al. on consecutive scans"
    )
    censi = closed_form(track, log.scan_t, consecutive) if len(consecutive.i) >= 10 else np.full(7, np.nan)
    rn = range_noise(log.ranges_mm, log.scan.angles(log.beams))
    return WheelLidarResult(result, censi, rn, track, consecutive, tuple(notes))


def raise_too_few(log: Lidar2DLog, matched: int, tried: int) -> None:
    if tried == 0:
        raise LogFormatError(
            f"the robot hardly moved: no two scans are {KEYFRAME_MM:g} mm or {math.degrees(KEYFRAME_RAD):.0f} "
            "degrees apart.",
            file=log.source,
            field="wheels",
            fix="record the robot driving and turning (both ways) for a few minutes.",
        )
    raise LogFormatError(
        f"only {matched} of {tried} scan pairs could be matched: the scans do not see enough of the same walls.",
        file=log.source,
        field="scans.csv",
        fix="record in a room with walls and furniture within the lidar's range, at its full rate, while the "
        "robot moves slowly.",
    )


# --- intervals given, as Censi et al.'s tool holds them ---
@dataclass(frozen=True, eq=False)
class IntervalsResult:
    fit: WheelLidarFit  # the delay held at 0: intervals come without a clock to shift
    closed_form: np.ndarray  # Censi et al.'s answer on the same intervals
    notes: tuple[str, ...]


def intervals_track(log: IntervalsLog) -> tuple[WheelTrack, np.ndarray, Matches]:
    """The intervals laid end to end: each wheel turns its velocity times T within its own interval (an arc, as
    Censi et al. model it), and the scan matcher's displacement links the interval's two ends."""
    t = np.concatenate([[0.0], np.cumsum(log.t_s)])
    phi = np.vstack([[0.0, 0.0], np.cumsum(log.phi_rad_s * log.t_s[:, None], axis=0)])
    k = np.arange(log.n)
    s = from_rep103(log.sm_m * np.array([1000.0, 1000.0, 1.0]))  # REP 103 metres -> sensact's mm
    return WheelTrack(t, phi, False), t, Matches(k, k + 1, s, log.n)


def learn_intervals(log: IntervalsLog) -> IntervalsResult:
    """Censi et al.'s closed form on the given intervals, then the maximum-likelihood fit from it (the same as
    the scan route's after its matching: the noise's growth with distance and turn, outliers set aside)."""
    track, t, m = intervals_track(log)
    track, start, notes = _closed_form_start(track, t, m)
    if start is None:
        turned = float(np.abs(m.s[:, 2]).sum())
        raise LogFormatError(
            f"the scan matcher turned {turned:.2g} rad in all and the wheels do not say how: the radii and the axle "
            "show only in turns.",
            file=log.source,
            field="phi_l, phi_r",
            fix="give intervals of the robot turning both ways as well as driving (and phi_l, phi_r in rad/s).",
        )
    return IntervalsResult(fit(track, t, m, start, hold_delay=True), start, tuple(notes))
