"""The chapter-5 world: a car with a Velodyne HDL-64E driving through a small town (secs. 2.5.2, 5.4).

* **Car** (eqs. 2.30-2.34): ``a = C3 (C1 + C2 g - v) - C4 v b`` and ``omega = C9 v + C10 v s``, plus
  white process noise and what the model leaves out, as a real car has it: drag, a nonlinear and lagging
  throttle response, road grade, and understeer. They make the model good but not perfect: fitted to the
  truth itself it is about as far off as the thesis's From-Truth column.
* **Driver**: a script at 20 Hz produces throttle ``g``, brake ``b`` and steering ``s`` for a 200 s drive
  with three left turns, stops and accelerations, at up to about 6.3 m/s.
* **Town**: a ground plane, buildings along both sides of the streets the car drives, poles, trees and
  parked cars; all vertical prisms, ray-cast through a uniform grid (``sensact.core.raycast``).
* **HDL-64E** (sec. 2.5.2): 64 lasers firing together at ``f = 7800`` Hz while the unit turns clockwise (seen
  from above, as every Velodyne does) at 600 rpm; or another unit of ``sensact.models.spinning_lidar`` (``lidar``),
  each laser fired at its own delay into the firing;
  vertical angles and true horizontal angles from a ROS calibration file (``64e_utexas.yaml`` when the
  shared data is present, else the thesis's nominal geometry), a mounting yaw ``theta_b``, range noise,
  a maximum range and dropouts. The returns are written as the unit's real UDP packets in ``velodyne.pcap``.
* **Ground truth** in the manner of the Applanix: pose, velocity, acceleration and turn rate at 20 Hz.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sensact.core.raycast import BOX, CYLINDER, build_grid, cast_firings
from sensact.limits import steps_problem
from sensact.models.laser_intrinsics import LaserIntrinsics
from sensact.models.spinning_lidar import UNITS, LidarUnit
from sensact.records import JsonObject

TWO_PI = 2.0 * np.pi
TIME_ORIGIN_S = 1.6e9  # the capture clock of the written pcap at the start of the drive


def nominal_intrinsics() -> LaserIntrinsics:
    """The thesis's HDL-64E geometry (sec. 2.5.2): lower 32 lasers every 0.512° from -24.7°, upper 32 every
    0.340° from -8.5° to +2.0°; horizontal angles spanning -8° to +10° in a pattern like a factory file's."""
    vert = np.radians(np.concatenate([np.linspace(-8.5, 2.0, 32), np.linspace(-24.7, -8.9, 32)]))
    k = np.arange(64)
    horiz = np.radians(1.0 + 9.0 * np.sin(0.9 * k + 0.3 * (k // 32)))
    return LaserIntrinsics(vert, horiz)


def nominal_unit_intrinsics(unit: LidarUnit) -> LaserIntrinsics:
    """A unit's datasheet geometry; an OS-1-64's typical one (beams 0.53° apart from +16.6°, azimuths
    repeating +3.1°, +1.0°, -1.1°, -3.1° every four beams, as its metadata lists them)."""
    if unit.vertical_deg is not None and unit.rot_correction_deg is not None:
        return LaserIntrinsics(np.radians(unit.vertical_deg), np.radians(unit.rot_correction_deg))
    altitude = np.linspace(16.6, -16.6, unit.lasers)
    azimuth = np.resize([3.1, 1.0, -1.1, -3.1], unit.lasers)
    return LaserIntrinsics(np.radians(altitude), -np.radians(azimuth), 0.001)


@dataclass(frozen=True)
class CarConfig:
    """Every knob of the simulated drive. Overridable with ``--set name=value`` or ``--config file.yaml``."""

    seconds: float = 200.0  # sec. 5.4
    seed: int = 0
    control_hz: float = 20.0  # actions were recorded at roughly 20 Hz, sec. 5.4
    sim_hz: float = 100.0
    # true dynamics, eqs. 2.30-2.31 written with C1..C4 (sec. 2.5.2)
    c1_m_s: float = 0.0  # steady-state speed C1 + C2 g: a released car with no brake coasts to rest
    c2_m_s: float = 12.0
    c3_per_s: float = 0.35  # approach rate to the steady-state speed
    c4_per_s: float = 0.5  # braking: C4 v b
    c9_rad_m: float = 0.002  # omega = C9 v + C10 v s
    c10_rad_m: float = 0.11
    drag_per_m: float = 0.008  # not in the model: a -= drag v|v|
    throttle_curve_m_s: float = -3.0  # not in the model: the steady speed gains this times g^2 as well
    throttle_lag_s: float = 0.5  # not in the model: the engine follows the pedal with this time constant
    grade_pct: float = 2.0  # not in the model: the road rises and falls this much ...
    grade_wavelength_m: float = 150.0  # ... over this distance
    understeer_s2_m2: float = 0.01  # not in the model: omega shrinks by 1 / (1 + k v^2)
    accel_noise_m_s2: float = 0.1  # white process noise per sim step
    yaw_noise_rad_s: float = 0.002
    # the route: three left turns, stops, accelerations
    cruise_m_s: float = 6.2
    turn_m_s: float = 3.5
    turn_times_s: tuple[float, ...] = (35.0, 95.0, 150.0)
    stop_times_s: tuple[float, ...] = (30.0, 90.0, 145.0, 185.0)  # each turn starts from a stop, as in Fig. 5.4
    stop_hold_s: float = 4.0
    # the town along the route
    street_half_width_m: float = 7.0
    building_depth_m: tuple[float, float] = (8.0, 20.0)
    building_height_m: tuple[float, float] = (4.0, 18.0)
    building_gap_m: tuple[float, float] = (2.0, 12.0)
    pole_spacing_m: float = 25.0
    tree_spacing_m: float = 18.0
    parked_car_spacing_m: float = 30.0
    grid_cell_m: float = 8.0
    # the lidar, sec. 2.5.2: the thesis's HDL-64E, or an HDL-32E, VLP-32C, VLP-16, Puck Hi-Res or OS-1 (64 beams)
    lidar: str = "HDL-64E"
    calibration_yaml: str | None = None  # true angles (ROS YAML, or an OS-1's metadata JSON); None: the
    # model's file in the shared data (64e_utexas.yaml, 32db.yaml, VLP16db.yaml, ouster_example.json), else its
    # nominal geometry (read by sensact.app.velodyne_car.true_intrinsics)
    firing_hz: float | None = None  # f; None: the model's (HDL-64E: the thesis's 7800 Hz)
    rpm: float = 600.0  # |omega| = 20 pi rad/s
    clockwise: bool = True  # seen from above, as every Velodyne turns (theta_r, counterclockwise, falls)
    mount_yaw_deg: float = 89.1  # theta_b, sec. 5.4
    sensor_height_m: float = 2.0
    max_range_m: float = 120.0
    range_noise_m: float = 0.02
    dropout: float = 0.02
    chunk_s: float = 2.0  # firings simulated and written per chunk

    def __post_init__(self) -> None:
        problems = []
        if self.seconds <= 0 or self.control_hz <= 0 or self.sim_hz < self.control_hz:
            problems.append("seconds and control_hz must be > 0, sim_hz >= control_hz")
        elif (too_long := steps_problem(self.seconds * self.sim_hz, "seconds * sim_hz")) is not None:
            problems.append(too_long)
        if not 0 <= self.dropout < 1:
            problems.append("dropout must be in [0, 1)")
        if (self.firing_hz is not None and self.firing_hz <= 0) or self.rpm <= 0:
            problems.append("firing_hz and rpm must be > 0")
        if self.lidar not in UNITS:
            problems.append(f"lidar must be one of {', '.join(UNITS)}")
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def unit(self) -> LidarUnit:
        return UNITS[self.lidar]

    @property
    def firing_rate_hz(self) -> float:
        return self.firing_hz if self.firing_hz is not None else self.unit.firing_hz

    @property
    def omega_rad_s(self) -> float:
        """d theta_r / dt, counterclockwise (eq. 2.35)."""
        return (-1.0 if self.clockwise else 1.0) * self.rpm / 60.0 * TWO_PI

    def true_coefficients(self) -> dict[str, float]:
        """C5..C10 of eqs. 2.30-2.31 from C1..C4 (the drag is not among them)."""
        return {
            "C5": self.c3_per_s * self.c1_m_s,
            "C6": self.c3_per_s * self.c2_m_s,
            "C7": -self.c3_per_s,
            "C8": -self.c4_per_s,
            "C9": self.c9_rad_m,
            "C10": self.c10_rad_m,
        }


@dataclass(frozen=True, eq=False)
class Drive:
    """The drive at the control rate: actions and the Applanix-like truth."""

    times_s: np.ndarray  # (K,)
    throttle: np.ndarray
    brake: np.ndarray
    steering: np.ndarray
    poses: np.ndarray  # (K, 3) x, y (m), theta (rad; 0 faces +y)
    speed_m_s: np.ndarray
    accel_m_s2: np.ndarray
    omega_rad_s: np.ndarray
    sim_times_s: np.ndarray  # (S,) the fine simulation grid
    sim_poses: np.ndarray  # (S, 3)


def _drive(cfg: CarConfig, rng: np.random.Generator) -> Drive:
    """Integrate the car under the scripted driver (eqs. 2.32-2.34 at ``sim_hz``)."""
    dt = 1.0 / cfg.sim_hz
    per = round(cfg.sim_hz / cfg.control_hz)
    S = round(cfg.seconds * cfg.sim_hz) + 1
    x = y = th = v = odo_m = engine = 0.0
    heading_goal = 0.0
    turning_until_heading: float | None = None
    g = b = s = 0.0
    out_t, out_g, out_b, out_s, out_pose, out_v, out_a, out_w = [], [], [], [], [], [], [], []
    sim_pose = np.empty((S, 3))
    turns = list(cfg.turn_times_s)
    for k in range(S):
        t = k * dt
        sim_pose[k] = (x, y, th)
        if k % per == 0:  # the driver acts at the control rate
            stopping = any(ts <= t < ts + cfg.stop_hold_s for ts in cfg.stop_times_s) or t < 2.0
            if turns and t >= turns[0] and turning_until_heading is None:
                turns.pop(0)
                turning_until_heading = heading_goal + np.pi / 2
            if turning_until_heading is not None and th >= turning_until_heading - 0.05:
                heading_goal = turning_until_heading
                turning_until_heading = None
            target = 0.0 if stopping else (cfg.turn_m_s if turning_until_heading is not None else cfg.cruise_m_s)
            err = target - v
            steady_g = (target - cfg.c1_m_s) / cfg.c2_m_s if target > 0 else 0.0  # the driver's rough idea
            g = float(np.clip(steady_g + 0.35 * err, 0.0, 1.0)) if target > 0 else 0.0
            b = float(np.clip(-0.6 * err, 0.0, 1.0)) if (err < -0.3 or target == 0.0) else 0.0
            if target == 0.0:
                b = 1.0 if v > 0.05 else 0.5
            if turning_until_heading is not None:
                s = 0.5
            else:
                s = float(np.clip(2.5 * (heading_goal - th) - cfg.c9_rad_m / cfg.c10_rad_m, -1.0, 1.0))
            out_t.append(t)
            out_g.append(g)
            out_b.append(b)
            out_s.append(s)
        engine += (g - engine) * min(1.0, dt / cfg.throttle_lag_s) if cfg.throttle_lag_s > 0 else g - engine
        steady = cfg.c1_m_s + cfg.c2_m_s * engine + cfg.throttle_curve_m_s * engine * engine
        grade = 0.01 * cfg.grade_pct * np.sin(2 * np.pi * odo_m / cfg.grade_wavelength_m)
        a = cfg.c3_per_s * (steady - v) - cfg.c4_per_s * v * b - cfg.drag_per_m * v * abs(v) - 9.81 * grade
        a += rng.normal() * cfg.accel_noise_m_s2
        w = (cfg.c9_rad_m * v + cfg.c10_rad_m * v * s) / (1.0 + cfg.understeer_s2_m2 * v * v)
        w += rng.normal() * cfg.yaw_noise_rad_s
        if k % per == 0:
            out_pose.append((x, y, th))
            out_v.append(v)
            out_a.append(a)
            out_w.append(w)
        # eq. 2.32 (R(theta) applied to forward motion; theta = 0 faces +y), 2.33, 2.34
        x += -np.sin(th) * v * dt
        y += np.cos(th) * v * dt
        th += w * dt
        odo_m += v * dt
        v = max(0.0, v + a * dt)
    return Drive(
        np.asarray(out_t),
        np.asarray(out_g),
        np.asarray(out_b),
        np.asarray(out_s),
        np.asarray(out_pose),
        np.asarray(out_v),
        np.asarray(out_a),
        np.asarray(out_w),
        np.arange(S) * dt,
        sim_pose,
    )


def _town(cfg: CarConfig, path_xy: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Buildings, poles, trees and parked cars along both sides of the route, never on it."""
    from scipy.spatial import cKDTree

    tree = cKDTree(path_xy)
    lo, hi = path_xy.min(axis=0) - 80.0, path_xy.max(axis=0) + 80.0
    kinds, params = [], []

    def clear(x0: float, y0: float, x1: float, y1: float, margin: float) -> bool:
        cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        r = 0.5 * np.hypot(x1 - x0, y1 - y0) + margin
        near = tree.query_ball_point((cx, cy), r)
        if not near:
            return True
        p = path_xy[near]
        dx = np.maximum(np.maximum(x0 - p[:, 0], p[:, 0] - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - p[:, 1], p[:, 1] - y1), 0.0)
        return bool(np.all(np.hypot(dx, dy) >= margin))

    # rows of buildings on a coarse grid covering the neighbourhood, kept only where off the streets
    for axis in (0, 1):
        pos = lo[axis]
        while pos < hi[axis]:
            length = rng.uniform(10.0, 30.0)
            depth = rng.uniform(*cfg.building_depth_m)
            for other in np.arange(lo[1 - axis], hi[1 - axis], rng.uniform(25.0, 45.0)):
                a0, a1 = pos, pos + length
                b0, b1 = other, other + depth
                box = (a0, b0, a1, b1) if axis == 0 else (b0, a0, b1, a1)
                if clear(*box, cfg.street_half_width_m):
                    kinds.append(BOX)
                    params.append((*box, rng.uniform(*cfg.building_height_m)))
            pos += length + rng.uniform(*cfg.building_gap_m)
    # street furniture along the route
    seg = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path_xy, axis=0).T))]
    for spacing, offset, kind, size in (
        (cfg.pole_spacing_m, 5.0, CYLINDER, (0.15, 7.0)),
        (cfg.tree_spacing_m, 5.8, CYLINDER, (0.4, 5.0)),
        (cfg.parked_car_spacing_m, 4.2, BOX, (1.9, 1.5)),
    ):
        for s in np.arange(rng.uniform(0, spacing), seg[-1], spacing):
            i = min(np.searchsorted(seg, s), len(path_xy) - 2)
            d = path_xy[i + 1] - path_xy[i]
            n = np.array([-d[1], d[0]]) / (np.hypot(*d) + 1e-12)
            side = rng.choice((-1.0, 1.0))
            c = path_xy[i] + side * offset * n
            if kind == CYLINDER:
                if clear(c[0] - size[0], c[1] - size[0], c[0] + size[0], c[1] + size[0], 3.0):
                    kinds.append(CYLINDER)
                    params.append((c[0], c[1], size[0], size[1], 0.0))
            else:
                along = np.abs(d) / (np.hypot(*d) + 1e-12)
                hx = 2.3 * along[0] + 0.95 * along[1]
                hy = 2.3 * along[1] + 0.95 * along[0]
                box = (c[0] - hx, c[1] - hy, c[0] + hx, c[1] + hy)
                if clear(*box, 2.5):
                    kinds.append(BOX)
                    params.append((*box, size[1]))
    return np.asarray(kinds, dtype=np.int64), np.asarray(params, dtype=float)


@dataclass(frozen=True, eq=False)
class CarRun:
    config: CarConfig
    drive: Drive
    intrinsics: LaserIntrinsics  # the true geometry (horizontal = theta_l)
    kinds: np.ndarray
    params: np.ndarray

    @property
    def true_laser_angles_rad(self) -> np.ndarray:
        """theta_l + theta_b, what sec. 5.1 learns (indexed by laser id)."""
        return self.intrinsics.horizontal_rad + np.radians(self.config.mount_yaw_deg)


def simulate_drive(config: CarConfig | None = None, intrinsics: LaserIntrinsics | None = None) -> CarRun:
    """The drive and the town (no lidar yet). ``intrinsics`` is the true laser geometry (default: nominal)."""
    cfg = config or CarConfig()
    rng_drive, rng_town = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(2))
    drive = _drive(cfg, rng_drive)
    kinds, params = _town(cfg, drive.sim_poses[::10, :2], rng_town)
    return CarRun(cfg, drive, intrinsics or nominal_intrinsics(), kinds, params)


def scan_chunks(run: CarRun, progress=None):
    """Yield ``(firing_times_s, rotation_rad, distances_m (F, lasers))`` chunk by chunk over the drive; F is
    a whole number of the unit's packets."""
    cfg = run.config
    rng = np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(3)[2])
    origin, cell, shape, start, items = build_grid(run.kinds, run.params, cfg.grid_cell_m)
    per = cfg.unit.firings_per_packet
    hz = cfg.firing_rate_hz
    n_total = int(cfg.seconds * hz) // per * per
    chunk = max(per, int(cfg.chunk_s * hz) // per * per)
    d = run.drive
    heading = np.unwrap(d.sim_poses[:, 2])
    vert = run.intrinsics.vertical_rad
    # a laser that fires tau_l into its firing points omega tau_l further round (the car barely moves in
    # those microseconds)
    delay = np.asarray(cfg.unit.delay_s) if cfg.unit.velodyne else np.zeros(vert.size)  # an OS-1's fire at once
    horiz = run.intrinsics.horizontal_rad + cfg.omega_rad_s * delay
    mount = np.radians(cfg.mount_yaw_deg)
    for f0 in range(0, n_total, chunk):
        f = np.arange(f0, min(f0 + chunk, n_total))
        t = f / hz
        poses = np.column_stack(
            [
                np.interp(t, d.sim_times_s, d.sim_poses[:, 0]),
                np.interp(t, d.sim_times_s, d.sim_poses[:, 1]),
                np.interp(t, d.sim_times_s, heading),
            ]
        )
        rot = np.mod(cfg.omega_rad_s * t, TWO_PI)
        out = np.zeros((f.size, vert.size))
        cast_firings(
            poses,
            cfg.sensor_height_m,
            rot,
            vert,
            horiz,
            mount,
            cfg.max_range_m,
            run.kinds,
            run.params,
            origin,
            cell,
            shape[0],
            shape[1],
            start,
            items,
            out,
        )
        hit = out > 0
        out[hit] += rng.normal(size=hit.sum()) * cfg.range_noise_m
        out[rng.random(out.shape) < cfg.dropout] = 0.0
        out[(out < 0.5) | (out > cfg.max_range_m)] = 0.0
        if progress:
            progress(f"{cfg.lidar} scans", int(f[-1]) + 1, n_total)
        yield t, rot, out


def log_tables(run: CarRun) -> JsonObject:
    """The log folder's tables (meta, actions, ground truth); ``sensact.io.velodyne_car_folder.write_car_log`` writes
    them with the scans."""
    cfg = run.config
    d = run.drive
    return {
        "meta": {
            "platform": "car",
            "dt_s": 1.0 / cfg.control_hz,
            "actions": {"columns": ["throttle", "brake", "steering"]},
            "lidar": {
                "file": "velodyne.pcap",
                "model": cfg.lidar,
                "firing_hz": cfg.firing_rate_hz,
                "rpm": cfg.rpm,
                "time_origin_s": TIME_ORIGIN_S,
                "vertical_deg": np.degrees(run.intrinsics.vertical_rad).tolist(),  # factory-known, sec. 2.5.2
            },
            "simulator": {"name": "car", "seed": cfg.seed, "config": asdict(cfg)},
            "truth": {
                "coefficients": cfg.true_coefficients(),
                "laser_angles_rad": run.true_laser_angles_rad.tolist(),
                "mount_yaw_deg": cfg.mount_yaw_deg,
                "calibration": "calibration_true.yaml",
            },
        },
        "actions": {"t_s": d.times_s, "throttle": d.throttle, "brake": d.brake, "steering": d.steering},
        "groundtruth": {
            "t_s": d.times_s,
            "x_m": d.poses[:, 0],
            "y_m": d.poses[:, 1],
            "theta_rad": d.poses[:, 2],
            "speed_m_s": d.speed_m_s,
            "accel_m_s2": d.accel_m_s2,
            "omega_rad_s": d.omega_rad_s,
        },
    }


def log_summary(run: CarRun) -> JsonObject:
    d = run.drive
    turned = np.degrees(d.poses[-1, 2] - d.poses[0, 2])
    return {
        "seconds": run.config.seconds,
        "max_speed_m_s": float(d.speed_m_s.max()),
        "turned_deg": float(turned),
        "obstacles": len(run.kinds),
    }
