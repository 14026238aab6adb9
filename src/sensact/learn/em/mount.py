"""The sensor's mount on the robot, learned in the M-step (beyond the thesis, whose eq. 4.19 reads the
landmark from the robot's own point).

**Model.** A planar sensor sits at ``m = (forward, left, yaw)`` on the robot; its pose is
``s(w, m) = w + R(theta) (-left, forward, yaw)`` (``core.pose_models.sensor_poses``), and eq. 4.19 reads
the landmark from ``s``: ``o_i = f_i(d(s)) + N(0, sigma_i^2)``, ``o_b = ang(s) + N(0, sigma_2^2)``.

**M-step.** As sec. 4.3 derives each update, the expected complete-data log-likelihood splits into the
prior's, the motion's and the observations' terms, and only the last depends on ``m``::

    Q(m) = - sum_k sum_i w_ki E_gamma[(o_ki - f_i(d(s(w_k, m))) - g_ki d)^2] / (2 sigma_i^2)
           - sum_k w_kb E_gamma[(o_kb - ang(s(w_k, m)))^2] / (2 sigma_2^2) + const

with ``w`` the E-step's reading weights and ``g_ki`` a channel's bearing gain. The expectations over
``gamma_k`` are taken, as eq. 4.25 takes them, on the poses sampled from ``gamma`` (``mstep.sample_gamma``),
and ``Q`` is maximized by Gauss-Newton (a weighted nonlinear least squares in three unknowns), before the
sensor functions are refitted at the new mount: each conditional update raises ``Q`` (ECM, Meng and
Rubin 1993), so the iteration stays a generalized EM.

**Which components the log pins.** Relative to what point is the sensor mounted? The pose EM learns is
that of the point whose motion the action model describes. A robot that cannot side-step (its sideways
velocity held at zero mean: a differential drive) has one such point, the middle of its axle, so the
sensor's offsets from it are pinned: turning in place swings a sensor ahead of the axle sideways, and
driving straight points its yaw. A robot whose every velocity is free (the thesis's Aibo, a legged robot)
can be described from any point with another action model of the same likelihood, so its mount is
held. A range-only sensor reads no yaw: its yaw is held. ``mount_freedom`` says which, and why.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, sensor_distance, sensor_poses
from sensact.models.em_model import EMModel
from sensact.models.landmark_sensor import LandmarkSensor, SensorMount

MOUNT_COMPONENTS = ("forward_mm", "left_mm", "yaw_rad")
GAUSS_NEWTON_STEPS = 3  # per M-step; EM's own iterations carry it the rest of the way


@dataclass(frozen=True)
class MountFreedom:
    """Which of the mount's components the M-step learns (forward, left, yaw), and why the rest are held."""

    free: tuple[bool, bool, bool]
    reason: str

    @property
    def any(self) -> bool:
        return any(self.free)

    def describe(self) -> str:
        d = self.to_dict()
        parts = [f"{k}: {', '.join(d[k])}" for k in ("learned", "held") if d[k]]
        return "; ".join(parts) + f" ({self.reason})"

    def to_dict(self) -> dict[str, object]:
        return {
            "learned": [n for n, f in zip(MOUNT_COMPONENTS, self.free, strict=True) if f],
            "held": [n for n, f in zip(MOUNT_COMPONENTS, self.free, strict=True) if not f],
            "reason": self.reason,
        }


def mount_freedom(model: EMModel, given: bool, reads_bearing: bool) -> MountFreedom:
    """Which components of the sensor's mount the log pins (module docstring), for ``model``'s action
    model; ``given``: the config gives the mount, which is then held whole."""
    if not model.geometry.has_heading:
        return MountFreedom((False, False, False), "a track's sensor has no pose of its own")
    if given:
        return MountFreedom((False, False, False), "given in the config (sensor_mount)")
    action = model.action
    if "v_x_mm_s" not in action.zero_mean:
        return MountFreedom(
            (False, False, False),
            "every velocity of the action model is free, so any point of the robot describes its motion "
            "equally well; hold v_x_mm_s at zero mean (action_zero_mean) for a robot that cannot side-step",
        )
    if not reads_bearing:
        return MountFreedom((True, True, False), "a range-only sensor reads no yaw")
    return MountFreedom((True, True, True), "the robot cannot side-step: its axle is the point EM tracks")


