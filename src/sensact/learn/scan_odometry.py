"""Sec. 5.2: the car's motion from consecutive lidar scans, by 2-D ICP (Algorithm 2), and the angle
offset ``C`` from the direction the car moves.

Scans are taken every ``dt`` (0.5 s): all returns of one revolution, at horizontal angle
``theta_r + theta'_l`` in the frame (x_C, y_C), which is the car's frame turned by the unknown ``C``. Points
more than 1 m below the sensor are dropped: the ground's circles move with the car and would pull ICP
toward no motion. ICP matches the scan with fewer points (D1) into the other (D2) with a k-d tree, fits
``(dx, dy, dtheta)`` by linearized least squares around the current estimate, and ignores pairs more
than 7 m apart. ``matcher="kiss_icp"`` (not the thesis's; the ``kiss`` extra) matches every revolution
with KISS-ICP instead (``_kiss_icp_odometry``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from sensact.core.angles import wrap_angle
from sensact.errors import ConfigError, LogFormatError


@dataclass(frozen=True)
class OdometryConfig:
    dt_s: float = 0.5  # sec. 5.4
    drop_below_m: float = 1.0  # sec. 5.2
    outlier_m: float = 7.0  # footnote 3 of ch. 5
    max_iterations: int = 50
    tolerance: float = 1e-5  # stop when the update (m, rad) is this small
    min_speed_m_s: float = 2.0  # footnote 4: only faster motions vote for C
    voxel_m: float = 0.0  # > 0 thins D1 to one point per voxel (speed; the thesis used every point)
    # "kiss_icp": every revolution, deskewed, matched to a local map by KISS-ICP (the kiss extra), with the
    # guesses as its initial guesses; "algorithm2": the thesis's 2-D ICP between scans every dt_s
    matcher: Literal["algorithm2", "kiss_icp"] = "algorithm2"


@dataclass(frozen=True, eq=False)
class Odometry:
    times_s: np.ndarray  # (K,) start of each interval
    motion: np.ndarray  # (K, 3) m_x, m_y (already turned by -m_theta/2), m_theta, in the (x_C, y_C) frame
    rms_m: np.ndarray  # (K,) ICP's final RMS (eq. 5.2)
    iterations: np.ndarray  # (K,)
    n_points: np.ndarray  # (K + 1,) points per scan (KISS-ICP: per revolution)


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
    if cfg.matcher == "kiss_icp":
        scan = (rot_rad, dist, vertical_rad, relative_rad, firing_hz, omega_rad_s)
        return _kiss_icp_odometry(scan, guess, cfg, progress)
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


def _revolution_points(rot_rad, dist, vertical_rad, relative_rad, drop_below_m) -> tuple[np.ndarray, np.ndarray]:
    """One revolution's returns as 3-D points in (x_C, y_C, up), the ground left out as ``scan_points`` leaves
    it, and each point's time through the revolution in [0, 1] (for deskewing)."""
    alpha = rot_rad[:, None] + relative_rad[None, :]
    cv, sv = np.cos(vertical_rad), np.sin(vertical_rad)
    d = dist.astype(float)
    keep = (d > 0) & (d * sv[None, :] >= -drop_below_m)
    r = (d * cv[None, :])[keep]
    a = alpha[keep]
    points = np.column_stack([r * np.cos(a), r * np.sin(a), (d * sv[None, :])[keep]])
    frac = np.broadcast_to(np.arange(len(rot_rad))[:, None] / len(rot_rad), d.shape)[keep]
    return points, frac


def _planar_transform(dx: float, dy: float, dtheta: float) -> np.ndarray:
    c, s = np.cos(dtheta), np.sin(dtheta)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = dx, dy
    return T


def _register(kiss, points: np.ndarray, frac: np.ndarray, predicted: np.ndarray | None) -> None:
    """KISS-ICP's ``register_frame`` with the revolution's motion ``predicted`` (4x4, the learned dynamics')
    as the registration's initial guess in place of its constant-velocity one; the deskewing keeps KISS-ICP's
    own estimate of the motion during the revolution, so that a poor prediction moves only the start."""
    frame = kiss.preprocessor.preprocess(points, frac, kiss.last_delta)
    source, frame_downsample = kiss.voxelize(frame)
    sigma = kiss.adaptive_threshold.get_threshold()
    initial_guess = kiss.last_pose @ (kiss.last_delta if predicted is None else predicted)
    new_pose = kiss.registration.align_points_to_map(
        points=source,
        voxel_map=kiss.local_map,
        initial_guess=initial_guess,
        max_correspondance_distance=3 * sigma,
        kernel=sigma,
    )
    kiss.adaptive_threshold.update_model_deviation(np.linalg.inv(initial_guess) @ new_pose)
    kiss.local_map.update(frame_downsample, new_pose)
    kiss.last_delta = np.linalg.inv(kiss.last_pose) @ new_pose
    kiss.last_pose = new_pose


