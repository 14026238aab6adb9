"""A 1/10-scale car-like robot (F1TENTH, MuSHR) lapping a corridor track with a 270-degree lidar
(docs/ackermann.md): what its bag records, with the truth its ``vesc.yaml`` does not know.

The car's controller (pure pursuit on the corridor's centre line, at a speed that changes every few
seconds) publishes ``/drive`` (speed, steering angle). The VESC driver turns them into motor ERPM and a servo
position through the yaml's four numbers (``ERPM = gain * speed + offset``, ``servo = gain * angle + offset``),
which are not the car's true ones: the motor reaches its ERPM with a lag, and the wheels steer to the angle
the *true* servo numbers give, ``steering_delay_s`` after the command, within the linkage's stop. The car moves
by kinematic bicycle at its rear axle (``base_link``), each step's travel and turn a little off (``slip_sd``).
The VESC reports its measured ERPM (``/sensors/core``), stamped ``erpm_delay_s`` late; the lidar, mounted at
``mount`` (not where ``urdf_mount`` says), sweeps its beams counterclockwise, 25 ms a revolution.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from sensact.core import raycast
from sensact.logs.car_log import CarLog
from sensact.logs.lidar2d_log import Pose2, ScanGeometry, UrdfGuess
from sensact.records import JsonObject
from sensact.sim.lidar2d import FURNITURE_HEIGHT_M, LIDAR_HEIGHT_M, cast_beams

MAX_STEER_RAD = 0.42  # what the controller commands at most (F1TENTH: 0.4189)
STOP_RAD = 0.5  # the linkage's stop


@dataclass(frozen=True)
class CarConfig:
    """Every knob of the simulated car (``--set name=value``), in ROS's units as the yaml holds them (m, rad, s,
    ERPM, servo units), the mount in mm."""

    seconds: float = 300.0
    seed: int = 0
    # the truth the learner is after
    speed_to_erpm_gain: float = 4614.0
    speed_to_erpm_offset: float = 0.0
    steering_angle_to_servo_gain: float = -1.2135
    steering_angle_to_servo_offset: float = 0.5304
    wheelbase_m: float = 0.3302
    steering_delay_s: float = 0.08
    erpm_delay_s: float = 0.02  # the VESC's report stamped late
    motor_lag_s: float = 0.15  # the motor reaches its commanded ERPM as a first-order lag
    mount: tuple[float, float, float] = (265.0, 8.0, 0.015)  # forward_mm, left_mm, yaw_rad of the lidar
    range_sd_mm: float = 10.0
    erpm_sd: float = 20.0
    slip_sd: float = 0.01  # of each 5-ms step's travel and turn
    # what the yaml says (the owner's tape-measure numbers)
    yaml_speed_gain: float = 4380.0  # 5 % low
    yaml_speed_offset: float = 0.0
    yaml_servo_gain: float = -1.28  # 5.5 % high
    yaml_servo_offset: float = 0.5304 - 1.2135 * math.radians(2.0)  # the wheels 2 degrees right of straight
    urdf_mount: tuple[float, float, float] = (270.0, 0.0, 0.0)
    # the recording
    scan_hz: float = 40.0
    beams: int = 1081
    fov_deg: float = 270.0
    range_min_mm: float = 60.0
    range_max_mm: float = 10000.0
    vesc_hz: float = 50.0
    drive_hz: float = 40.0
    # the driving: counterclockwise laps (a lap turns left six times and right twice) at speeds drawn in
    # [speed_min, speed_max] every few seconds, the corners taken as tight as ``lookahead_m`` makes them;
    # ``scale`` > 1 makes the track (and the lookahead) larger: gentle curves only
    speed_min_m_s: float = 1.0
    speed_max_m_s: float = 2.5
    lookahead_m: float = 0.9
    scale: float = 1.0

    def __post_init__(self) -> None:
        problems = []
        if not 10 <= self.seconds <= 36_000:
            problems.append("seconds must be in [10, 36000]")
        if self.speed_to_erpm_gain == 0 or self.yaml_speed_gain == 0:
            problems.append("speed_to_erpm_gain and yaml_speed_gain must not be 0")
        if self.steering_angle_to_servo_gain == 0 or self.yaml_servo_gain == 0:
            problems.append("steering_angle_to_servo_gain and yaml_servo_gain must not be 0")
        if not 0.05 <= self.wheelbase_m <= 5:
            problems.append("wheelbase_m must be in [0.05, 5]")
        if not (0 <= self.steering_delay_s <= 1 and 0 <= self.erpm_delay_s <= 1 and 0 <= self.motor_lag_s <= 2):
            problems.append("steering_delay_s and erpm_delay_s must be in [0, 1], motor_lag_s in [0, 2]")
        if min(self.range_sd_mm, self.erpm_sd, self.slip_sd) < 0:
            problems.append("range_sd_mm, erpm_sd and slip_sd must be >= 0")
        if not (1 <= self.scan_hz <= 100 and 5 <= self.vesc_hz <= 1000 and 5 <= self.drive_hz <= 200):
            problems.append("scan_hz must be in [1, 100], vesc_hz in [5, 1000], drive_hz in [5, 200]")
        if not 16 <= self.beams <= 4096 or not 10 <= self.fov_deg <= 360:
            problems.append("beams must be in [16, 4096], fov_deg in [10, 360]")
        if not 0 < self.range_min_mm < self.range_max_mm <= 100_000:
            problems.append("need 0 < range_min_mm < range_max_mm <= 100000")
        if not 0.5 <= self.scale <= 10:
            problems.append("scale must be in [0.5, 10]")
        if not 0 < self.speed_min_m_s <= self.speed_max_m_s <= 10 or not 0.3 <= self.lookahead_m <= 10:
            problems.append("need 0 < speed_min_m_s <= speed_max_m_s <= 10, lookahead_m in [0.3, 10]")
        if problems:
            raise ValueError("; ".join(problems) + " (docs/ackermann.md).")

    def truth(self) -> JsonObject:
        f, left, yaw = self.mount
        return {
            "vesc": {
                "speed_to_erpm_gain": self.speed_to_erpm_gain,
                "speed_to_erpm_offset": self.speed_to_erpm_offset,
                "steering_angle_to_servo_gain": self.steering_angle_to_servo_gain,
                "steering_angle_to_servo_offset": self.steering_angle_to_servo_offset,
            },
            "car": {
                "wheelbase_mm": self.wheelbase_m * 1000,
                "steering_delay_s": self.steering_delay_s,
                "speed_delay_s": self.erpm_delay_s,
            },
            "lidar": {"mount": {"forward_mm": f, "left_mm": left, "yaw_rad": yaw}, "range_sigma_mm": self.range_sd_mm},
            "yaml": self.yaml(),
        }

    def yaml(self) -> JsonObject:
        return {
            "speed_to_erpm_gain": self.yaml_speed_gain,
            "speed_to_erpm_offset": self.yaml_speed_offset,
            "steering_angle_to_servo_gain": self.yaml_servo_gain,
            "steering_angle_to_servo_offset": self.yaml_servo_offset,
        }


# the track's centre line (m), counterclockwise: a loop with a notch, so that a lap turns both ways
CENTRE = np.array([(-7, -4), (7, -4), (7, 4), (2, 4), (2, 0), (-2, 0), (-2, 4), (-7, 4)], dtype=float)


def corridor_track(scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Corridors 2 m wide around ``CENTRE``, with alcoves and pillars along the walls (what a scan matcher
    holds on to in a corridor), all ``scale`` times larger: prisms as ``core.raycast`` casts them, in m."""
    h = FURNITURE_HEIGHT_M
    boxes = [
        (-8.05, -5.05, 8.05, -5.0),  # the outer walls
        (-8.05, 5.0, 8.05, 5.05),
        (-8.05, -5.05, -8.0, 5.05),
        (8.0, -5.05, 8.05, 5.05),
        (-6.0, -3.0, -3.0, 3.0),  # the blocks the corridors run around
        (3.0, -3.0, 6.0, 3.0),
        (-3.0, -3.0, 3.0, -1.0),
        (-1.0, 1.0, 1.0, 5.0),
        (-5.0, -5.0, -4.6, -4.75),  # door frames and cabinets along the walls
        (-0.5, -5.0, 0.3, -4.8),
        (4.2, -5.0, 4.5, -4.7),
        (7.7, -1.5, 8.0, -0.9),
        (7.8, 2.0, 8.0, 2.6),
        (4.5, 4.7, 5.3, 5.0),
        (-5.5, 4.8, -4.9, 5.0),
        (-8.0, 0.5, -7.75, 1.1),
        (-8.0, -2.6, -7.8, -2.2),
        (-2.4, -3.2, -1.6, -3.0),
        (1.2, -3.15, 2.0, -3.0),
    ]
    cylinders = [(-2.0, -1.2, 0.12), (6.3, 0.0, 0.1), (-6.3, -1.0, 0.1), (0.0, 0.8, 0.1), (5.0, 3.2, 0.08)]
    kind = np.array([raycast.BOX] * len(boxes) + [raycast.CYLINDER] * len(cylinders), dtype=np.int64)
    params = np.array([(*b, h) for b in boxes] + [(*c, h, 0.0) for c in cylinders], dtype=float)
    params[:, :4] *= np.where(kind[:, None] == raycast.BOX, scale, [scale, scale, scale, 1.0])
    return kind, params


