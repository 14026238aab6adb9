"""Sec. 5.2: the car's motion from consecutive lidar scans, by 2-D ICP (Algorithm 2), and the angle
offset ``C`` from the direction the car moves.

Scans are taken every ``dt`` (0.5 s): all returns of one revolution, at horizontal angle
``theta_r + theta'_l`` in the frame (x_C, y_C), which is the car's frame turned by the unknown ``C``. Points
more than 1 m below the sensor are dropped: the ground's circles move with the car and would pull ICP
toward no motion. ICP matches the scan with fewer points (D1) into the other (D2) with a k-d tree, fits
``(dx, dy, dtheta)`` by linearized least squares around the current estimate, and ignores pairs more
than 7 m apart.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sensact.core.angles import wrap_angle
from sensact.errors import LogFormatError


@dataclass(frozen=True)
class OdometryConfig:
    dt_s: float = 0.5  # sec. 5.4
    drop_below_m: float = 1.0  # sec. 5.2
    outlier_m: float = 7.0  # footnote 3 of ch. 5
    max_iterations: int = 50
    tolerance: float = 1e-5  # stop when the update (m, rad) is this small
    min_speed_m_s: float = 2.0  # footnote 4: only faster motions vote for C
    voxel_m: float = 0.0  # > 0 thins D1 to one point per voxel (speed; the thesis used every point)


@dataclass(frozen=True, eq=False)
class Odometry:
    times_s: np.ndarray  # (K,) start of each interval
    motion: np.ndarray  # (K, 3) m_x, m_y (already turned by -m_theta/2), m_theta, in the (x_C, y_C) frame
    rms_m: np.ndarray  # (K,) ICP's final RMS (eq. 5.2)
    iterations: np.ndarray  # (K,)
    n_points: np.ndarray  # (K + 1,) points per scan


def scan_points(rot_rad, dist, vertical_rad, relative_rad, drop_below_m=1.0) -> np.ndarray:
    """(N, 2) points of one revolution in (x_C, y_C); ``rot_rad`` (F,), ``dist`` (F, n) by laser id."""
    alpha = rot_rad[:, None] + relative_rad[None, :]
    cv, sv = np.cos(vertical_rad), np.sin(vertical_rad)
    keep = (dist > 0) & (dist * sv[None, :] >= -drop_below_m)
    r = (dist * cv[None, :])[keep]
    a = alpha[keep]
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _voxel(points: np.ndarray, size: float) -> np.ndarray:
    if size <= 0 or len(points) == 0:
        return points
    keys = np.floor(points / size).astype(np.int64)
    _, first = np.unique(keys[:, 0] * 1_000_003 + keys[:, 1], return_index=True)
    return points[np.sort(first)]


def icp(d1: np.ndarray, tree2: cKDTree, d2: np.ndarray, init: np.ndarray, cfg: OdometryConfig):
    """Algorithm 2: ``T = (dx, dy, dtheta)`` with ``R(dtheta) p + (dx, dy)`` mapping D1 onto D2."""
    T = np.array(init, dtype=float)
    rms = np.nan
    for it in range(1, cfg.max_iterations + 1):
        c, s = np.cos(T[2]), np.sin(T[2])
        rp = d1 @ np.array([[c, s], [-s, c]])  # R(dtheta) p for every row
        p = rp + T[:2]
        dist, idx = tree2.query(p, distance_upper_bound=cfg.outlier_m)
        ok = np.isfinite(dist)
        if ok.sum() < 10:
            return T, np.inf, it
        q = d2[idx[ok]]
        res = (q - p[ok]).reshape(-1)
        J = np.zeros((2 * ok.sum(), 3))
        J[0::2, 0] = 1.0
        J[1::2, 1] = 1.0
        J[0::2, 2] = -rp[ok, 1]
        J[1::2, 2] = rp[ok, 0]
        delta, *_ = np.linalg.lstsq(J, res, rcond=None)
        T += delta
        rms = float(np.sqrt(np.mean(dist[ok] ** 2)))
        if np.all(np.abs(delta) < cfg.tolerance):
            break
    return T, rms, it


def invert(T: np.ndarray) -> np.ndarray:
    c, s = np.cos(T[2]), np.sin(T[2])
    return np.array([-(c * T[0] + s * T[1]), -(-s * T[0] + c * T[1]), -T[2]])


def scan_odometry(
    rot_rad: np.ndarray,
    dist: np.ndarray,
    vertical_rad: np.ndarray,
    relative_rad: np.ndarray,
    firing_hz: float,
    omega_rad_s: float,
    guess: np.ndarray | None = None,
    config: OdometryConfig | None = None,
    progress: Callable[[str, int, int], None] | None = None,
) -> Odometry:
    """Motions between scans every ``dt``. ``guess`` (K, 3) are initial motions in (x_C, y_C), or identity."""
    cfg = config or OdometryConfig()
    per_rev = round(2 * np.pi / abs(omega_rad_s) * firing_hz)
    step = round(cfg.dt_s * firing_hz)
    starts = np.arange(0, len(rot_rad) - per_rev + 1, step)
    scans = [
        scan_points(rot_rad[a : a + per_rev], dist[a : a + per_rev], vertical_rad, relative_rad, cfg.drop_below_m)
        for a in starts
    ]
    K = len(scans) - 1
    motion = np.zeros((K, 3))
    rms = np.zeros(K)
    iters = np.zeros(K, dtype=int)
    trees: dict[int, cKDTree] = {}
    for k in range(K):
        early, late = scans[k], scans[k + 1]
        m0 = np.zeros(3) if guess is None else guess[k]
        if len(early) <= len(late):  # D1 is the earlier scan: T maps earlier points into the later scan
            d1, j2, init = early, k + 1, invert(m0)
        else:
            d1, j2, init = late, k, m0
        if j2 not in trees:
            trees = {j2: cKDTree(scans[j2])} | {i: t for i, t in trees.items() if i >= k}
        T, rms[k], iters[k] = icp(_voxel(d1, cfg.voxel_m), trees[j2], scans[j2], init, cfg)
        M = invert(T) if d1 is early else T
        # (m_x, m_y) is in the earlier scan's frame; turn it by -m_theta/2 to the interval's mean heading
        c, s = np.cos(-M[2] / 2), np.sin(-M[2] / 2)
        motion[k] = (c * M[0] - s * M[1], s * M[0] + c * M[1], M[2])
        if progress:
            progress("scan matching (sec. 5.2)", k + 1, K)
    return Odometry(starts[:K] / firing_hz, motion, rms, iters, np.array([len(s) for s in scans]))


def angle_median(angles: np.ndarray) -> float:
    """The angle with the least total absolute (wrapped) distance to all of ``angles`` (sec. 5.2)."""
    a = np.asarray(angles, dtype=float)
    cost = np.abs(wrap_angle(a[:, None] - a[None, :])).sum(axis=1)
    return float(a[np.argmin(cost)])


def offset_from_motion(motion: np.ndarray, dt_s: float, min_speed_m_s: float = 2.0) -> float:
    """``C = pi/2 - angle median`` of the motion vectors faster than ``min_speed_m_s`` (sec. 5.2)."""
    speed = np.hypot(motion[:, 0], motion[:, 1]) / dt_s
    fast = speed > min_speed_m_s
    if not fast.any():
        fastest = float(speed.max()) if speed.size else 0.0
        raise LogFormatError(
            f"the scans show no motion faster than {min_speed_m_s:g} m/s (the fastest: {fastest:.2f} m/s), and only "
            "faster motions say which way the car's forward is (sec. 5.2, footnote 4).",
            field="min_speed_m_s",
            fix="give a drive that reaches that speed, or lower it with --set min_speed_m_s=...",
        )
    return float(wrap_angle(np.pi / 2 - angle_median(np.arctan2(motion[fast, 1], motion[fast, 0]))))
