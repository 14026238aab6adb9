"""The outdoor robot's calibration (docs/inertial.md): wheel odometry, an IMU and GNSS, learned from one log with
no ground truth.

1. The IMU's mount: roll and pitch from gravity in the accelerations, yaw from the robot's own accelerations
   (speeding up, and a turn's pull toward its centre) as the odometry and the gyro predict them, in one complex
   linear regression that also takes up the accelerometer's bias and its offset from the centre of turning.
2. The IMU's clock: the lag that best lines the gyro's turn rate up with the odometry's.
3. EM over the path (sec. 4.1, with the odometry as the action model and the gyro and GNSS as sensors): the
   E-step is ``core.inertial_smoother`` (an EKF and RTS smoother with the constant parameters in the state),
   the M-step sets each noise from its expected squared residual (eqs. 4.25-4.28's pattern) and GNSS's inlier
   share as a two-component mixture (inliers, outliers), until the likelihood stops rising.

Without GNSS, only the product of the turn gain and the gyro's scale is told (the gyro's scale is fixed at 1
and the turn gain carries it); the forward gain, the lever arm and the heading need fixes (None).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from sensact.core import inertial_smoother as ks
from sensact.core.pose_models import rpy_matrix
from sensact.logs.inertial_log import InertialLog
from sensact.progress import Progress

STEP_S = 1.0  # the E-step's grid: long enough that the odometry's own jitter hardly biases the turn gain
# (an error in what is regressed on shrinks the slope by its share of the variance, which falls as 1 / step)
BIN_S = 0.2  # for the mount's regression
ACCEL_BIAS_M_S2 = 0.05  # a MEMS accelerometer's bias (1 sd): indistinguishable from a tilt of the mount
MAX_LAG_S = 1.0  # the IMU's clock is searched within this of the odometry's
SEGMENTS = 10  # the jackknife's, for the mount's and the clock's error bars
MAX_ITERATIONS = 40
TOLERANCE = 1.0  # a rise in the log-likelihood (nats) below which EM has stopped learning anything
G = 9.80665


@dataclass(frozen=True)
class Estimate:
    value: float | None
    sd: float | None


@dataclass(frozen=True, eq=False)
class InertialResult:
    """Every learned number (REP 103, SI but the lever arm and GNSS sigma in mm, as the JSON names them), the
    bias's path, the smoothed path and each sensor's normalized residuals, and how EM went."""

    estimates: dict[str, Estimate]
    t_s: np.ndarray  # the grid's instants (the state's), s on the odometry's clock
    bias_rad_s: np.ndarray  # (T,) the gyro's bias during each step
    bias_sd_rad_s: np.ndarray
    path_enu_m: np.ndarray  # (T+1, 2) base_link (east, north) m; (odometry frame, rotated by the heading) w/o GNSS
    gnss_t: np.ndarray  # the fixes used
    gnss_enu_m: np.ndarray
    gnss_inlier: np.ndarray  # each fix's inlier probability
    gyro_z: np.ndarray  # (T,) the filter's innovations in their sd, N(0, 1) where the model holds
    gnss_z: np.ndarray  # (K, 2) whitened
    loglik: tuple[float, ...]
    iterations: int
    converged: bool
    filter_ok: bool
    distance_m: float
    turn_left_rad: float
    turn_right_rad: float
    has_gnss: bool
    noise: np.ndarray  # the E-step's q, in core.inertial_smoother's units


# ---------------------------------------------------------------- the mount and the clock


def _bin_means(t: np.ndarray, x: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Mean of ``x`` (rows at ``t``) in each bin; NaN for an empty bin."""
    idx = np.searchsorted(edges, t, side="right") - 1
    nb = edges.size - 1
    keep = (idx >= 0) & (idx < nb)
    x2 = x.reshape(len(x), -1)[keep]
    cnt = np.bincount(idx[keep], minlength=nb).astype(float)
    out = np.stack([np.bincount(idx[keep], weights=x2[:, j], minlength=nb) for j in range(x2.shape[1])], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = out / cnt[:, None]
    return out.reshape((nb, *x.shape[1:]))


def tilt_rpy(u: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (URDF rpy) of a mount whose base z axis, in the IMU's axes, is ``u`` (the third row of
    Rz(yaw) Ry(pitch) Rx(roll) is (-sin p, cos p sin r, cos p cos r))."""
    u = u / np.linalg.norm(u)
    return float(np.arctan2(u[1], u[2])), float(np.arcsin(np.clip(-u[0], -1, 1)))


def level(roll: float, pitch: float) -> np.ndarray:
    """Ry(pitch) Rx(roll): the IMU's vectors into a frame with base_link's z and the mount's yaw left."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    return np.array([[cp, sp * sr, sp * cr], [0.0, cr, -sr], [-sp, cp * sr, cp * cr]])


@dataclass(frozen=True)
class MountFit:
    roll: float
    pitch: float
    yaw: float
    explained: float  # share of the horizontal accelerations' variance the regression explains


def _mount_on(
    acc: np.ndarray,
    gyro: np.ndarray,
    gyro_dot: np.ndarray,
    v: np.ndarray,
    v_dot: np.ndarray,
    w_odom: np.ndarray,
    up: np.ndarray | None = None,
) -> MountFit | None:
    """The mount from binned accelerations, gyro rates and odometry speeds and turn rates (rows: bins, all
    finite; the derivatives taken on the whole run, so that a jackknife's deleted span leaves no false jump).
    The regression's columns: the odometry's acceleration forward plus i times the turn's pull (with
    the gyro's rate, its bias taken where the robot stands still), the IMU's offset from the centre of turning
    (w^2 and dw/dt), the accelerometer's bias, and v (what is left of the gyro's bias in the pull). ``up``
    (rows: bins), the IMU's own say of which way is up, where its accelerations carry no gravity."""
    if len(acc) < 20:
        return None
    u = acc.mean(axis=0) if up is None else up.mean(axis=0)
    roll, pitch, yaw = *tilt_rpy(u), 0.0
    explained = 0.0
    for _ in range(3):
        L = level(roll, pitch)
        lev = acc @ L.T
        w = gyro @ L[2]
        still = (np.abs(v) < 1e-3) & (np.abs(w_odom) < 1e-3)
        w = w - (np.median(w[still]) if still.sum() >= 5 else np.polyfit(w_odom, w, 1)[1])
        f = v_dot + 1j * v * w  # the base's horizontal acceleration, forward + i left
        h = lev[:, 0] + 1j * lev[:, 1]
        A = np.column_stack([f, w * w, gyro_dot @ L[2], np.ones(len(f)), 1j * v])
        coef, *_ = np.linalg.lstsq(A, h, rcond=None)
        yaw = float(-np.angle(coef[0]))
        resid = h - A @ coef
        explained = float(1 - np.var(resid) / max(np.var(h), 1e-30))
        # gravity without the mean of what the robot's own motion adds, in the IMU's axes
        R = rpy_matrix(roll, pitch, yaw)
        motion = np.column_stack(
            [
                (A[:, :3] @ coef[:3] * np.exp(1j * yaw)).real,
                (A[:, :3] @ coef[:3] * np.exp(1j * yaw)).imag,
                np.zeros(len(f)),
            ]
        )
        if up is None:
            u = (acc - motion @ R).mean(axis=0)
            roll, pitch = tilt_rpy(u)
    return MountFit(roll, pitch, yaw, explained)


def _jackknife(values: list[np.ndarray]) -> np.ndarray:
    v = np.array(values)
    n = len(v)
    return np.sqrt((n - 1) / n * ((v - v.mean(axis=0)) ** 2).sum(axis=0))


def _angle_jackknife(full: float, parts: list[float]) -> float:
    d = np.angle(np.exp(1j * (np.array(parts) - full)))
    n = len(d)
    return float(np.sqrt((n - 1) / n * ((d - d.mean()) ** 2).sum()))


def carries_gravity(log: InertialLog) -> bool:
    """Whether the accelerations average gravity's size (REP 145's specific force, in m/s^2)."""
    return 0.5 * G < float(np.linalg.norm(np.nanmean(log.accel_m_s2, axis=0))) < 1.5 * G


def _up_from_orientation(log: InertialLog) -> np.ndarray:
    """Up in the IMU's axes at each reading, from the orientation it reports (NaN where none)."""
    from scipy.spatial.transform import Rotation

    q = log.imu_orientation_xyzw
    up = np.full((log.imu_t.size, 3), np.nan)
    if q is not None:
        said = np.isfinite(q).all(axis=1)
        up[said] = Rotation.from_quat(q[said]).as_matrix()[:, 2, :]  # the levelled frame's z in the IMU's axes
    return up


def fit_mount(log: InertialLog, time_offset_s: float = 0.0) -> tuple[MountFit | None, np.ndarray]:
    """The IMU's orientation on the robot and its sd (roll, pitch, yaw), a segment jackknife with the
    accelerometer's bias (a tilt in disguise) carried through the URDF angles (``tilt_sd``). The IMU's
    readings are put on the odometry's clock first (``time_offset_s``): the yaw comes from lining their
    accelerations up with the odometry's, and a lag between them turns the fit."""
    imu_t = log.imu_t - time_offset_s
    t0, t1 = max(log.odom_t[0], imu_t[0]), min(log.odom_t[-1], imu_t[-1])
    edges = np.arange(t0, t1 + BIN_S, BIN_S)
    acc = _bin_means(imu_t, log.accel_m_s2, edges)
    gyr = _bin_means(imu_t, log.gyro_rad_s, edges)
    v = _bin_means(log.odom_t, log.odom_v_m_s, edges)
    wo = _bin_means(log.odom_t, log.odom_omega_rad_s, edges)
    gyr_dot, v_dot = np.gradient(gyr, BIN_S, axis=0), np.gradient(v, BIN_S)
    ok = np.isfinite(acc).all(axis=1) & np.isfinite(gyr_dot).all(axis=1) & np.isfinite(v_dot) & np.isfinite(wo)
    cols = [acc[ok], gyr[ok], gyr_dot[ok], v[ok], v_dot[ok], wo[ok]]
    if not carries_gravity(log):  # the driver took gravity out: up from the IMU's orientation
        up = _bin_means(imu_t, _up_from_orientation(log), edges)
        ok_up = np.isfinite(up).all(axis=1)[ok]
        cols = [c[ok_up] for c in cols] + [up[ok][ok_up]]
    full = _mount_on(*cols)
    if full is None:
        return None, np.full(3, np.nan)
    parts = []
    for seg in np.array_split(np.arange(len(cols[0])), SEGMENTS):
        keep = np.ones(len(cols[0]), bool)
        keep[seg] = False
        m = _mount_on(*(c[keep] for c in cols))
        if m is not None:
            parts.append(m)
    jack = np.array(
        [_angle_jackknife(getattr(full, a), [getattr(p, a) for p in parts]) for a in ("roll", "pitch", "yaw")]
    )
    return full, np.hypot(jack, tilt_sd(full))


def tilt_sd(m: MountFit) -> np.ndarray:
    """Roll's, pitch's and yaw's sd from the accelerometer's bias (a tilt in disguise: up off by ACCEL_BIAS_M_S2
    / G about either of the base's level axes), through the URDF angles: near a pitch of 90 degrees roll and
    yaw turn about nearly one axis, and a small tilt moves each by far more than itself."""
    from scipy.spatial.transform import Rotation

    R = Rotation.from_matrix(rpy_matrix(m.roll, m.pitch, m.yaw))
    rpy = np.array([m.roll, m.pitch, m.yaw])
    h = 1e-4
    var = np.zeros(3)
    for axis in np.eye(3)[:2]:
        moved = (Rotation.from_rotvec(h * axis) * R).as_euler("xyz")  # the base's axes: URDF's extrinsic rpy
        var += (np.angle(np.exp(1j * (moved - rpy))) / h) ** 2
    return ACCEL_BIAS_M_S2 / G * np.sqrt(var)


LAG_WINDOW_S = 0.05
GOLDEN = (np.sqrt(5) - 1) / 2


def _lag(t: np.ndarray, ao: np.ndarray, gt: np.ndarray, gc: np.ndarray) -> float:
    """The lag (s) that best lines the gyro (its integral ``gc`` at ``gt``, the IMU's clock) up with the
    odometry (its turn ``ao`` over each window from ``t``): least squares of the gyro's turn over
    [t + lag, t + lag + w] on a x the odometry's + b, coarse on a 5 ms grid, then Brent's method. Turns over
    windows, not rates at instants: a noisy rate interpolated between samples is less noisy midway, and the
    fit would lean toward half a sample. (A cross-correlation's peak is as broad as the robot's turns are slow,
    and a parabola through it leans toward its grid.)"""
    from scipy.optimize import minimize_scalar

    A = np.column_stack([ao, np.ones_like(ao)])

    def sse(lag: float) -> float:
        y = np.interp(t + lag + LAG_WINDOW_S, gt, gc) - np.interp(t + lag, gt, gc)
        coef, res, *_ = np.linalg.lstsq(A, y, rcond=None)
        return float(res[0]) if res.size else float(np.sum((y - A @ coef) ** 2))

    grid = np.arange(-MAX_LAG_S, MAX_LAG_S + 1e-9, 0.005)
    k = int(np.argmin([sse(g) for g in grid]))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    return float(minimize_scalar(sse, bounds=(lo, hi), method="bounded", options={"xatol": 1e-5}).x)


def fit_time_offset(log: InertialLog, u: np.ndarray) -> tuple[float, float]:
    """t_imu - t_odom for one instant (add it to the odometry's stamps to read the IMU's clock), and its sd."""
    t0, t1 = max(log.odom_t[0], log.imu_t[0]) + MAX_LAG_S, min(log.odom_t[-1], log.imu_t[-1]) - MAX_LAG_S
    # windows start at every phase of the IMU's and the odometry's samples (a golden-ratio sequence): a turn
    # read between samples is interpolated, hence less noisy, and windows all in one phase would pull the
    # fit half a sample off the truth
    k = np.arange(int((t1 - t0) / LAG_WINDOW_S))
    t = t0 + LAG_WINDOW_S * (k + np.modf(k * GOLDEN)[0])
    co = _cumulative(log.odom_t, log.odom_omega_rad_s)
    ao = np.interp(t + LAG_WINDOW_S, log.odom_t, co) - np.interp(t, log.odom_t, co)
    gc = _cumulative(log.imu_t, log.gyro_rad_s @ u)
    lag = _lag(t, ao, log.imu_t, gc)
    segments = np.array_split(np.arange(t.size), SEGMENTS)
    parts = [_lag(np.delete(t, seg), np.delete(ao, seg), log.imu_t, gc) for seg in segments]
    return lag, max(float(_jackknife(parts)), _lag_profile_sd(t, ao, log.imu_t, gc, lag))


def _lag_profile_sd(t: np.ndarray, ao: np.ndarray, gt: np.ndarray, gc: np.ndarray, lag: float) -> float:
    """The lag's sd from the least squares' rise around it (a parabola over +-15 ms), the noise taken from the
    residuals with their correlation between neighbouring windows. A floor under the jackknife, whose
    replicates on a short log all stop at one end of the flat bottom. (The slope of each window's turn in the
    lag is no use here: over a few ms it is the gyro's noise, not the robot's turning.)"""
    A = np.column_stack([ao, np.ones_like(ao)])

    def residual(shift: float) -> np.ndarray:
        y = np.interp(t + shift + LAG_WINDOW_S, gt, gc) - np.interp(t + shift, gt, gc)
        return y - A @ np.linalg.lstsq(A, y, rcond=None)[0]

    shifts = lag + np.linspace(-0.015, 0.015, 7)
    curvature = 2 * np.polyfit(shifts - lag, [np.sum(residual(s) ** 2) for s in shifts], 2)[0]
    r = residual(lag)
    var = np.mean(r**2)
    rho = [np.mean(r[k:] * r[:-k]) / var for k in range(1, 6)]
    long_run = var * max(1.0, 1 + 2 * float(np.sum(rho)))
    return float(np.sqrt(2 * long_run / curvature)) if curvature > 0 else float("inf")


def gyro_follows_odometry(log: InertialLog) -> float | None:
    """The largest correlation of any of the gyro's axes with the odometry's turn rate, in one-second bins;
    None where the odometry hardly turns (a half turn in all), which says nothing of the gyro."""
    t0, t1 = max(log.odom_t[0], log.imu_t[0]), min(log.odom_t[-1], log.imu_t[-1])
    edges = np.arange(t0, t1 + 1.0, 1.0)
    if edges.size < 4:
        return None
    wo = _bin_means(log.odom_t, log.odom_omega_rad_s, edges)
    wg = _bin_means(log.imu_t, log.gyro_rad_s, edges)
    ok = np.isfinite(wo) & np.isfinite(wg).all(axis=1)
    wo, wg = wo[ok], wg[ok]
    if np.sum(np.abs(wo)) < np.pi or np.std(wo) == 0:
        return None
    c = [abs(np.corrcoef(wo, wg[:, i])[0, 1]) if np.std(wg[:, i]) > 0 else 0.0 for i in range(3)]
    return float(np.nanmax(c))


# ---------------------------------------------------------------- the path


@dataclass(frozen=True, eq=False)
class Steps:
    """The E-step's grid: each step's span, odometry travel (mm) and turn (rad), the gyro's turn (rad), and the
    odometry's pieces within it at its own rate (``sub_d`` mm travelled, ``sub_a`` rad turned from the step's
    start at each piece's middle; step k's are ``sub_ptr[k]:sub_ptr[k+1]``); and each fix (sensact's frame, mm:
    x east, y north) with the step it falls in and the odometry's pieces from that step's start to it."""

    t: np.ndarray  # (T+1,)
    dt: np.ndarray
    d: np.ndarray
    a: np.ndarray
    gz: np.ndarray
    sub_ptr: np.ndarray
    sub_d: np.ndarray
    sub_a: np.ndarray
    fix_step: np.ndarray  # (K,) int64, sorted
    fix_ptr: np.ndarray
    fix_sub_d: np.ndarray
    fix_sub_a: np.ndarray
    fix_dp: np.ndarray  # the travel to the fix (mm)
    fix_ap: np.ndarray  # the turn to the fix (rad)
    fix_xy: np.ndarray  # (K, 2)
    fix_row: np.ndarray  # the fix's row in the log

    @property
    def n_fixes(self) -> int:
        return int(self.fix_step.size)

    def pieces(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        return self.sub_d[self.sub_ptr[k] : self.sub_ptr[k + 1]], self.sub_a[self.sub_ptr[k] : self.sub_ptr[k + 1]]

    def fix_pieces(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self.fix_ptr[j], self.fix_ptr[j + 1]
        return self.fix_sub_d[lo:hi], self.fix_sub_a[lo:hi]


def _cumulative(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum((x[1:] + x[:-1]) / 2 * np.diff(t))])


def _pieces(odom_t: np.ndarray, cd: np.ndarray, ca: np.ndarray, starts: np.ndarray, ends: np.ndarray):
    """The odometry's pieces over each span ``[starts[i], ends[i]]``: cut at its own rows, travel (mm) and
    the turn from the span's start at each piece's middle, and that middle's time. CSR: (ptr, d, a, t)."""
    ptr, ds, As, mids = [0], [], [], []
    for lo, hi in zip(starts.tolist(), ends.tolist(), strict=True):
        inner = odom_t[(odom_t > lo) & (odom_t < hi)]
        cuts = np.concatenate([[lo], inner, [hi]])
        d_cut = np.interp(cuts, odom_t, cd)
        a_cut = np.interp(cuts, odom_t, ca) - np.interp(lo, odom_t, ca)
        ds.append(np.diff(d_cut))
        As.append(0.5 * (a_cut[1:] + a_cut[:-1]))
        mids.append(0.5 * (cuts[1:] + cuts[:-1]))
        ptr.append(ptr[-1] + cuts.size - 1)
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros(0)  # noqa: E731
    return np.asarray(ptr, dtype=np.int64), cat(ds), cat(As), cat(mids)


def _shaped(
    t_cuts: np.ndarray, starts: np.ndarray, ptr: np.ndarray, a_span: np.ndarray, span_t: tuple, gyro: tuple, bias: float
) -> np.ndarray:
    """The turn from each span's start at each piece's middle as the gyro shapes it: the odometry's turn over
    the whole step, shared out as the gyro (bias taken off) turned. The odometry's reported rate is noisy at
    its own rate, and a heading regressed on a noisy turn is a turn gain shrunk toward 0 (errors in variables);
    the gyro's shape within a second is clean."""
    gt, gc = gyro
    g = lambda x: np.interp(x, gt, gc) - bias * x  # noqa: E731
    lo, hi = span_t
    total = g(hi) - g(lo)
    out = np.full(ptr[-1], np.nan)  # NaN: the gyro hardly turned, and the odometry's own shape stays
    for i in range(lo.size):
        sl = slice(ptr[i], ptr[i + 1])
        frac = (g(t_cuts[sl]) - g(lo[i])) / total[i] if abs(total[i]) > 1e-3 else None
        if frac is not None:
            out[sl] = a_span[i] * frac
    return out


def make_steps(log: InertialLog, u: np.ndarray, time_offset_s: float, bias: float | None = None) -> Steps:
    """The grid; with ``bias`` (the gyro's, a first guess), the turns within each step and to each fix shaped by
    the gyro (``_shaped``), else by the odometry's own report."""
    imu_t = log.imu_t - time_offset_s  # on the odometry's clock
    t0, t1 = max(log.odom_t[0], imu_t[0]), min(log.odom_t[-1], imu_t[-1])
    n = max(1, int(np.floor((t1 - t0) / STEP_S)))
    t = t0 + np.arange(n + 1) * ((t1 - t0) / n)
    cd = _cumulative(log.odom_t, log.odom_v_m_s) * 1000.0
    ca = _cumulative(log.odom_t, log.odom_omega_rad_s)
    od, oa = np.interp(t, log.odom_t, cd), np.interp(t, log.odom_t, ca)
    gi = np.interp(t, imu_t, _cumulative(imu_t, log.gyro_rad_s @ u))
    rows = np.flatnonzero((log.gnss_t >= t0) & (log.gnss_t < t[-1]))
    tf = log.gnss_t[rows]
    k = np.clip(np.searchsorted(t, tf, side="right") - 1, 0, n - 1)
    sub_ptr, sub_d, sub_a, sub_mid = _pieces(log.odom_t, cd, ca, t[:-1], t[1:])
    fix_ptr, fix_d, fix_a, fix_mid = _pieces(log.odom_t, cd, ca, t[k], tf)
    fix_ap = np.interp(tf, log.odom_t, ca) - oa[k]
    if bias is not None:
        gyro = (imu_t, _cumulative(imu_t, log.gyro_rad_s @ u))
        a = np.diff(oa)
        shaped = _shaped(sub_mid, t[:-1], sub_ptr, a, (t[:-1], t[1:]), gyro, bias)
        sub_a = np.where(np.isnan(shaped), sub_a, shaped) if shaped.size else sub_a
        ends = _shaped(tf, t[k], np.arange(tf.size + 1), a[k], (t[k], t[k + 1]), gyro, bias)
        fix_ap = np.where(np.isnan(ends), fix_ap, ends) if ends.size else fix_ap
        shaped = _shaped(fix_mid, t[k], fix_ptr, a[k], (t[k], t[k + 1]), gyro, bias)
        fix_a = np.where(np.isnan(shaped), fix_a, shaped) if shaped.size else fix_a
    return Steps(
        t,
        np.diff(t),
        np.diff(od),
        np.diff(oa),
        np.diff(gi),
        sub_ptr,
        sub_d,
        sub_a,
        k.astype(np.int64),
        fix_ptr,
        fix_d,
        fix_a,
        np.interp(tf, log.odom_t, cd) - od[k],
        fix_ap,
        log.gnss_enu_m[rows, :2] * 1000.0,
        rows,
    )


def _umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, float, np.ndarray]:
    """The rotation angle, scale and translation taking points ``src`` onto ``dst`` (least squares)."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - ms, dst - md
    cov = b.T @ a / len(a)
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(2)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[1, 1] = -1
    R = U @ S @ Vt
    var = (a**2).sum() / len(a)
    scale = float(np.trace(np.diag(D) @ S) / var) if var > 0 else 1.0
    return float(np.arctan2(R[1, 0], R[0, 0])), scale, md - scale * R @ ms


START_TRAVEL_MM = 50_000.0  # the fixes of the first 50 m (or the first ten) place the start


def _start(steps: Steps, has_gnss: bool) -> np.ndarray:
    """The first guess: the product of the turn gain and the gyro's scale and the mean bias by least squares
    (the odometry regressed on the gyro, whose noise is small); with GNSS, the start's position and heading
    and the forward gain from the first fixes against the path the odometry and the gyro dead-reckon."""
    A = np.column_stack([steps.gz, -steps.dt])  # a = c gz - c b dt
    (c, cb), *_ = np.linalg.lstsq(A, steps.a, rcond=None)
    product = 1.0 / c if abs(c) > 1e-6 else 1.0
    bias = cb / c if abs(c) > 1e-6 else 0.0
    m0 = np.zeros(ks.N_STATE)
    m0[ks.B] = m0[ks.CB] = bias
    m0[ks.GF] = 1.0
    m0[ks.GT] = product
    m0[ks.S] = 1.0
    if has_gnss:
        heading = np.concatenate([[0.0], np.cumsum(steps.gz - bias * steps.dt)])
        mid = heading[:-1] + 0.5 * np.diff(heading)
        xy = np.column_stack(
            [
                np.concatenate([[0.0], np.cumsum(-steps.d * np.sin(mid))]),
                np.concatenate([[0.0], np.cumsum(steps.d * np.cos(mid))]),
            ]
        )
        k = steps.fix_step
        src = xy[k] + steps.fix_dp[:, None] * np.column_stack([-np.sin(heading[k]), np.cos(heading[k])])
        travelled = np.concatenate([[0.0], np.cumsum(np.abs(steps.d))])[k]
        use = travelled <= max(START_TRAVEL_MM, travelled[min(len(k) - 1, 10)])
        src, dst = src[use], steps.fix_xy[use]
        keep = np.ones(len(src), bool)
        for _ in range(3):
            ang, scale, tr = _umeyama(src[keep], dst[keep])
            R = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
            err = np.linalg.norm(dst - (scale * src @ R.T + tr), axis=1)
            keep = err <= max(3 * np.median(err), 1.0)
        m0[ks.X] = m0[ks.CX] = tr[0]
        m0[ks.Y] = m0[ks.CY] = tr[1]
        m0[ks.TH] = m0[ks.CTH] = ang
        m0[ks.GF] = float(np.clip(scale, 0.5, 2.0)) if np.ptp(src, axis=0).max() > 5000 else 1.0
    return m0


PRIOR_WIDTH = 10.0  # after EM's first pass, the start's spread is this many times its posterior sd


def _prior(has_gnss: bool, posterior_sd: np.ndarray | None = None, *, settling: bool = False) -> np.ndarray:
    """The initial state's covariance: broad, or (``posterior_sd``, from the previous pass) PRIOR_WIDTH times
    the posterior's sd, no broader: still a tenth as informative as the log, and the smoother's covariances
    stay within the float's reach (a broad prior on states the fixes pin to a millimetre cancels 12 digits).
    ``settling``: the gyro's scale and the lever arm held (EM's first passes find the path, its start and the
    gains first: with metre-grade fixes a filter that also frees a lever arm two metres wide can turn the path
    around before the fixes have said where it goes)."""
    sd = np.zeros(ks.N_STATE)
    sd[[ks.X, ks.Y]] = 5000.0  # without fixes the path's place and heading are nobody's: any spread will do
    sd[ks.TH] = 0.3
    sd[ks.B] = 0.02
    sd[ks.GT] = 0.2
    if has_gnss:
        sd[ks.GF] = 0.2
        sd[ks.S] = 0.0 if settling else 0.1
        sd[[ks.LF, ks.LL]] = 0.0 if settling else 2000.0
    if posterior_sd is not None:
        sd = np.where(sd > 0, np.minimum(sd, np.maximum(PRIOR_WIDTH * posterior_sd, 1e-3 * sd)), 0.0)
    P0 = np.diag(sd**2)
    for c, o in ((ks.CX, ks.X), (ks.CY, ks.Y), (ks.CTH, ks.TH), (ks.CB, ks.B)):
        P0[c, :] = P0[o, :]
        P0[:, c] = P0[:, o]
        P0[c, c] = P0[o, o]
    return P0


# ---------------------------------------------------------------- the M-step


def _expected_sq(r: np.ndarray, Jr: np.ndarray, P: np.ndarray) -> np.ndarray:
    """E[r^2] of a linearized residual: r(mean)^2 + J P J^T, per row (``Jr``: (T, n), ``P``: (T, n, n))."""
    return r**2 + np.einsum("ti,tij,tj->t", Jr, P, Jr)


def _variance_components(e2: np.ndarray, units: list[np.ndarray], old: list[float]) -> list[float]:
    """Variances ``s_j`` with E[r_k^2] = sum_j s_j u_jk: one step of the MM algorithm for variance components
    (Zhou, Hu and Lange 2019), s_j <- s_j sqrt(sum_k u_jk e_k / var_k^2 / sum_k u_jk / var_k), which never
    lowers the likelihood, from ``old``; rows with no unit at all are left out."""
    U = np.array(units)
    use = U.sum(axis=0) > 0
    e2, U = np.maximum(e2[use], 0.0), U[:, use]
    var = np.asarray(old) @ U
    out = []
    for s, u in zip(old, U, strict=True):
        den = np.sum(u / var)
        out.append(max(float(s * np.sqrt(np.sum(u * e2 / var**2) / den)), 1e-30) if den > 0 else s)
    return out


def _travel_residuals(steps: Steps, m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each step's travel residual (state after it minus the arc from its clone), (T, 2), and its Jacobian in the
    state after the step, (T, 2, n): the clone holds the pose before."""
    T, n = steps.dt.size, ks.N_STATE
    r = np.zeros((T, 2))
    Jr = np.zeros((T, 2, n))
    J = np.zeros((3, n))
    before = m.copy()
    before[:, [ks.X, ks.Y, ks.TH]] = m[:, [ks.CX, ks.CY, ks.CTH]]
    for k in range(T):
        x, y, _ = ks.odometry_move(before[k], *steps.pieces(k), steps.a[k], J)
        r[k] = m[k, ks.X] - x, m[k, ks.Y] - y
        # the arc's Jacobian is in the pose before: the clones' columns
        Jr[k, 0, ks.X] = Jr[k, 1, ks.Y] = 1.0
        for src, dst in ((ks.X, ks.CX), (ks.Y, ks.CY), (ks.TH, ks.CTH)):
            Jr[k, :, dst] -= J[:2, src]
        for col in (ks.GF, ks.GT):
            Jr[k, :, col] -= J[:2, col]
    return r, Jr