@dataclass(frozen=True)
class CarRun:
    """What the car recorded (ROS units) and where it truly was."""

    config: CarConfig
    drive_t: np.ndarray
    drive_speed_m_s: np.ndarray
    drive_angle_rad: np.ndarray
    servo_t: np.ndarray
    servo: np.ndarray  # the servo position the driver sent (the yaml's mapping of /drive)
    vesc_t: np.ndarray  # the VESC's stamps (erpm_delay_s late)
    erpm: np.ndarray
    odom_t: np.ndarray
    odom_pose: np.ndarray  # (n, 3) x_m, y_m, yaw: vesc_to_odom through the yaml's numbers
    odom_twist: np.ndarray  # (n, 2) v_m_s, omega_rad_s
    scan_t: np.ndarray
    ranges_m: np.ndarray  # (scans, beams), inf where nothing came back
    angle_min_rad: float
    angle_increment_rad: float
    time_increment_s: float
    truth_t: np.ndarray
    truth_pose: np.ndarray  # (n, 3) x_m, y_m, yaw of the rear axle's middle

    def log(self, source: str = "simulated") -> CarLog:
        cfg = self.config
        f, left, yaw = cfg.urdf_mount
        return CarLog(
            source=source,
            scan_t=self.scan_t,
            ranges_mm=np.where(np.isfinite(self.ranges_m), self.ranges_m * 1000, np.nan),
            scan=ScanGeometry(
                self.angle_min_rad, self.angle_increment_rad, self.time_increment_s, cfg.range_min_mm, cfg.range_max_mm
            ),
            erpm_t=self.vesc_t,
            erpm=self.erpm,
            servo_t=self.servo_t,
            servo=self.servo,
            drive_t=self.drive_t,
            drive=np.column_stack([self.drive_speed_m_s, self.drive_angle_rad]),
            urdf=UrdfGuess(Pose2(f, left, yaw), LIDAR_HEIGHT_M * 1000, lidar_frame="laser", base_frame="base_link"),
            odom_t=self.odom_t,
            odom=self.odom_twist,
            truth_t=self.truth_t,
            truth_pose=self.truth_pose * (1000, 1000, 1),
            truth=cfg.truth(),
        )


