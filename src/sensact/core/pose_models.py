"""Motion and landmark-observation geometry for the EM robots (sec. 2.5.1, eqs. 2.28 and 4.19).

Two state spaces share one set of functions, picked by ``mode``:

* ``PLANAR`` (chapter 4): the pose ``w = (x, y, theta)`` in the world frame. The robot frame has x to
  the robot's right and y forward (sec. 2.5.1); ``theta = 0`` means the robot faces world +y. A velocity
  ``(v_x, v_y, v_theta)`` is given in the robot frame and moves the pose by ``R(theta) v dt`` (eq. 2.28).
  A landmark's bearing is its angle counterclockwise from the robot's forward axis, wrapped to [-pi, pi).
* ``TRACK`` (sec. 4.4.3): the state is the distance to the beacon; a forward velocity shortens it.

The compiled functions fill caller-owned arrays so that the E-step's loops allocate nothing; the numpy
functions are their vectorized twins for simulators and the M-step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensact.core.angles import wrap, wrap_angle

PLANAR = 0
TRACK = 1
STATE_DIM = (3, 1)  # by mode


def state_dim(mode: int) -> int:
    return STATE_DIM[mode]


# ---------------------------------------------------------------- numpy (vectorized) forms


def landmark_distance(poses: np.ndarray, landmark_xy: np.ndarray, mode: int = PLANAR) -> np.ndarray:
    """Distance from each pose (rows) to its landmark (rows of ``landmark_xy``, or one landmark)."""
    poses = np.atleast_2d(poses)
    if mode == TRACK:
        return poses[:, 0].copy()
    d = np.asarray(landmark_xy, dtype=float) - poses[:, :2]
    return np.hypot(d[..., 0], d[..., 1])


def landmark_bearing(poses: np.ndarray, landmark_xy: np.ndarray) -> np.ndarray:
    """Bearing of the landmark from each planar pose, counterclockwise from the forward axis."""
    poses = np.atleast_2d(poses)
    d = np.asarray(landmark_xy, dtype=float) - poses[:, :2]
    return wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - poses[:, 2] - 0.5 * np.pi)


def sensor_poses(poses: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """The sensor's poses on robots at ``poses`` when it sits at ``mount`` = (forward mm, left mm, yaw rad,
    counterclockwise) in the robot frame: ``w + R(theta) (-left, forward, yaw)`` (sec. 2.5.1's robot frame
    has x to the right). A zero mount gives the poses back, bit for bit."""
    poses = np.atleast_2d(np.asarray(poses, dtype=float))
    fwd, left, yaw = (float(v) for v in mount)
    if fwd == 0.0 and left == 0.0 and yaw == 0.0:
        return poses
    return apply_displacement(poses, np.broadcast_to([-left, fwd, yaw], poses.shape))


def sensor_distance(poses: np.ndarray, landmark_xy: np.ndarray, mount: np.ndarray, mode: int = PLANAR) -> np.ndarray:
    """``landmark_distance`` from the sensor at ``mount`` (``sensor_poses``) on each pose; on a track, the state."""
    if mode == TRACK:
        return landmark_distance(poses, landmark_xy, mode)
    return landmark_distance(sensor_poses(poses, mount), landmark_xy)


def relative_displacement(w1: np.ndarray, w2: np.ndarray, mode: int = PLANAR) -> np.ndarray:
    """``D(w_t, w_t+1) = R(-theta_t)(w_t+1 - w_t)`` with the angle difference wrapped (sec. 4.2)."""
    w1 = np.atleast_2d(w1)
    w2 = np.atleast_2d(w2)
    if mode == TRACK:
        return w1 - w2
    dx, dy = w2[:, 0] - w1[:, 0], w2[:, 1] - w1[:, 1]
    c, s = np.cos(w1[:, 2]), np.sin(w1[:, 2])
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(w2[:, 2] - w1[:, 2])])


def apply_displacement(w: np.ndarray, disp: np.ndarray, mode: int = PLANAR) -> np.ndarray:
    """``w + R(theta) disp`` (eq. 2.28 without noise); the inverse of ``relative_displacement``."""
    w = np.atleast_2d(w)
    disp = np.atleast_2d(disp)
    if mode == TRACK:
        return w - disp
    c, s = np.cos(w[:, 2]), np.sin(w[:, 2])
    return np.column_stack(
        [w[:, 0] + c * disp[:, 0] - s * disp[:, 1], w[:, 1] + s * disp[:, 0] + c * disp[:, 1], w[:, 2] + disp[:, 2]]
    )


def arc_poses(ds: np.ndarray, dth: np.ndarray) -> np.ndarray:
    """``(T + 1, 3)``: the poses, from the origin, of a robot that drives each step along an arc of length
    ``ds`` turning by ``dth`` (a differential drive's odometry, exact for a constant turn rate): each step its
    chord, at half its turn."""
    th = np.concatenate([[0.0], np.cumsum(dth)])
    chord = ds * np.sinc(dth / (2 * np.pi))
    mid = th[:-1] + dth / 2
    x = np.concatenate([[0.0], -np.cumsum(chord * np.sin(mid))])  # heading 0 drives along +y
    y = np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    return np.column_stack([x, y, th])


def dead_reckon(velocities: np.ndarray, dt: float) -> np.ndarray:
    """``D(w_start, w_end)`` after integrating eq. 2.28 (no noise) over each row of ``(N, W, 3)`` robot-frame
    velocities held for ``dt`` each: a window's displacement, dead-reckoned from its start."""
    theta = np.cumsum(velocities[:, :, 2] * dt, axis=1)
    before = np.concatenate([np.zeros((len(theta), 1)), theta[:, :-1]], axis=1)  # heading during each step
    c, s = np.cos(before), np.sin(before)
    dx = np.sum((c * velocities[:, :, 0] - s * velocities[:, :, 1]) * dt, axis=1)
    dy = np.sum((s * velocities[:, :, 0] + c * velocities[:, :, 1]) * dt, axis=1)
    return np.column_stack([dx, dy, theta[:, -1]])


def chords_of(poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each step's chord (the move between successive poses along their mid heading) and turn (unwrapped):
    what ``arc_poses`` drove, its arcs shortened to their chords."""
    dth = np.diff(np.unwrap(poses[:, 2]))
    mid = poses[:-1, 2] + dth / 2
    d = np.diff(poses[:, :2], axis=0)
    return -d[:, 0] * np.sin(mid) + d[:, 1] * np.cos(mid), dth


def from_rep103(v: np.ndarray) -> np.ndarray:
    """Vectors (rows, last axis ``(x, y)`` or ``(x, y, yaw)``) from REP 103's axes (x forward, y left), as a
    ROS message or a LaserScan's beams give them, into sensact's (x right, y forward); a yaw, a difference of
    headings, is the same in both. Exact: a swap and a sign."""
    v = np.asarray(v, dtype=float)
    return np.concatenate([-v[..., 1:2], v[..., 0:1], v[..., 2:]], axis=-1)


def to_rep103(v: np.ndarray) -> np.ndarray:
    """``from_rep103``'s inverse: sensact's axes (x right, y forward) into REP 103's (x forward, y left)."""
    v = np.asarray(v, dtype=float)
    return np.concatenate([v[..., 1:2], -v[..., 0:1], v[..., 2:]], axis=-1)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's rpy: Rz(yaw) Ry(pitch) Rx(roll), the child's axes in the parent's (a sensor's 3-D mount, REP
    103 axes: x forward, y left, z up)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


# ---------------------------------------------------------------- compiled forms


@njit(cache=True, error_model="numpy")
def poly_value_slope(coef, center, scale, x):
    """``f(x)`` and ``f'(x)`` for ascending coefficients in ``u = (x - center) / scale``."""
    u = (x - center) / scale
    v = 0.0
    dv = 0.0
    for i in range(coef.shape[0] - 1, -1, -1):
        dv = dv * u + v
        v = v * u + coef[i]
    return v, dv / scale


@njit(cache=True, error_model="numpy")
def predict(mode, w, disp, out, F):
    """``out = w + R(theta) disp`` and its Jacobian ``F`` with respect to ``w`` (eqs. 2.24, 2.26)."""
    if mode == TRACK:
        out[0] = w[0] - disp[0]
        F[0, 0] = 1.0
        return
    c = np.cos(w[2])
    s = np.sin(w[2])
    out[0] = w[0] + c * disp[0] - s * disp[1]
    out[1] = w[1] + s * disp[0] + c * disp[1]
    out[2] = w[2] + disp[2]
    for i in range(3):
        for j in range(3):
            F[i, j] = 1.0 if i == j else 0.0
    F[0, 2] = -s * disp[0] - c * disp[1]
    F[1, 2] = c * disp[0] - s * disp[1]


@njit(cache=True, error_model="numpy")
def motion_covariance(mode, theta, var_robot, Q):
    """The motion noise ``Sigma_m`` (robot frame, diagonal) rotated into the world frame."""
    if mode == TRACK:
        Q[0, 0] = var_robot[0]
        return
    c = np.cos(theta)
    s = np.sin(theta)
    Q[0, 0] = c * c * var_robot[0] + s * s * var_robot[1]
    Q[1, 1] = s * s * var_robot[0] + c * c * var_robot[1]
    Q[0, 1] = c * s * (var_robot[0] - var_robot[1])
    Q[1, 0] = Q[0, 1]
    Q[0, 2] = 0.0
    Q[2, 0] = 0.0
    Q[1, 2] = 0.0
    Q[2, 1] = 0.0
    Q[2, 2] = var_robot[2]


@njit(cache=True, error_model="numpy")
def displacement(mode, w1, w2, D, G):
    """``D(w1, w2)`` into ``D`` and its Jacobian ``G = [dD/dw1, dD/dw2]`` (n x 2n) into ``G``."""
    if mode == TRACK:
        D[0] = w1[0] - w2[0]
        G[0, 0] = 1.0
        G[0, 1] = -1.0
        return
    dx = w2[0] - w1[0]
    dy = w2[1] - w1[1]
    c = np.cos(w1[2])
    s = np.sin(w1[2])
    D[0] = c * dx + s * dy
    D[1] = -s * dx + c * dy
    D[2] = wrap(w2[2] - w1[2])
    for i in range(3):
        for j in range(6):
            G[i, j] = 0.0
    G[0, 0] = -c
    G[0, 1] = -s
    G[1, 0] = s
    G[1, 1] = -c
    G[0, 2] = -s * dx + c * dy
    G[1, 2] = -c * dx - s * dy
    G[2, 2] = -1.0
    G[0, 3] = c
    G[0, 4] = s
    G[1, 3] = -s
    G[1, 4] = c
    G[2, 5] = 1.0


@njit(cache=True, error_model="numpy")
def sensor_point(w, mount):
    """Where the sensor sits in the world, ``(sx, sy)``, and its position's derivative in theta
    ``(dsx, dsy)``: ``mount`` = (forward mm, left mm, yaw rad) in the robot frame (x right, y forward)."""
    c = np.cos(w[2])
    s = np.sin(w[2])
    ox = -mount[1]  # to the right
    oy = mount[0]
    return w[0] + c * ox - s * oy, w[1] + s * ox + c * oy, -s * ox - c * oy, c * ox - s * oy


@njit(cache=True, error_model="numpy")
def landmark_range(mode, w, lx, ly, mount):
    """Distance from the sensor (at ``mount`` on the robot at ``w``) to the landmark; on a track the state."""
    if mode == TRACK:
        return w[0]
    sx, sy, _, _ = sensor_point(w, mount)
    return ((lx - sx) ** 2 + (ly - sy) ** 2) ** 0.5


@njit(cache=True, error_model="numpy")
def observe_height(mode, w, lx, ly, coef, center, scale, gain, mount, H):
    """Predicted reading ``f(dist) + gain * dist`` and its gradient ``H`` in the robot's pose (eq. 4.19,
    first component; ``gain`` is the channel's bearing term at the measured bearing, 0 in the thesis).
    ``dist`` is measured from the sensor, at ``mount`` on the robot; a zero mount is eq. 4.19 exactly."""
    if mode == TRACK:
        v, dv = poly_value_slope(coef, center, scale, w[0])
        H[0] = dv + gain
        return v + gain * w[0]
    sx, sy, dsx, dsy = sensor_point(w, mount)
    dx = lx - sx
    dy = ly - sy
    r = (dx * dx + dy * dy) ** 0.5
    v, dv = poly_value_slope(coef, center, scale, r)
    dv += gain
    H[0] = -dv * dx / r
    H[1] = -dv * dy / r
    H[2] = -dv * (dx * dsx + dy * dsy) / r
    return v + gain * r


@njit(cache=True, error_model="numpy")
def observe_bearing(w, lx, ly, mount, H):
    """Predicted bearing ``ang`` (wrapped) from the sensor at ``mount`` and its gradient ``H`` in the
    robot's pose (eq. 4.19, second component; a zero mount is the thesis's exactly)."""
    sx, sy, dsx, dsy = sensor_point(w, mount)
    dx = lx - sx
    dy = ly - sy
    r2 = dx * dx + dy * dy
    H[0] = dy / r2
    H[1] = -dx / r2
    H[2] = (dy * dsx - dx * dsy) / r2 - 1.0
    return wrap(np.arctan2(dy, dx) - w[2] - mount[2] - 0.5 * np.pi)