def _objective_terms(
    mount: np.ndarray,
    poses: np.ndarray,
    lm: np.ndarray,
    readings: np.ndarray,
    weights: np.ndarray,
    sensor: LandmarkSensor,
    bearings: np.ndarray,
    free: np.ndarray,
) -> tuple[float, np.ndarray, np.ndarray]:
    """``-2 Q(m)`` up to a constant, its gradient ``J' W e`` and Gauss-Newton matrix ``J' W J`` in the free
    components. ``poses`` ``(S, R, 3)`` are robot poses sampled from gamma at the ``R`` sightings."""
    S = poses.shape[0]
    p = poses.reshape(-1, 3)
    lm_s = np.tile(lm, (S, 1))
    at = sensor_poses(p, mount)
    dx, dy = lm_s[:, 0] - at[:, 0], lm_s[:, 1] - at[:, 1]
    d = np.hypot(dx, dy)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    # the sensor's position's derivatives in (forward, left): (-sin, cos) and (-cos, -sin)
    dd = np.column_stack([-(-dx * s + dy * c) / d, (dx * c + dy * s) / d, np.zeros_like(d)])
    db = np.column_stack([(-dy * s - dx * c) / d**2, (-dy * c + dx * s) / d**2, -np.ones_like(d)])
    total, grad, gn = 0.0, np.zeros(3), np.zeros((3, 3))
    b_s = np.tile(bearings, S)
    for ci, ch in enumerate(sensor.channels):
        w = np.tile(weights[:, ci], S) / ch.sigma**2
        use = w > 0
        if not use.any():
            continue
        gain = ch.bearing_gain(b_s[use]) if ch.bearing_terms else 0.0
        e = np.tile(readings[:, ci], S)[use] - ch.function(d[use]) - gain * d[use]
        J = (ch.function.slope(d[use]) + gain)[:, None] * dd[use]
        total += float(np.sum(w[use] * e**2))
        grad += J.T @ (w[use] * e)
        gn += J.T @ (J * w[use, None])
    if sensor.reads_bearing:
        w = np.tile(weights[:, -1], S) / sensor.sigma_bearing_rad**2
        use = (w > 0) & np.isfinite(b_s)
        if use.any():
            e = wrap_angle(b_s[use] - landmark_bearing(at[use], lm_s[use]))
            J = db[use]
            total += float(np.sum(w[use] * e**2))
            grad += J.T @ (w[use] * e)
            gn += J.T @ (J * w[use, None])
    keep = np.asarray(free, dtype=bool)
    return total, grad[keep], gn[np.ix_(keep, keep)]


def mount_update(
    poses: np.ndarray,
    lm: np.ndarray,
    readings: np.ndarray,
    weights: np.ndarray,
    bearings: np.ndarray,
    sensor: LandmarkSensor,
    free: tuple[bool, bool, bool],
) -> SensorMount:
    """The mount that raises ``Q(m)`` (module docstring) from ``sensor.mount``: Gauss-Newton steps on the
    sampled poses, each halved until it lowers ``-2 Q`` (so the update never lowers ``Q``). ``readings``
    ``(R, C)`` and ``weights`` ``(R, C+1)`` are the sightings' channels and E-step weights, ``bearings``
    ``(R,)`` their measured bearings; only the ``free`` components move."""
    keep = np.asarray(free, dtype=bool)
    mount = sensor.mount.as_array()
    if not keep.any() or poses.shape[1] == 0:
        return sensor.mount
    args = (poses, lm, readings, weights, sensor, bearings, keep)
    value, grad, gn = _objective_terms(mount, *args)
    for _ in range(GAUSS_NEWTON_STEPS):
        try:
            step = np.linalg.solve(gn + 1e-9 * np.trace(gn) * np.eye(keep.sum()), grad)
        except np.linalg.LinAlgError:
            break
        moved = False
        for _half in range(8):
            trial = mount.copy()
            trial[keep] += step
            t_value, t_grad, t_gn = _objective_terms(trial, *args)
            if np.isfinite(t_value) and t_value < value:
                mount, value, grad, gn, moved = trial, t_value, t_grad, t_gn, True
                break
            step = 0.5 * step
        if not moved:
            break
    return SensorMount.from_array(mount)


def sensor_distances(poses: np.ndarray, lm: np.ndarray, mount: SensorMount, mode: int) -> np.ndarray:
    """Each sampled robot pose's (rows of ``poses``, ``(S, R, n)``) distance from its sensor to its landmark."""
    m = mount.as_array()
    return np.stack([sensor_distance(poses[s], lm, m, mode) for s in range(poses.shape[0])])


def remounted(model: EMModel, mount: np.ndarray) -> EMModel:
    """``model`` with its sensor at ``mount`` and its start moved so that the sensor's own start pose stays
    where it was: the same first sightings, read from a robot placed behind its sensor anew."""
    old = model.sensor.mount.as_array()
    new = np.asarray(mount, dtype=float)
    if model.landmarks is not None and model.landmarks.held.sum() < 2:  # the start is the map's frame: it stays
        return model.replace(sensor=replace(model.sensor, mount=SensorMount.from_array(new)))
    s0 = sensor_poses(model.prior_mean, old)[0]
    theta = s0[2] - new[2]
    c, s = np.cos(theta), np.sin(theta)
    x = s0[0] + c * new[1] + s * new[0]
    y = s0[1] + s * new[1] - c * new[0]
    sensor = replace(model.sensor, mount=SensorMount.from_array(new))
    return model.replace(sensor=sensor, prior_mean=np.array([x, y, theta]))