def _route(laps: int, scale: float) -> np.ndarray:
    """The centre line's corners, lap after lap."""
    return np.vstack([np.tile(CENTRE, (laps, 1)), CENTRE[:1]]) * scale


def _densify(corners: np.ndarray, step: float = 0.05) -> np.ndarray:
    out = []
    for a, b in itertools.pairwise(corners):
        n = max(1, int(np.ceil(np.hypot(*(b - a)) / step)))
        out.append(a + (b - a) * np.arange(n)[:, None] / n)
    return np.vstack([*out, corners[-1:]])


def simulate_car(cfg: CarConfig | None = None) -> CarRun:
    cfg = cfg or CarConfig()
    rng = np.random.default_rng(cfg.seed)
    dt = 0.005
    n = round(cfg.seconds / dt)
    t = np.arange(n + 1) * dt
    laps = int(cfg.seconds * cfg.speed_max_m_s / (44 * cfg.scale)) + 2  # a lap is 44 m
    path = _densify(_route(laps, cfg.scale))
    look = cfg.lookahead_m * cfg.scale
    pose = np.zeros((n + 1, 3))
    pose[0] = (*CENTRE[0] * cfg.scale, 0.0)  # the first corner, heading along the bottom corridor
    erpm = np.zeros(n + 1)
    servo_cmd = np.zeros(n + 1)
    drive = np.zeros((n + 1, 2))
    k_drive = max(1, round(1 / (cfg.drive_hz * dt)))
    delay = round(cfg.steering_delay_s / dt)
    target, next_change, near = cfg.speed_min_m_s, 0.0, 0
    v_cmd = d_cmd = 0.0
    lag = dt / max(cfg.motor_lag_s, dt)
    for k in range(n):
        if k % k_drive == 0:  # the controller: pure pursuit on the centre line
            x, y, th = pose[k]
            window = path[near : near + 200]
            near += int(np.argmin(np.hypot(window[:, 0] - x, window[:, 1] - y)))
            ahead = path[near:]
            far = np.flatnonzero(np.hypot(ahead[:, 0] - x, ahead[:, 1] - y) >= look)
            gx, gy = ahead[far[0]] if far.size else ahead[-1]
            alpha = math.atan2(gy - y, gx - x) - th
            d_cmd = math.atan2(2 * cfg.wheelbase_m * math.sin(alpha), look)  # the owner's wheelbase
            if t[k] >= next_change:
                target = float(rng.uniform(cfg.speed_min_m_s, cfg.speed_max_m_s))
                next_change = t[k] + float(rng.uniform(2.0, 6.0))
            v_cmd = min(t[k] / 2.0, 1.0) * target  # a gentle start
            d_cmd = float(np.clip(d_cmd, -MAX_STEER_RAD, MAX_STEER_RAD))
        drive[k] = v_cmd, d_cmd
        # the VESC driver: the yaml's numbers
        erpm_cmd = cfg.yaml_speed_gain * v_cmd + cfg.yaml_speed_offset
        servo_cmd[k] = cfg.yaml_servo_gain * d_cmd + cfg.yaml_servo_offset
        erpm[k + 1] = erpm[k] + (erpm_cmd - erpm[k]) * lag
        # the car: the true numbers
        v = (erpm[k] - cfg.speed_to_erpm_offset) / cfg.speed_to_erpm_gain
        s_in = servo_cmd[k - delay] if k >= delay else servo_cmd[0]
        delta = (s_in - cfg.steering_angle_to_servo_offset) / cfg.steering_angle_to_servo_gain
        delta = float(np.clip(delta, -STOP_RAD, STOP_RAD))
        ds = v * dt * (1 + cfg.slip_sd * rng.standard_normal())
        dth = ds * math.tan(delta) / cfg.wheelbase_m * (1 + cfg.slip_sd * rng.standard_normal())
        mid = pose[k, 2] + dth / 2
        pose[k + 1] = pose[k] + (ds * math.cos(mid), ds * math.sin(mid), dth)
    servo_cmd[n], drive[n] = servo_cmd[n - 1], drive[n - 1]  # the last command holds to the end
    vesc_idx = np.unique(np.round(np.arange(0, cfg.seconds, 1 / cfg.vesc_hz) / dt).astype(int))
    drive_idx = np.arange(0, n + 1, k_drive)
    erpm_read = erpm[vesc_idx] + cfg.erpm_sd * rng.standard_normal(vesc_idx.size)
    # vesc_to_odom, as each report arrives: the yaml's numbers, the last servo command sent, and its wheelbase (the
    # owner's, right here)
    v_o = (erpm_read - cfg.yaml_speed_offset) / cfg.yaml_speed_gain
    sent = np.searchsorted(t[drive_idx], t[vesc_idx] + cfg.erpm_delay_s, side="right") - 1
    s_at = servo_cmd[drive_idx][np.clip(sent, 0, drive_idx.size - 1)]
    w_o = v_o * np.tan((s_at - cfg.yaml_servo_offset) / cfg.yaml_servo_gain) / cfg.wheelbase_m
    odt = np.diff(t[vesc_idx], prepend=t[vesc_idx][0])
    th_o = np.cumsum(w_o * odt)
    odom = np.column_stack([np.cumsum(v_o * np.cos(th_o) * odt), np.cumsum(v_o * np.sin(th_o) * odt), th_o])
    # the scans: a sweep of 25 ms a revolution, stamped at the first beam
    period = 1 / cfg.scan_hz
    scan_t = np.arange(0.5, cfg.seconds - period - 0.05, period)
    fov = np.radians(cfg.fov_deg)
    inc = fov / (cfg.beams - 1)
    angles = -fov / 2 + inc * np.arange(cfg.beams)
    tinc = 0.025 / (2 * np.pi / inc)
    beam_t = (scan_t[:, None] + tinc * np.arange(cfg.beams)).ravel()
    at = np.column_stack([np.interp(beam_t, t, pose[:, j]) for j in range(3)])
    fwd, left, yaw = cfg.mount[0] / 1000, cfg.mount[1] / 1000, cfg.mount[2]
    c, s = np.cos(at[:, 2]), np.sin(at[:, 2])
    lx, ly = at[:, 0] + c * fwd - s * left, at[:, 1] + s * fwd + c * left
    heading = at[:, 2] + yaw + np.tile(angles, scan_t.size)
    kind, params = corridor_track(cfg.scale)
    origin, cell, shape, start, items = raycast.build_grid(kind, params, 0.5)
    hits = np.zeros(beam_t.size)
    max_m = cfg.range_max_mm / 1000 * 1.5
    cast_beams(lx, ly, heading, max_m, kind, params, origin, cell, int(shape[0]), int(shape[1]), start, items, hits)
    hits = np.where(hits > 0, hits + rng.standard_normal(hits.size) * cfg.range_sd_mm / 1000, np.inf)
    hits[(hits < cfg.range_min_mm / 1000) | (hits > cfg.range_max_mm / 1000)] = np.inf
    return CarRun(
        config=cfg,
        drive_t=t[drive_idx],
        drive_speed_m_s=drive[drive_idx, 0],
        drive_angle_rad=drive[drive_idx, 1],
        servo_t=t[drive_idx],
        servo=servo_cmd[drive_idx],
        vesc_t=t[vesc_idx] + cfg.erpm_delay_s,
        erpm=erpm_read,
        odom_t=t[vesc_idx] + cfg.erpm_delay_s,
        odom_pose=odom,
        odom_twist=np.column_stack([v_o, w_o]),
        scan_t=scan_t,
        ranges_m=hits.reshape(scan_t.size, cfg.beams),
        angle_min_rad=float(angles[0]),
        angle_increment_rad=float(inc),
        time_increment_s=float(tinc),
        truth_t=t[vesc_idx],
        truth_pose=pose[vesc_idx],
    )