def _m_step(
    steps: Steps, m: np.ndarray, P: np.ndarray, q: np.ndarray, has_gnss: bool, gnss: GnssMix
) -> tuple[np.ndarray, GnssMix]:
    """New noise from the smoothed states ``m``, ``P`` (all T+1 rows; row k+1 holds step k's clones)."""
    q = q.copy()
    T = steps.dt.size
    n = ks.N_STATE
    d, a, dt = steps.d, steps.a, steps.dt
    m1, P1 = m[1:], P[1:]
    # the turn: theta - theta_prev - GT a
    J = np.zeros((T, n))
    J[:, ks.TH], J[:, ks.CTH], J[:, ks.GT] = 1.0, -1.0, -a
    r = m1[:, ks.TH] - m1[:, ks.CTH] - m1[:, ks.GT] * a
    moving = np.where((np.abs(d) > 1e-9) | (np.abs(a) > 1e-12), dt, 0.0)
    turn = [ks.Q_TURN, ks.Q_TURN_D, ks.Q_TURN_T]
    q[turn] = _variance_components(
        _expected_sq(r, J, P1) - ks.FLOOR_RAD2 * dt, [np.abs(a), np.abs(d), moving], list(q[turn])
    )
    if has_gnss:
        rxy, Jxy = _travel_residuals(steps, m1)
        mid = m1[:, ks.CTH] + 0.5 * m1[:, ks.GT] * a
        sn, cs = np.sin(mid), np.cos(mid)
        for idx, (ux, uy) in (([ks.Q_ALONG, ks.Q_ALONG_T], (-sn, cs)), ([ks.Q_ACROSS], (cs, sn))):
            rr = ux * rxy[:, 0] + uy * rxy[:, 1]
            Jrr = ux[:, None] * Jxy[:, 0] + uy[:, None] * Jxy[:, 1]
            e = _expected_sq(rr, Jrr, P1) - ks.FLOOR_MM2 * dt
            q[idx] = _variance_components(e, [np.abs(d), moving][: len(idx)], list(q[idx]))
    # the bias's walk
    Jb = np.zeros((T, n))
    Jb[:, ks.B], Jb[:, ks.CB] = 1.0, -1.0
    q[ks.Q_BIAS] = max(float(np.sum(_expected_sq(m1[:, ks.B] - m1[:, ks.CB], Jb, P1)) / np.sum(dt)), 1e-20)
    # the gyro's white noise is measured, not fitted (``gyro_noise_density``)
    if has_gnss:
        gnss = gnss.update(steps, m, P)
        q[ks.R_GNSS], q[ks.R_OUTLIER], q[ks.OUTLIER_SHARE] = gnss.sigma2, gnss.outlier2, 1 - gnss.inlier
    return q, gnss


