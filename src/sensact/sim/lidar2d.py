"""A differential drive with wheel encoders and a mounted 2-D lidar in a furnished room (docs/lidar2d.md): what a
TurtleBot records, with the truth it does not know.

The robot's wheels turn as ``/cmd_vel`` asks through the URDF's nominal radius and axle, after
``delay_s``; each wheel moves the robot by its true radius times its turn, each step's travel off by
``slip_sd`` (the drive's noise). The encoders read the wheels' angles (``ticks_per_rev``), ``/odom``
integrates them with the nominal radius and axle, and the lidar, mounted at ``mount`` (not where the URDF
says, ``urdf_mount``), sweeps its beams counterclockwise through one revolution per scan (``sweep``; the
stamp is the first beam's time, as ROS's LaserScan says) with Gaussian range noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from sensact.core import raycast
from sensact.logs.lidar2d_log import Lidar2DLog, Pose2, ScanGeometry, UrdfGuess
from sensact.records import JsonObject

FURNITURE_HEIGHT_M = 1.0
LIDAR_HEIGHT_M = 0.2


@dataclass(frozen=True)
class Lidar2DConfig:
    """Every knob of the simulated robot (``--set name=value``), in mm, rad, s and Hz."""

    sensor: str = "lidar2d"
    seconds: float = 300.0
    seed: int = 0
    # the truth the learner is after
    wheel_radius_left_mm: float = 33.15
    wheel_radius_right_mm: float = 32.9
    axle_mm: float = 162.4
    mount: tuple[float, float, float] = (-8.0, 21.0, 0.06)  # forward_mm, left_mm, yaw_rad of the lidar
    range_sd_mm: float = 10.0
    slip_sd: float = 0.01  # of each wheel's travel per 10 ms step
    delay_s: float = 0.1  # from /cmd_vel to the wheels
    # what the URDF says (a datasheet's numbers)
    urdf_wheel_radius_mm: float = 33.0
    urdf_axle_mm: float = 160.0
    urdf_mount: tuple[float, float, float] = (-32.0, 0.0, 0.0)
    # the recording
    scan_hz: float = 5.0
    beams: int = 360
    fov_deg: float = 360.0  # the beams' span, centred ahead (a Hokuyo URG-04LX: 240)
    range_min_mm: float = 120.0
    range_max_mm: float = 3500.0
    sweep: bool = True  # beams taken one after another through the scan period (time_increment > 0)
    joint_hz: float = 30.0
    cmd_hz: float = 10.0
    ticks_per_rev: int = 4096
    encoder_positions: str = "rad"  # or "ticks": the wheels' positions as encoder counts, as some drivers publish
    # the driving: among waypoints, turning toward each and spinning at it, or "straight" back and forth along
    # its heading, never turning (a log that cannot fix the lidar's mount)
    pattern: str = "waypoints"
    speed_mm_s: float = 180.0
    turn_rate_rad_s: float = 1.5

    def __post_init__(self) -> None:
        problems = []
        if self.sensor != "lidar2d":
            problems.append(f"sensor is {self.sensor!r}; this simulator is the 2-D lidar's (sensor=lidar2d)")
        if not 10 <= self.seconds <= 36_000:
            problems.append("seconds must be in [10, 36000]")
        if min(self.wheel_radius_left_mm, self.wheel_radius_right_mm, self.axle_mm) <= 0:
            problems.append("wheel radii and axle_mm must be > 0")
        if min(self.urdf_wheel_radius_mm, self.urdf_axle_mm) <= 0:
            problems.append("urdf_wheel_radius_mm and urdf_axle_mm must be > 0")
        if self.range_sd_mm < 0 or self.slip_sd < 0 or not 0 <= self.delay_s <= 1:
            problems.append("range_sd_mm and slip_sd must be >= 0, delay_s in [0, 1]")
        if not (0.5 <= self.scan_hz <= 50 and 1 <= self.joint_hz <= 1000 and 1 <= self.cmd_hz <= 100):
            problems.append("scan_hz must be in [0.5, 50], joint_hz in [1, 1000], cmd_hz in [1, 100]")
        if not 16 <= self.beams <= 4096:
            problems.append("beams must be in [16, 4096]")
        if not 0 < self.range_min_mm < self.range_max_mm <= 100_000:
            problems.append("need 0 < range_min_mm < range_max_mm <= 100000")
        if self.ticks_per_rev < 0 or not (0 < self.speed_mm_s <= 2000 and 0 < self.turn_rate_rad_s <= 10):
            problems.append(
                "ticks_per_rev must be >= 0 (0: exact angles), speed_mm_s in (0, 2000], turn_rate in (0, 10]"
            )
        if self.pattern not in ("waypoints", "straight"):
            problems.append(f"pattern must be waypoints or straight, not {self.pattern!r}")
        if not 10 <= self.fov_deg <= 360 or self.encoder_positions not in ("rad", "ticks"):
            problems.append("fov_deg must be in [10, 360], encoder_positions rad or ticks")
        if self.encoder_positions == "ticks" and not self.ticks_per_rev:
            problems.append("encoder_positions=ticks needs ticks_per_rev > 0")
        if problems:
            raise ValueError("; ".join(problems) + " (docs/lidar2d.md).")

    @property
    def per_position(self) -> float:
        """Radians of wheel turn per unit of the logged positions."""
        return 2 * np.pi / self.ticks_per_rev if self.encoder_positions == "ticks" else 1.0

    def truth(self) -> JsonObject:
        """The true models; the radii per unit of the logged positions (mm per tick for ticks)."""
        f, left, yaw = self.mount
        return {
            "drive": {
                "wheel_radius_left_mm": self.wheel_radius_left_mm * self.per_position,
                "wheel_radius_right_mm": self.wheel_radius_right_mm * self.per_position,
                "axle_mm": self.axle_mm,
                "delay_s": self.delay_s,
                "slip_sd": self.slip_sd,
            },
            "lidar": {
                "mount": {"forward_mm": f, "left_mm": left, "yaw_rad": yaw},
                "range_sigma_mm": self.range_sd_mm,
            },
        }

    def urdf(self) -> JsonObject:
        f, left, yaw = self.urdf_mount
        return {
            "lidar_mount": {"forward_mm": f, "left_mm": left, "yaw_rad": yaw, "up_mm": LIDAR_HEIGHT_M * 1000},
            "wheel_radius_mm": self.urdf_wheel_radius_mm * self.per_position,
            "axle_mm": self.urdf_axle_mm,
        }


def furnished_room() -> tuple[np.ndarray, np.ndarray]:
    """A 6 m by 5 m room (its middle at the origin) with a table on four legs, shelves, a sofa, a pillar and
    bins: prisms as ``core.raycast`` casts them, in m."""
    boxes = [
        (-3.05, -2.55, 3.05, -2.5),  # walls
        (-3.05, 2.5, 3.05, 2.55),
        (-3.05, -2.55, -3.0, 2.55),
        (3.0, -2.55, 3.05, 2.55),
        (-2.95, 1.6, -1.2, 2.45),  # sofa
        (1.0, 2.05, 2.6, 2.45),  # shelves
        (2.55, -2.45, 2.95, -0.9),  # cabinet
        (-2.95, -2.45, -2.35, -1.7),  # desk
        (0.2, -2.45, 0.9, -2.15),  # a box by the wall
    ]
    cylinders = [(-1.3, -1.25, 0.025), (-0.1, -1.25, 0.025), (-1.3, -0.55, 0.025), (-0.1, -0.55, 0.025)]  # table legs
    cylinders += [(1.6, 0.4, 0.15), (2.4, 1.4, 0.12), (-2.3, 0.3, 0.18), (0.9, -1.5, 0.09)]  # pillar, bins, plant
    kind = np.array([raycast.BOX] * len(boxes) + [raycast.CYLINDER] * len(cylinders), dtype=np.int64)
    params = np.array(
        [(*b, FURNITURE_HEIGHT_M) for b in boxes] + [(*c, FURNITURE_HEIGHT_M, 0.0) for c in cylinders], dtype=float
    )
    return kind, params


# waypoints the robot drives among, clear of the furniture (m)
WAYPOINTS = np.array(
    [(-1.8, 0.6), (0.4, 1.3), (1.9, -0.1), (1.2, -1.1), (-0.6, 0.1), (-2.2, -0.8), (0.5, -0.2), (1.5, 1.2)]
)


@njit(cache=True, parallel=True)
def cast_beams(px, py, heading, max_range, kind, params, origin, cell, nx, ny, start, items, out):
    for k in prange(px.size):
        out[k] = raycast.cast_ray(
            px[k], py[k], LIDAR_HEIGHT_M, np.cos(heading[k]), np.sin(heading[k]), 0.0, max_range,
            kind, params, origin, cell, nx, ny, start, items,
        )  # fmt: skip


@dataclass(frozen=True)
class Lidar2DRun:
    """What the robot recorded (ROS units: m, rad, s) and where it truly was."""

    config: Lidar2DConfig
    cmd_t: np.ndarray
    cmd_v_m_s: np.ndarray
    cmd_omega_rad_s: np.ndarray
    joint_t: np.ndarray
    wheel_rad: np.ndarray  # (n, 2) left, right encoder angles
    odom_t: np.ndarray
    odom_pose: np.ndarray  # (n, 3) x_m, y_m, yaw from the encoders and the nominal radius and axle
    odom_twist: np.ndarray  # (n, 2) v_m_s, omega_rad_s
    scan_t: np.ndarray  # each scan's stamp: its first beam's time
    ranges_m: np.ndarray  # (scans, beams), inf where nothing came back
    angle_min_rad: float
    angle_increment_rad: float
    time_increment_s: float
    truth_t: np.ndarray
    truth_pose: np.ndarray  # (n, 3) x_m, y_m, yaw of the axle's middle

    def log(self, source: str = "simulated") -> Lidar2DLog:
        """The run as sensact reads it (mm), driven by its encoders, the URDF's guess and the truth beside."""
        cfg = self.config
        urdf = cfg.urdf()
        m = urdf["lidar_mount"]
        return Lidar2DLog(
            source=source,
            scan_t=self.scan_t,
            ranges_mm=np.where(np.isfinite(self.ranges_m), self.ranges_m * 1000, np.nan),
            scan=ScanGeometry(
                self.angle_min_rad, self.angle_increment_rad, self.time_increment_s, cfg.range_min_mm, cfg.range_max_mm
            ),
            drive="wheels",
            drive_t=self.joint_t,
            drive_values=self.wheel_rad,
            urdf=UrdfGuess(
                Pose2(m["forward_mm"], m["left_mm"], m["yaw_rad"]),
                m["up_mm"],
                urdf["wheel_radius_mm"],
                urdf["axle_mm"],
            ),
            truth_t=self.truth_t,
            truth_pose=self.truth_pose * (1000, 1000, 1),
            truth=cfg.truth(),
        )

    def tables(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """wheels.csv, odom.csv and cmd_vel.csv's times and values (mm)."""
        return {
            "wheels": (self.joint_t, self.wheel_rad),
            "odom": (self.odom_t, self.odom_pose * (1000, 1000, 1)),
            "cmd_vel": (self.cmd_t, np.column_stack([self.cmd_v_m_s * 1000, self.cmd_omega_rad_s])),
        }


def _controller(cfg: Lidar2DConfig, rng: np.random.Generator, x: float, y: float, th: float, state: list) -> tuple:
    """/cmd_vel toward the current waypoint: turn in place when far off it, else drive and steer; at each
    waypoint a spin of random size (the turns that make the lidar's mount observable)."""
    v_max, w_max = cfg.speed_mm_s / 1000, cfg.turn_rate_rad_s
    if cfg.pattern == "straight":  # 4 s forward, 4 s back
        state[0] += 1
        return (v_max if (state[0] // int(4 * cfg.cmd_hz)) % 2 == 0 else -v_max), 0.0
    if state[1] > 0:  # spinning
        state[1] -= 1
        return 0.0, state[2]
    gx, gy = WAYPOINTS[state[0]]
    err = np.arctan2(gy - y, gx - x) - th
    err = (err + np.pi) % (2 * np.pi) - np.pi
    if np.hypot(gx - x, gy - y) < 0.15:
        state[0] = int(rng.integers(len(WAYPOINTS) - 1))
        state[0] += state[0] >= np.flatnonzero((WAYPOINTS == (gx, gy)).all(axis=1))[0]
        state[1] = int(rng.integers(0, 3 * cfg.cmd_hz))
        state[2] = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.4, 1.0) * w_max)
        return 0.0, 0.0
    if abs(err) > 0.6:  # turn in place, the way first chosen (a goal behind would flip it every step)
        state[3] = state[3] or float(np.sign(err))
        return 0.0, state[3] * w_max
    state[3] = 0.0
    w = float(np.clip(2.0 * err, -w_max, w_max))
    return v_max * (1 - abs(err) / 0.8), w


def simulate_lidar2d(cfg: Lidar2DConfig | None = None) -> Lidar2DRun:
    cfg = cfg or Lidar2DConfig()
    rng = np.random.default_rng(cfg.seed)
    dt = 0.01
    n = round(cfg.seconds / dt)
    t = np.arange(n + 1) * dt
    r0, b0 = cfg.urdf_wheel_radius_mm / 1000, cfg.urdf_axle_mm / 1000
    rl, rr, b = cfg.wheel_radius_left_mm / 1000, cfg.wheel_radius_right_mm / 1000, cfg.axle_mm / 1000
    cmd_every = max(1, round(1 / (cfg.cmd_hz * dt)))
    delay = round(cfg.delay_s / dt)
    pose = np.zeros((n + 1, 3))
    phi = np.zeros((n + 1, 2))
    cmds = np.zeros((n + 1, 2))
    state = [0, 0, 0.0, 0.0]  # waypoint, spin steps left, spin rate, turn-in-place direction
    v_c = w_c = 0.0
    for k in range(n):
        if k % cmd_every == 0:
            v_c, w_c = _controller(cfg, rng, *pose[k], state)
        cmds[k] = v_c, w_c
        v_in, w_in = cmds[k - delay] if k >= delay else (0.0, 0.0)
        dphi = np.array([(v_in - w_in * b0 / 2) / r0, (v_in + w_in * b0 / 2) / r0]) * dt
        phi[k + 1] = phi[k] + dphi
        travel = np.array([rl, rr]) * dphi * (1 + cfg.slip_sd * rng.standard_normal(2))
        ds, dth = travel.mean(), (travel[1] - travel[0]) / b
        mid = pose[k, 2] + dth / 2
        pose[k + 1] = pose[k] + (ds * np.cos(mid), ds * np.sin(mid), dth)
    cmd_idx = np.arange(0, n + 1, cmd_every)
    joint_idx = np.unique(np.round(np.arange(0, cfg.seconds, 1 / cfg.joint_hz) / dt).astype(int))
    wheel = phi[joint_idx]
    if cfg.ticks_per_rev:
        tick = 2 * np.pi / cfg.ticks_per_rev
        wheel = np.round(wheel / tick) * tick
    # /odom: the encoders' angles through the nominal radius and axle
    d = np.diff(wheel, axis=0) * r0
    ds, dth = d.mean(axis=1), (d[:, 1] - d[:, 0]) / b0
    th = np.concatenate([[0.0], np.cumsum(dth)])
    mid = th[:-1] + dth / 2
    odom = np.column_stack(
        [np.concatenate([[0.0], np.cumsum(ds * np.cos(mid))]), np.concatenate([[0.0], np.cumsum(ds * np.sin(mid))]), th]
    )
    jdt = np.diff(t[joint_idx])
    twist = np.vstack([[0.0, 0.0], np.column_stack([ds / jdt, dth / jdt])])
    # the scans
    period = 1 / cfg.scan_hz
    scan_t = np.arange(0.5, cfg.seconds - period - 0.05, period)
    fov = np.radians(cfg.fov_deg)
    inc = fov / cfg.beams
    angles = -fov / 2 + inc * np.arange(cfg.beams)
    tinc = period * (fov / (2 * np.pi)) / cfg.beams if cfg.sweep else 0.0
    beam_t = (scan_t[:, None] + tinc * np.arange(cfg.beams)).ravel()
    unwrapped = pose.copy()
    at = np.column_stack([np.interp(beam_t, t, unwrapped[:, j]) for j in range(3)])
    fwd, left, yaw = cfg.mount[0] / 1000, cfg.mount[1] / 1000, cfg.mount[2]
    c, s = np.cos(at[:, 2]), np.sin(at[:, 2])
    lx, ly = at[:, 0] + c * fwd - s * left, at[:, 1] + s * fwd + c * left
    heading = at[:, 2] + yaw + np.tile(angles, scan_t.size)
    kind, params = furnished_room()
    grid = raycast.build_grid(kind, params, 0.5)
    origin, cell, shape, start, items = grid
    hits = np.zeros(beam_t.size)
    max_m = cfg.range_max_mm / 1000 * 1.5
    cast_beams(lx, ly, heading, max_m, kind, params, origin, cell, int(shape[0]), int(shape[1]), start, items, hits)
    hits = np.where(hits > 0, hits + rng.standard_normal(hits.size) * cfg.range_sd_mm / 1000, np.inf)
    hits[(hits < cfg.range_min_mm / 1000) | (hits > cfg.range_max_mm / 1000)] = np.inf
    return Lidar2DRun(
        config=cfg,
        cmd_t=t[cmd_idx],
        cmd_v_m_s=cmds[cmd_idx, 0],
        cmd_omega_rad_s=cmds[cmd_idx, 1],
        joint_t=t[joint_idx],
        wheel_rad=wheel / cfg.per_position,
        odom_t=t[joint_idx],
        odom_pose=odom,
        odom_twist=twist,
        scan_t=scan_t,
        ranges_m=hits.reshape(scan_t.size, cfg.beams),
        angle_min_rad=float(angles[0]),
        angle_increment_rad=float(inc),
        time_increment_s=float(tinc),
        truth_t=t[joint_idx],
        truth_pose=pose[joint_idx],
    )
