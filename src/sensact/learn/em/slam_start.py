"""Where EM's map starts when nobody surveyed it (docs/map.md): one pass of EKF-SLAM (sec. 2.4's filter with
the landmarks in its state, as the SLAM literature the thesis cites runs it) under the starting model,
each landmark placed where it is first seen and moved by every later sighting; and ``starting_map``, what
``initial.py``'s starting model takes from it (the frame, the scale, the map). EM then learns the models
and the map together from there."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.landmark_map import LandmarkMap
from sensact.models.landmark_sensor import LandmarkSensor

HALF_PI = 0.5 * np.pi
GATE = 25.0  # chi-square, 2 dof: a sighting this far off is not used
PLACE_AFTER = 5  # a landmark is placed at the median of this many first sightings
MIN_ANCHORS_GIVEN = 3  # range-only anchors: given positions that fix the path (and so the frame) in 2-D


def slam_map(
    data: LandmarkLog,
    velocity: np.ndarray,
    motion_sd: np.ndarray,
    start: np.ndarray,
    distance: np.ndarray,
    range_sd: float,
    bearing_sd: float,
) -> np.ndarray:
    """(L, 2) landmark positions from a forward EKF-SLAM pass: the robot moves by ``velocity`` (T, 3) in its
    own frame (eq. 2.28) with per-step sds ``motion_sd`` (3,), from ``start`` (x, y, theta); each sighting
    reads ``distance`` (K,) mm (NaN: none) and its bearing. Given positions (finite rows of the log's map)
    are held; a landmark never seen stays NaN."""
    known = np.isfinite(data.landmarks_xy).all(axis=1)
    L = len(data.landmarks_xy)
    n = 3 + 2 * L
    x = np.zeros(n)
    x[:3] = start
    x[3:] = np.nan_to_num(data.landmarks_xy.ravel())
    P = np.zeros((n, n))
    P[:3, :3] = np.diag([1e-6, 1e-6, 1e-8])  # the start fixes the frame
    seen = known.copy()
    big = 1e12
    for i in np.flatnonzero(~known):
        P[3 + 2 * i : 5 + 2 * i, 3 + 2 * i : 5 + 2 * i] = np.eye(2) * big
    Q = np.diag(np.square(motion_sd))
    R = np.diag([range_sd**2, bearing_sd**2])
    dt = data.dt_s
    ptr = data.obs_ptr
    gated = 0
    pending: list[list[np.ndarray]] = [[] for _ in range(L)]
    for t in range(data.n_steps):
        for k in range(ptr[t], ptr[t + 1]):
            d, b, l = distance[k], data.obs_bearing_rad[k], int(data.obs_landmark[k])
            if not (np.isfinite(d) and np.isfinite(b)):
                continue
            j = 3 + 2 * l
            if not seen[l]:  # placed at the median of its first sightings' positions, so that a misread cannot
                a = x[2] + HALF_PI + b
                pending[l].append(x[:2] + d * np.array([np.cos(a), np.sin(a)]))
                if len(pending[l]) < PLACE_AFTER:
                    continue
                x[j : j + 2] = np.median(np.array(pending[l]), axis=0)
                seen[l] = True
                G = np.array([[1, 0, -d * np.sin(a)], [0, 1, d * np.cos(a)]])
                Gz = np.array([[np.cos(a), -d * np.sin(a)], [np.sin(a), d * np.cos(a)]])
                P[j : j + 2, :] = G @ P[:3, :]  # correlated with the pose, and through it with the map
                P[:, j : j + 2] = P[j : j + 2, :].T
                P[j : j + 2, j : j + 2] = G @ P[:3, :3] @ G.T + Gz @ R @ Gz.T
                continue
            dx, dy = x[j] - x[0], x[j + 1] - x[1]
            q = max(dx * dx + dy * dy, 1e-6)
            r = np.sqrt(q)
            z_hat = np.array([r, wrap_angle(np.arctan2(dy, dx) - x[2] - HALF_PI)])
            H = np.zeros((2, n))
            H[0, [0, 1, j, j + 1]] = [-dx / r, -dy / r, dx / r, dy / r]
            H[1, [0, 1, 2, j, j + 1]] = [dy / q, -dx / q, -1.0, -dy / q, dx / q]
            idx = [0, 1, 2, j, j + 1]
            PH = P[:, idx] @ H[:, idx].T
            S = H[:, idx] @ PH[idx] + R
            innov = np.array([d - z_hat[0], wrap_angle(b - z_hat[1])])
            if innov @ np.linalg.solve(S, innov) > GATE:  # a misread, or the landmark was placed by one
                gated += 1
                continue
            K = np.linalg.solve(S, PH.T).T
            x = x + K @ innov
            P = P - K @ PH.T
            P = 0.5 * (P + P.T)  # rounding must not make it lose symmetry
        if t + 1 < data.n_steps:  # the time update (eq. 2.28)
            c, s = np.cos(x[2]), np.sin(x[2])
            v = velocity[t] * dt
            x[0] += c * v[0] - s * v[1]
            x[1] += s * v[0] + c * v[1]
            x[2] += v[2]
            F = np.eye(3)
            F[0, 2] = -s * v[0] - c * v[1]
            F[1, 2] = c * v[0] - s * v[1]
            Rt = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            P[:3, :] = F @ P[:3, :]
            P[:, :3] = P[:, :3] @ F.T
            P[:3, :3] += Rt @ Q @ Rt.T
    out = x[3:].reshape(L, 2).copy()
    for l in np.flatnonzero(~seen & np.array([len(p) > 0 for p in pending])):  # seen fewer times than that
        out[l] = np.median(np.array(pending[l]), axis=0)
        seen[l] = True
    out[~seen] = np.nan
    return out


# the robot's start when it fixes the map's frame: the origin, facing REP 103's +x (sensact's heading 0
# faces +y, so -pi/2), pinned to a millimetre and a milliradian
FRAME_START = np.array([0.0, 0.0, -HALF_PI])
FRAME_START_SD = np.array([1.0, 1.0, 1e-3])


def face_value_velocity(data: LandmarkLog) -> np.ndarray:
    """(T, 3) robot-frame velocities taking a forward command in mm/s and a turn command in rad/s at face
    value (what wheel odometry reports): the path EKF-SLAM starts the map from. Zero where the log has no
    such commands."""
    out = np.zeros((data.n_steps, 3))
    if data.step_commands is None:
        return out
    names = data.command_names
    fwd = next((i for i, n in enumerate(names) if n.startswith("v") and n.endswith("_mm_s") and "left" not in n), None)
    turn = next((i for i, n in enumerate(names) if n.endswith("_rad_s")), None)
    if fwd is not None:
        out[:, 1] = data.step_commands[:, fwd]
    if turn is not None:
        out[:, 2] = data.step_commands[:, turn]
    return out


def starting_map(
    data: LandmarkLog, sensor: LandmarkSensor, motion_sd: np.ndarray, config: EMConfig
) -> tuple[np.ndarray, np.ndarray, LandmarkMap]:
    """The start pose, its covariance and the map EM learns from when the log gives no (or a partial) map
    (docs/map.md): the robot's start fixes the frame unless two or more positions are given; the map starts
    from EKF-SLAM on the commands at face value (``slam_map``); its scale comes from the range
    readings in mm, or from the given positions."""
    held = data.map_given
    if not data.geometry.has_heading:
        raise ConfigError(
            f"{int((~held).sum())} of {len(held)} landmarks have no position, and a track reads one distance: "
            "no map to learn.",
            file=data.source,
            field="landmarks",
            fix="give the landmark's position in meta.json.",
        )
    if not sensor.reads_bearing:  # anchors read by range alone: placed on a path the given ones fix (anchors.py)
        if held.sum() < MIN_ANCHORS_GIVEN:
            raise ConfigError(
                f"{int((~held).sum())} of {len(held)} anchors have no position and the sensor reads ranges alone: "
                f"with {int(held.sum())} given, nothing fixes the robot's path to place them from.",
                file=data.source,
                field="landmarks",
                fix=f"give {MIN_ANCHORS_GIVEN} or more anchors' positions (convert ... --landmarks map.csv, "
                "id,x_m,y_m, with --learn-unlisted), or every one.",
            )
        mean = np.asarray(config.thesis.start_prior_mean[:3], dtype=float)
        cov = np.diag(np.asarray(config.thesis.start_prior_sd[:3], dtype=float) ** 2)
        xy = np.where(held[:, None], data.landmarks_xy, np.nan)
        return mean, cov, LandmarkMap(xy, held, np.full((len(xy), 2), np.nan), "map"), sensor
    first = sensor.channels[0]
    col = data.reading_names.index(first.name) if first.name in data.reading_names else 0
    o = data.obs_readings[:, col]
    if first.name.endswith("_mm"):
        distance = o
    else:  # the starting line, inverted
        slope = first.function.slope(np.array([1000.0]))[0] or 1.0
        distance = (o - first.function(0.0)) / slope
    scale = "map" if held.sum() >= 2 else "range" if any(c.name.endswith("_mm") for c in sensor.channels) else None
    if scale is None:
        raise ConfigError(
            "nothing fixes the learned map's scale: no reading is a length in mm and fewer than two landmark "
            "positions are given.",
            file=data.source,
            field="landmarks",
            fix="give two landmarks' positions (a partial --landmarks map.csv), or a range reading in mm.",
        )
    if held.sum() >= 2:
        mean = np.asarray(config.thesis.start_prior_mean[:3], dtype=float)
        cov = np.diag(np.asarray(config.thesis.start_prior_sd[:3], dtype=float) ** 2)
    else:
        mean, cov = FRAME_START.copy(), np.diag(FRAME_START_SD**2)
    if scale == "range":  # the length reading is the map's unit: f starts as the identity, and keeps its slope
        c = next(i for i, ch in enumerate(sensor.channels) if ch.name.endswith("_mm"))
        ch = sensor.channels[c]
        f = replace(ch.function, coef=(0.0, 1.0) + (0.0,) * (ch.function.degree - 1), center=0.0, scale=1.0)
        sensor = replace(
            sensor, channels=tuple(replace(ch, function=f) if i == c else k for i, k in enumerate(sensor.channels))
        )
    sd_b = sensor.sigma_bearing_rad
    xy = slam_map(data, face_value_velocity(data), motion_sd, mean, distance, first.sigma, sd_b)
    return mean, cov, LandmarkMap(xy, held, np.full((len(xy), 2), np.nan), scale), sensor