@dataclass(frozen=True)
class GnssMix:
    """The fixes as a mixture: inliers N(0, sigma2) with share ``inlier``, outliers N(0, outlier2) (mm^2 per
    axis); ``weights``: each fix's inlier probability."""

    sigma2: float
    outlier2: float
    inlier: float
    weights: np.ndarray

    def residuals(self, steps: Steps, m: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each fix's residual (K, 2) from the smoothed states (all T+1 rows), and the trace of its
        covariance (K,)."""
        K = steps.n_fixes
        r = np.zeros((K, 2))
        tr = np.zeros(K)
        H = np.zeros((2, ks.N_STATE))
        for j in range(K):
            k = steps.fix_step[j]
            hx, hy = ks.gnss_model(m[k], *steps.fix_pieces(j), steps.fix_ap[j], H)
            r[j] = steps.fix_xy[j] - (hx, hy)
            tr[j] = max(np.trace(H @ P[k] @ H.T), 0.0)
        return r, tr

    def update(self, steps: Steps, m: np.ndarray, P: np.ndarray) -> GnssMix:
        r, tr = self.residuals(steps, m, P)
        r2 = (r**2).sum(axis=1)
        e2 = r2 + tr

        def log_dens(v: np.ndarray) -> np.ndarray:
            return -0.5 * r2 / v - np.log(v)

        v_in, v_out = self.sigma2 + tr / 2, self.outlier2 + tr / 2
        lin = np.log(self.inlier) + log_dens(v_in)
        lout = np.log(1 - self.inlier) + log_dens(v_out)
        g = 1.0 / (1.0 + np.exp(np.clip(lout - lin, -700, 700)))
        sigma2 = max(float(np.sum(g * e2) / (2 * max(g.sum(), 1e-9))), 1e-6)
        outlier2 = max(float(np.sum((1 - g) * e2) / (2 * max((1 - g).sum(), 1e-9))), 16 * sigma2)
        inlier = float(np.clip(g.mean(), 0.5, 1 - 1e-4))
        return GnssMix(sigma2, outlier2, inlier, g)


# ---------------------------------------------------------------- EM


@dataclass(frozen=True, eq=False)
class Pass:
    """One E-step: the smoothed states (row k: at ``steps.t[k]``), the variance of the bias's integral, the
    log-likelihood, and the last filtered state (the constant parameters' exact posterior)."""

    m: np.ndarray
    P: np.ndarray
    var_bias_sum: float
    loglik: float
    ok: bool
    m_end: np.ndarray
    P_end: np.ndarray


def run_filter(
    steps: Steps, q: np.ndarray, m0: np.ndarray, P0: np.ndarray, use: np.ndarray | None = None, gate: float = 0.0
):
    """``core.inertial_smoother.run_filter`` on ``steps``; ``use``: the fixes used (all by default)."""
    w = np.ones(steps.n_fixes, dtype=np.bool_) if use is None else use
    return ks.run_filter(
        steps.dt, steps.d, steps.a, steps.gz, steps.sub_ptr, steps.sub_d, steps.sub_a, steps.fix_step, steps.fix_ptr,
        steps.fix_sub_d, steps.fix_sub_a, steps.fix_ap, steps.fix_xy, w, q, m0, P0, gate,
    )  # fmt: skip


def e_step(steps: Steps, q: np.ndarray, m0: np.ndarray, P0: np.ndarray, use: np.ndarray | None = None) -> Pass:
    m_f, P_f, m_p, P_p, Fs, ll, _, _, _, _, ok, _ = run_filter(steps, q, m0, P0, use)
    if not ok:
        return Pass(m_f, P_f, np.nan, ll, False, m_f[-1], P_f[-1])
    active = np.flatnonzero(np.diag(P0) > 0)
    active = np.union1d(active, [ks.X, ks.Y, ks.TH, ks.CX, ks.CY, ks.CTH, ks.B, ks.CB]).astype(np.int64)
    m_s, P_s, var_sum = ks.run_smoother(m_f, P_f, m_p, P_p, Fs, active, steps.dt)
    return Pass(m_s, P_s, var_sum, ll, True, m_f[-1], P_f[-1])


def _initial_noise(log: InertialLog, steps: Steps, gyro_noise: float) -> tuple[np.ndarray, GnssMix]:
    q = np.zeros(ks.N_NOISE)
    q[ks.Q_ALONG] = 0.01**2 * 1000.0  # 1 % of the travel over a metre (mm^2 per mm)
    q[ks.Q_ACROSS] = 0.01**2 * 1000.0
    q[ks.Q_TURN] = 0.02**2  # rad^2 per rad
    q[ks.Q_TURN_D] = 0.01**2 / 1000.0  # rad^2 per mm
    q[ks.Q_ALONG_T] = 10.0**2  # mm^2 per s in motion
    q[ks.Q_TURN_T] = 0.01**2  # rad^2 per s in motion
    q[ks.Q_BIAS] = 1e-4**2
    q[ks.R_GYRO] = max(gyro_noise, 1e-5) ** 2
    reported = log.gnss_var_reported_m2[steps.fix_row]
    sig2 = float(np.nanmedian(reported.mean(axis=1))) * 1e6 if np.isfinite(reported).any() else 1e6
    q[ks.R_GNSS], q[ks.R_OUTLIER], q[ks.OUTLIER_SHARE] = sig2, 100 * sig2, 0.05
    return q, GnssMix(sig2, 100 * sig2, 0.95, np.ones(steps.n_fixes))


def _density(w: np.ndarray, rate: float) -> float:
    d2 = np.diff(w, 2)
    mad = 1.4826 * np.median(np.abs(d2 - np.median(d2)))
    return float(np.sqrt(mad**2 / 6 / rate))


def gyro_noise_density(log: InertialLog, u: np.ndarray) -> tuple[float, float]:
    """The gyro's white noise density about base_link's z (rad/s/sqrt(Hz)) in motion, and its sd (a segment
    jackknife): from its second differences, which the robot's smooth motion hardly moves at an IMU's rate:
    var(x[k+1] - 2 x[k] + x[k-1]) = 6 sigma^2 and sigma^2 = N^2 rate (a robust scale, so that a bump is not
    noise). Measured, not fitted: within a step the gyro's noise and the odometry's trade against each other."""
    w = log.gyro_rad_s @ u
    rate = (log.imu_t.size - 1) / max(log.imu_t[-1] - log.imu_t[0], 1e-9)
    full = _density(w, rate)
    parts = [_density(np.delete(w, seg), rate) for seg in np.array_split(np.arange(w.size), SEGMENTS)]
    return full, float(_jackknife(parts))


def accel_noise_density(log: InertialLog) -> tuple[float, float]:
    """The accelerometer's white noise density (m/s^2/sqrt(Hz)) in motion, its three axes' mean, as the gyro's
    (``gyro_noise_density``), and its sd."""

    def of(acc: np.ndarray) -> float:
        return float(np.mean([_density(acc[:, i], log.imu_hz) for i in range(3)]))

    full = of(log.accel_m_s2)
    parts = [of(np.delete(log.accel_m_s2, seg, axis=0)) for seg in np.array_split(np.arange(log.imu_t.size), SEGMENTS)]
    return full, float(_jackknife(parts))


def _without_gnss(log: InertialLog) -> InertialLog:
    return dataclasses.replace(log, gnss_t=np.zeros(0), gnss_enu_m=np.zeros((0, 3)))


PARAMETER_STATES = [ks.GF, ks.GT, ks.S, ks.LF, ks.LL]
GNSS_NOISE = [ks.R_GNSS, ks.R_OUTLIER, ks.OUTLIER_SHARE]  # the mixture's, EM's own M-step
SETTLE = 2  # passes that move only the start, the parameters and the fixes' weights: a first pass far from
# the path (a heading off by a tenth of a radian) would set the noise to its own errors, and EM would take
# dozens of passes to walk it back
MIN_FIXES = 10


def learn_inertial(log: InertialLog, progress: Progress | None = None) -> InertialResult:
    mount, mount_sd = fit_mount(log)
    if mount is None:
        mount = MountFit(0.0, 0.0, 0.0, 0.0)
    u = rpy_matrix(mount.roll, mount.pitch, mount.yaw)[2]  # base z in the IMU's axes: gravity's, clock or not
    offset, offset_sd = fit_time_offset(log, u)
    mount, mount_sd = fit_mount(log, offset)  # the yaw again, the two clocks lined up
    if mount is None:
        mount = MountFit(0.0, 0.0, 0.0, 0.0)
    u = rpy_matrix(mount.roll, mount.pitch, mount.yaw)[2]
    steps = make_steps(log, u, offset)
    has_gnss = steps.n_fixes >= MIN_FIXES
    if not has_gnss:
        steps = make_steps(_without_gnss(log), u, offset)
    m0 = _start(steps, has_gnss)
    steps = make_steps(log if has_gnss else _without_gnss(log), u, offset, bias=float(m0[ks.B]))
    P0 = _prior(has_gnss, settling=True)
    gyro_noise, gyro_noise_sd = gyro_noise_density(log, u)
    q, gnss = _initial_noise(log, steps, gyro_noise)
    lls: list[float] = []
    converged = False
    it = 0
    for it in range(1, MAX_ITERATIONS + 1):
        e = e_step(steps, q, m0, P0)
        if not e.ok:
            break
        lls.append(e.loglik)
        if progress is not None:
            progress("EM over the path", it, MAX_ITERATIONS)
        if it > SETTLE + 1 and abs(lls[-1] - lls[-2]) <= TOLERANCE:
            converged = True
            break
        q_new, gnss = _m_step(steps, e.m, e.P, q, has_gnss, gnss)
        q[GNSS_NOISE] = q_new[GNSS_NOISE]
        if it > SETTLE:
            q = polish_noise(steps, q_new, m0, P0, has_gnss)
        # the initial state's mean is EM's too (the smoothed start); the parameters' is their posterior's
        m0 = e.m[0].copy()
        m0[PARAMETER_STATES] = e.m_end[PARAMETER_STATES]
        if m0[ks.GF] < 0:  # the same path driven backwards, turned round: the odometry's forward is forward
            m0[[ks.GF, ks.LF, ks.LL]] *= -1
            m0[ks.TH] += np.pi
        for c, o in ((ks.CX, ks.X), (ks.CY, ks.Y), (ks.CTH, ks.TH), (ks.CB, ks.B)):
            m0[c] = m0[o]
        sd = np.sqrt(np.maximum(np.diagonal(e.P[0]), 0.0))
        sd[PARAMETER_STATES] = np.sqrt(np.maximum(np.diagonal(e.P_end), 0.0))[PARAMETER_STATES]
        P0 = _prior(has_gnss, None if it < SETTLE else sd, settling=it < SETTLE)
    noise_sd = _noise_sd(steps, q, m0, P0, gnss, e.loglik, has_gnss)
    spread = jackknife(steps, q, m0, P0)
    return _result(
        log, steps, e, q, gnss, lls, it, converged, mount, mount_sd, (offset, offset_sd), gyro_noise_sd, has_gnss,
        noise_sd, m0, P0, spread,
    )  # fmt: skip


CURVATURE_STEP = 0.1  # on the log of a variance
JACKKNIFE_BLOCKS = 20


@dataclass(frozen=True)
class Spread:
    """A delete-a-block jackknife's sd of what EM learned (the constant parameters, the start's heading and
    the bias's mean), the noise held: what the run's own pieces disagree by, model or no model."""

    parameters: np.ndarray  # (N_STATE,), NaN where not a parameter
    heading: float
    bias_mean: float


def jackknife(steps: Steps, q: np.ndarray, m0: np.ndarray, P0: np.ndarray) -> Spread:
    """Each of JACKKNIFE_BLOCKS spans of the run deleted in turn (its gyro and its fixes; the odometry still
    carries the robot through it) and the E-step run again: sd = sqrt((n - 1) / n sum (x_i - mean)^2). A
    posterior sd assumes the noise model is the truth; this one does not, and the larger of the two is
    reported (a sandwich's job, at the price of n E-steps)."""
    edges = np.linspace(0, steps.dt.size, JACKKNIFE_BLOCKS + 1).astype(int)
    params, heads, biases = [], [], []
    for lo, hi in itertools.pairwise(edges):
        gz = steps.gz.copy()
        gz[lo:hi] = np.nan
        use = (steps.fix_step < lo) | (steps.fix_step >= hi)
        e = e_step(dataclasses.replace(steps, gz=gz), q, m0, P0, use)
        if not e.ok:
            continue
        params.append(e.m_end)
        heads.append(e.m[0, ks.TH])
        biases.append(float(np.sum(e.m[1:, ks.CB] * steps.dt) / np.sum(steps.dt)))
    if len(params) < 3:
        return Spread(np.full(ks.N_STATE, np.nan), np.nan, np.nan)
    return Spread(_jackknife(params), float(_jackknife(heads)), float(_jackknife(biases)))


POLISH_ITERATIONS = 20


def _learned_noise(has_gnss: bool) -> list[int]:
    """The noise EM learns (the gyro's is measured, GNSS's comes with its mixture's M-step)."""
    return [ks.Q_TURN, ks.Q_TURN_D, ks.Q_TURN_T, ks.Q_BIAS] + (
        [ks.Q_ALONG, ks.Q_ALONG_T, ks.Q_ACROSS] if has_gnss else []
    )


# the noises EM walks to slowly: the travel's, which the fixes see only in sum, and the bias's walk, which a
# pass moves by half a per cent (the gyro's white noise hides each step's share of it)
TRAVEL_NOISE = [ks.Q_ALONG, ks.Q_ALONG_T, ks.Q_ACROSS]


def polish_noise(steps: Steps, q: np.ndarray, m0: np.ndarray, P0: np.ndarray, has_gnss: bool) -> np.ndarray:
    """The path's noise at the maximum of the filter's log-likelihood (the path and the parameters integrated
    out), by quasi-Newton on the logs of the variances from EM's: EM moves a process noise the fixes see only
    in sum by a few per cent a pass, and would take hundreds of passes to reach where this goes in one."""
    from scipy.optimize import minimize

    idx = [ks.Q_BIAS, *(TRAVEL_NOISE if has_gnss else [])]
    x0 = np.log(q[idx])

    def nll(x: np.ndarray) -> float:
        qq = q.copy()
        qq[idx] = np.exp(x)
        f = run_filter(steps, qq, m0, P0)
        return -f[5] if f[10] and np.isfinite(f[5]) else 1e300

    res = minimize(nll, x0, method="L-BFGS-B", bounds=[(v - 8, v + 8) for v in x0],
                   options={"maxiter": POLISH_ITERATIONS, "eps": 1e-4, "ftol": 1e-9})  # fmt: skip
    out = q.copy()
    if res.fun <= nll(x0):
        out[idx] = np.exp(res.x)
    return out


def _noise_sd(
    steps: Steps, q: np.ndarray, m0: np.ndarray, P0: np.ndarray, gnss: GnssMix, ll: float, has_gnss: bool
) -> np.ndarray:
    """Each learned noise's sd on the log of its variance, from the curvature of the log-likelihood (the
    filter's, the path and the parameters integrated out): 1 / sqrt(-d2 ll / d(log q)^2); NaN where flat."""
    out = np.full(ks.N_NOISE, np.nan)
    learned = [*_learned_noise(has_gnss), *([ks.R_GNSS] if has_gnss else [])]  # the curvature's
    base = run_filter(steps, q, m0, P0)[5]
    for i in learned:
        lls = []
        for sgn in (-1.0, 1.0):
            qq = q.copy()
            qq[i] *= np.exp(sgn * CURVATURE_STEP)
            lls.append(run_filter(steps, qq, m0, P0)[5])
        curv = (lls[0] - 2 * base + lls[1]) / CURVATURE_STEP**2
        if curv < 0:
            out[i] = 1 / np.sqrt(-curv)
    return out


def _result(
    log: InertialLog,
    steps: Steps,
    e: Pass,
    q: np.ndarray,
    gnss: GnssMix,
    lls: list[float],
    it: int,
    converged: bool,
    mount: MountFit,
    mount_sd: np.ndarray,
    offset: tuple[float, float],
    gyro_noise_sd: float,
    has_gnss: bool,
    noise_sd: np.ndarray,
    m0: np.ndarray,
    P0: np.ndarray,
    spread: Spread,
) -> InertialResult:
    m_s, P_s = e.m, e.P
    sd = np.fmax(np.sqrt(np.maximum(np.diagonal(e.P_end), 0.0)), spread.parameters)
    p = e.m_end
    span = float(np.sum(steps.dt))
    bias = m_s[1:, ks.CB]
    est: dict[str, Estimate] = {}

    def put(key: str, value: float | None, s: float | None) -> None:
        est[key] = Estimate(None if value is None else float(value), None if s is None else float(s))

    def noise(i: int, scale: float = 1.0) -> tuple[float, float | None]:
        """sqrt(q_i) and its sd, from the sd of log q_i (half of it, relative, for the square root)."""
        v = float(np.sqrt(q[i] * scale))
        return v, (None if not np.isfinite(noise_sd[i]) else 0.5 * v * float(noise_sd[i]))

    put("odometry.gain_forward", p[ks.GF] if has_gnss else None, sd[ks.GF] if has_gnss else None)
    put("odometry.gain_turn", p[ks.GT], sd[ks.GT])
    put("odometry.noise_forward_m_sqrt_m", *(noise(ks.Q_ALONG, 1e-3) if has_gnss else (None, None)))
    put("odometry.noise_turn_rad_sqrt_rad", *noise(ks.Q_TURN))
    put(
        "imu.gyro.bias_rad_s",
        float(np.sum(bias * steps.dt) / span),
        np.fmax(np.sqrt(max(e.var_bias_sum, 0.0)) / span, spread.bias_mean),
    )
    put("imu.gyro.bias_walk_rad_s_sqrt_s", *noise(ks.Q_BIAS))
    put("imu.gyro.scale", p[ks.S], sd[ks.S] if has_gnss else None)
    put("imu.gyro.noise_rad_s_sqrt_hz", np.sqrt(q[ks.R_GYRO]), gyro_noise_sd)
    put("imu.accel.noise_m_s2_sqrt_hz", *accel_noise_density(log))
    put("imu.time_offset_s", *offset)
    put("imu.mount.roll_rad", mount.roll, mount_sd[0])
    put("imu.mount.pitch_rad", mount.pitch, mount_sd[1])
    put("imu.mount.yaw_rad", mount.yaw, mount_sd[2])
    keys = ("gnss.lever_arm.forward_mm", "gnss.lever_arm.left_mm", "gnss.sigma_mm", "gnss.outlier_share",
            "gnss.covariance_ratio", "gnss.heading_offset_rad")  # fmt: skip
    if has_gnss:
        # the odometry frame's start heading: its first pose's yaw, turned by what it reported until the grid began
        yaw_odom = log.odom_yaw0_rad + float(
            np.interp(steps.t[0], log.odom_t, _cumulative(log.odom_t, log.odom_omega_rad_s))
        )
        heading = float(np.angle(np.exp(1j * (m_s[0][ks.TH] + np.pi / 2 - yaw_odom))))
        sigma = float(np.sqrt(gnss.sigma2))
        sigma_sd = noise(ks.R_GNSS)[1]
        reported = log.gnss_var_reported_m2[steps.fix_row]
        rep = float(np.sqrt(np.nanmedian(reported.mean(axis=1)))) * 1000.0 if np.isfinite(reported).any() else None
        ratio = None if rep is None else rep / sigma
        put(keys[0], p[ks.LF], sd[ks.LF])
        put(keys[1], p[ks.LL], sd[ks.LL])
        put(keys[2], sigma, sigma_sd)
        put(keys[3], 1 - gnss.inlier, np.sqrt(gnss.inlier * (1 - gnss.inlier) / steps.n_fixes))
        put(keys[4], ratio, None if ratio is None or sigma_sd is None else ratio * sigma_sd / sigma)
        put(keys[5], heading, np.fmax(np.sqrt(max(P_s[0][ks.TH, ks.TH], 0.0)), spread.heading))
    else:
        for key in keys:
            put(key, None, None)
    # the filter's one-step-ahead innovations, each in its own sd: N(0, 1) where the model holds
    f = run_filter(steps, q, m0, P0)
    zg = f[6] / np.sqrt(f[7])
    zn = np.zeros((0, 2))
    if has_gnss:
        zn = np.full((steps.n_fixes, 2), np.nan)
        for j, (r, S) in enumerate(zip(f[8], f[9], strict=True)):
            if np.isfinite(S).all() and np.linalg.det(S) > 0:
                zn[j] = np.linalg.solve(np.linalg.cholesky(S), r)
    return InertialResult(
        estimates=est,
        t_s=steps.t,
        bias_rad_s=bias,
        bias_sd_rad_s=np.sqrt(np.maximum(P_s[1:, ks.CB, ks.CB], 0)),
        path_enu_m=m_s[:, [ks.X, ks.Y]] / 1000.0,
        gnss_t=log.gnss_t[steps.fix_row] if has_gnss else np.zeros(0),
        gnss_enu_m=steps.fix_xy / 1000.0 if has_gnss else np.zeros((0, 2)),
        gnss_inlier=gnss.weights if has_gnss else np.zeros(0),
        gyro_z=zg,
        gnss_z=zn,
        loglik=tuple(lls),
        iterations=it,
        converged=converged,
        filter_ok=e.ok,
        distance_m=float(np.sum(np.abs(steps.d))) / 1000.0,
        turn_left_rad=float(np.sum(np.maximum(steps.a * p[ks.GT], 0))),
        turn_right_rad=float(np.sum(np.maximum(-steps.a * p[ks.GT], 0))),
        has_gnss=has_gnss,
        noise=q,
    )