def _kiss_icp_odometry(
    scan: tuple, guess: np.ndarray | None, cfg: OdometryConfig, progress: Callable[[str, int, int], None] | None
) -> Odometry:
    """``scan_odometry``'s motions, by KISS-ICP (Vizzo et al. 2023) instead of Algorithm 2: every revolution,
    deskewed, matched point to point against a local voxel map with an adaptive threshold. The motion over
    each interval is read off its poses, interpolated to the middles of the revolutions that start and end
    the interval, as Algorithm 2's scans stand for. ``guess`` (the learned dynamics' motions, sec. 5.3)
    seeds each revolution's registration in place of KISS-ICP's constant-velocity guess: the API gap its
    users ask about (kiss-icp issue #183), filled by setting its predicted motion before each frame.
    ``scan`` is ``scan_odometry``'s first six arguments."""
    rot_rad, dist, vertical_rad, relative_rad, firing_hz, omega_rad_s = scan
    try:
        from kiss_icp.config import KISSConfig
        from kiss_icp.kiss_icp import KissICP
    except ImportError:
        raise ConfigError(
            "the kiss_icp matcher needs KISS-ICP, which is not installed.",
            field="matcher",
            fix="pip install 'sensact[kiss]', or leave matcher at algorithm2.",
        ) from None
    per_rev = round(2 * np.pi / abs(omega_rad_s) * firing_hz)
    step = round(cfg.dt_s * firing_hz)
    starts = np.arange(0, len(rot_rad) - per_rev + 1, step)
    revs = np.arange(0, len(rot_rad) - per_rev + 1, per_rev)
    reach = float(np.max(dist, initial=0.0))
    kiss_cfg = KISSConfig()
    kiss_cfg.data.max_range = max(reach, 1.0)
    kiss_cfg.mapping.voxel_size = kiss_cfg.data.max_range / 100.0  # as KISS-ICP's own pipeline sets it
    kiss = KissICP(kiss_cfg)
    poses = np.zeros((len(revs), 3))
    n_points = np.zeros(len(revs), dtype=int)
    for j, a in enumerate(revs):
        points, frac = _revolution_points(
            rot_rad[a : a + per_rev], dist[a : a + per_rev], vertical_rad, relative_rad, cfg.drop_below_m
        )
        predicted = None
        if guess is not None and len(guess):
            k = min(int(np.searchsorted(starts, a, side="right")) - 1, len(guess) - 1)
            mx, my, mt = guess[max(k, 0)] * (per_rev / step)  # the interval's motion, for one revolution
            c, s = np.cos(mt / 2), np.sin(mt / 2)
            predicted = _planar_transform(c * mx - s * my, s * mx + c * my, mt)
        _register(kiss, points, frac, predicted)
        P = kiss.last_pose
        poses[j] = P[0, 3], P[1, 3], np.arctan2(P[1, 0], P[0, 0])
        n_points[j] = len(points)
        if progress:
            progress("scan matching (KISS-ICP)", j + 1, len(revs))
    # KISS-ICP's pose is the revolution's end (its deskewing's reference): the middle of revolution r is
    # half a revolution before; the pose there is interpolated
    pose_t = (revs + per_rev) / firing_hz
    track = np.column_stack([poses[:, :2], np.unwrap(poses[:, 2])])
    mid = (starts + per_rev / 2) / firing_hz
    at = np.column_stack([np.interp(mid, pose_t, track[:, i]) for i in range(3)])
    K = len(starts) - 1
    d = np.diff(at, axis=0)
    c, s = np.cos(at[:K, 2]), np.sin(at[:K, 2])
    mx, my = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]  # in the earlier scan's frame
    c, s = np.cos(-d[:, 2] / 2), np.sin(-d[:, 2] / 2)  # then turned by -m_theta/2, as Algorithm 2's are
    motion = np.column_stack([c * mx - s * my, s * mx + c * my, d[:, 2]])
    return Odometry(starts[:K] / firing_hz, motion, np.full(K, np.nan), np.zeros(K, dtype=int), n_points)


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
