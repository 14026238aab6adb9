"""A differential-drive robot among barcoded landmarks: the conditions of the MRCLAM logs that EM on real
robots learns from (docs/em-real.md), with a known model to recover.

* The robot drives to random waypoints in a room ringed by landmarks, as MRCLAM's robots did: it turns
  in place towards a waypoint far off its heading, drives at up to 80 mm/s (MRCLAM's: 67-86) while
  steering at up to 0.4 rad/s, and waits a few seconds at each waypoint. The controller reads the true pose (the
  simulator's stand-in for the robot's own navigation).
* The commands it logs are continuous ``(v, omega)``, or (``wheel_axle_mm``) the wheel speeds they make,
  or (``sidestep_mm_s``, a robot that can side-step, as a legged one) ``(v, v_left, omega)``: such a robot
  walks at some waypoints straight at the waypoint without turning, forward and sideways at once;
  the robot obeys them ``delay_s`` late, through a first-order lag (a motor does not jump to a new
  speed), with an affine gain and bias. A differential drive does not side-step: its sideways
  velocity is 0 on average.
* Per-step motion noise in the robot frame (sideways, forward, heading), Gaussian.
* A camera sees landmarks inside its field of view and range at a frame rate; each landmark in view
  is detected with a probability. A sighting reads the range as ``gain d + offset + d (a_1 b + a_2
  b^2)`` (a range from a barcode's apparent size, distorted across the image; ``b`` the measured
  bearing) plus Gaussian noise, and the bearing plus Gaussian noise. A share of sightings are
  misread: range and bearing anywhere in the camera's reach.
* Or (``sensor: radio``) a range-only sensor, as UWB anchors or sonar beacons: every landmark in
  range, in any direction, is read at the frame rate with the detection probability, as ``gain d +
  offset`` plus noise, and the log has no bearings; a misread range is anywhere in reach.
* Optionally (``bearing_drift_sd_rad``, 0 by default), an effect the learner's model leaves out: a
  camera yaw error that every sighting shares and that wanders over seconds. The truth's bearing
  residual counts it as noise; a learner without ground truth can only read it as heading.

Units are the learner's: mm, rad, s. The pose frame is sensact's (sec. 2.5.1): ``theta = 0`` faces
world +y, the robot's forward axis is its +y.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.signal import lfilter

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, landmark_distance, sensor_poses
from sensact.limits import steps_problem
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.wheel_drive import WHEEL_COMMAND_NAMES
from sensact.records import JsonObject

COMMAND_NAMES = ("v_mm_s", "omega_rad_s")
SIDESTEP_COMMAND_NAMES = ("v_mm_s", "v_left_mm_s", "omega_rad_s")  # v_left: to the robot's left (ROS REP 103)
SENSORS = ("camera", "radio")


def wheel_speeds(commands: np.ndarray, axle_mm: float) -> np.ndarray:
    """``(v, omega)`` rows as the wheel speeds ``(v - omega B / 2, v + omega B / 2)`` of an axle ``B``."""
    c = np.asarray(commands, dtype=float)
    return np.column_stack([c[:, 0] - 0.5 * axle_mm * c[:, 1], c[:, 0] + 0.5 * axle_mm * c[:, 1]])


def from_wheel_coefficients(beta: np.ndarray, axle_mm: float) -> np.ndarray:
    """An affine model on the wheel speeds ``(1, left, right)`` rewritten on ``(1, v, omega)``: the same
    velocities, since ``Phi_wheels = Phi_(v, omega) T`` with ``T`` the wheel map, so ``beta_(v, omega) = T beta``."""
    h = 0.5 * axle_mm
    return np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0], [0.0, -h, h]]) @ np.asarray(beta, dtype=float)


def ring_of_landmarks(width_mm: float, length_mm: float, per_side: int) -> tuple[tuple[float, float], ...]:
    """Landmarks evenly spaced along the walls of a ``width x length`` room centred on the origin,
    ``per_side`` on each long wall and half as many on each short one (MRCLAM's 15 stand around a
    room about 4 m x 9 m)."""
    hw, hl = 0.5 * width_mm, 0.5 * length_mm
    ys = np.linspace(-hl, hl, per_side)
    xs = np.linspace(-hw, hw, max(per_side // 2, 2) + 2)[1:-1]
    pts = [(-hw, y) for y in ys] + [(hw, y) for y in ys] + [(x, -hl) for x in xs] + [(x, hl) for x in xs]
    return tuple((float(x), float(y)) for x, y in pts)


@dataclass(frozen=True)
class DiffDriveConfig:
    """Every knob of the simulated robot. Overridable with ``--set name=value`` or ``--config``."""

    seconds: float = 900.0  # MRCLAM Dataset 6 is about 890 s a robot
    seed: int = 0
    dt_s: float = 1.0 / 30.0  # the log's step (`convert mrclam`'s default)
    room_width_mm: float = 4000.0
    room_length_mm: float = 9000.0
    landmarks_per_side: int = 5
    margin_mm: float = 800.0  # waypoints stay this far inside the walls
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # the waypoint controller (its commands are what the log records)
    speed_mm_s: float = 80.0
    turn_rate_rad_s: float = 0.4
    steer_gain: float = 1.0  # omega command per rad of heading error, up to turn_rate_rad_s
    turn_in_place_rad: float = 0.5  # farther off the waypoint than this, turn without driving
    arrive_mm: float = 200.0
    max_wait_s: float = 8.0  # wait uniformly up to this long at each waypoint
    # the true action model: the velocity the robot reaches from a command
    forward_gain: float = 0.95
    forward_bias_mm_s: float = 3.0
    turn_gain: float = 0.92
    turn_bias_rad_s: float = 0.004
    # turn rate per mm/s of forward command: the curve a wheel mismatch gives a robot told to drive straight
    straight_turn_rad_per_mm: float = 0.0
    delay_s: float = 0.2
    lag_s: float = 0.1  # first-order lag's time constant (0 = none)
    # per-step motion noise in the robot frame
    sideways_sd_mm: float = 0.3
    forward_sd_mm: float = 1.5
    heading_sd_rad: float = 0.002
    # the sensor: "camera" (range and bearing inside fov_deg, the range distorted across the image by
    # range_bearing_terms) or "radio" (range alone, in every direction: fov_deg, the bearing terms and
    # the bearing's noise and drift do not apply, and the log has no bearings)
    sensor: str = "camera"
    frame_period_s: float = 0.24
    fov_deg: float = 68.0
    min_range_mm: float = 1000.0
    max_range_mm: float = 7000.0
    detect_probability: float = 0.3  # of each landmark in view, per frame
    range_gain: float = 1.03
    range_offset_mm: float = -40.0
    range_bearing_terms: tuple[float, float] = (0.0, 0.08)  # a_1, a_2
    range_sd_mm: float = 40.0
    bearing_sd_rad: float = 0.006
    misread_rate: float = 0.01
    # where the sensor sits on the robot: forward and left of the axle's middle (mm), and its yaw
    # (rad, counterclockwise); it reads the landmarks from there (learn/em/mount.py). Named apart from
    # EMConfig's sensor_mount, which holds the learner's mount, so that --set reaches the simulator
    mounted_at: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # an effect the learner's model leaves out (0 = none): a camera yaw error shared by every sighting that
    # wanders slowly (Ornstein-Uhlenbeck, stationary sd and time constant), as MRCLAM robot 1's bearing
    # residuals about Vicon hold (docs/em-real.md, Known limits); the truth's residual counts it as noise
    bearing_drift_sd_rad: float = 0.0
    bearing_drift_tau_s: float = 5.0
    # what the log records: 0 logs the controller's (v, omega); an axle length logs the wheel speeds
    # (left_mm_s, right_mm_s) the same commands make on it, as a robot driven wheel by wheel is logged
    wheel_axle_mm: float = 0.0
    # a robot that can side-step, as a legged one does (0 = a differential drive, which cannot): the controller's
    # largest sideways command, logged as v_left_mm_s; at a share of the waypoints (crab_share) it walks straight
    # at the waypoint without turning. The robot's sideways velocity is sideways_gain v_left + sideways_bias_mm_s
    sidestep_mm_s: float = 0.0
    crab_share: float = 0.5
    sideways_gain: float = 0.85
    sideways_bias_mm_s: float = 0.0
    # from this time on the robot's motors give only change_factor of every velocity they gave (sec. 4.4.3's
    # degradation, on a planar robot): what `sensact monitor` must notice; None: no change
    change_at_s: float | None = None
    change_factor: float = 0.75

    def __post_init__(self) -> None:
        problems = []
        if self.seconds <= 0 or self.dt_s <= 0 or self.frame_period_s < self.dt_s:
            problems.append("seconds and dt_s must be > 0, frame_period_s >= dt_s")
        elif (too_long := steps_problem(self.seconds / self.dt_s, "seconds / dt_s")) is not None:
            problems.append(too_long)
        if self.room_width_mm <= 2 * self.margin_mm or self.room_length_mm <= 2 * self.margin_mm:
            problems.append("the room must be wider and longer than twice margin_mm")
        if self.landmarks_per_side < 2:
            problems.append("landmarks_per_side must be >= 2")
        if not 0 < self.min_range_mm < self.max_range_mm:
            problems.append("need 0 < min_range_mm < max_range_mm")
        if not 0 < self.fov_deg < 360:
            problems.append("fov_deg must be in (0, 360)")
        if min(self.range_sd_mm, self.bearing_sd_rad) <= 0:
            problems.append("range_sd_mm and bearing_sd_rad must be > 0")
        if min(self.sideways_sd_mm, self.forward_sd_mm, self.heading_sd_rad, self.delay_s, self.lag_s) < 0:
            problems.append("motion noise, delay_s and lag_s must be >= 0")
        if self.wheel_axle_mm < 0:
            problems.append("wheel_axle_mm must be >= 0 (0 logs v and omega)")
        if self.sidestep_mm_s < 0 or not 0 <= self.crab_share <= 1:
            problems.append("sidestep_mm_s must be >= 0 (0 = a differential drive) and crab_share in [0, 1]")
        if self.sidestep_mm_s > 0 and self.wheel_axle_mm > 0:
            problems.append(
                "a robot that side-steps (sidestep_mm_s > 0) is not logged by two wheels' speeds (wheel_axle_mm)"
            )
        if self.sensor not in SENSORS:
            problems.append(f"sensor must be one of {', '.join(SENSORS)}, not {self.sensor!r}")
        if self.bearing_drift_sd_rad < 0 or self.bearing_drift_tau_s <= 0:
            problems.append("bearing_drift_sd_rad must be >= 0 and bearing_drift_tau_s > 0")
        if not (0 <= self.detect_probability <= 1 and 0 <= self.misread_rate < 1):
            problems.append("detect_probability must be in [0, 1] and misread_rate in [0, 1)")
        if self.speed_mm_s <= 0 or self.turn_rate_rad_s <= 0 or self.arrive_mm <= 0:
            problems.append("speed_mm_s, turn_rate_rad_s and arrive_mm must be > 0")
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def landmarks_xy_mm(self) -> tuple[tuple[float, float], ...]:
        return ring_of_landmarks(self.room_width_mm, self.room_length_mm, self.landmarks_per_side)

    @property
    def delay_steps(self) -> int:
        return round(self.delay_s / self.dt_s)

    @property
    def command_names(self) -> tuple[str, ...]:
        """The controller's commands, the rows of ``action_coefficients`` after the constant."""
        return SIDESTEP_COMMAND_NAMES if self.sidestep_mm_s > 0 else COMMAND_NAMES

    @property
    def reads_bearing(self) -> bool:
        return self.sensor == "camera"

    @property
    def robot_kind(self) -> str:
        return "side-stepping robot" if self.sidestep_mm_s > 0 else "differential drive"

    @property
    def logged_command_names(self) -> tuple[str, ...]:
        """The commands as the log records them: the controller's, or the wheel speeds they make."""
        return WHEEL_COMMAND_NAMES if self.wheel_axle_mm > 0 else self.command_names

    def action_coefficients(self) -> np.ndarray:
        """The true model in the learner's affine family (``LinearActionModel``): rows the features
        ``1, v, omega`` (``1, v, v_left, omega`` for a robot that side-steps), columns ``v_x`` (sideways,
        to the robot's right: sec. 2.5.1's frame, so a step to the left is a negative ``v_x``), ``v_y``
        (forward), ``v_theta``, lag aside."""
        # v_x is to the right: a bias to the left is negative (and a differential drive's 0.0, not -0.0)
        right_bias = -self.sideways_bias_mm_s if self.sidestep_mm_s > 0 and self.sideways_bias_mm_s else 0.0
        rows = [
            [right_bias, self.forward_bias_mm_s, self.turn_bias_rad_s],
            [0.0, self.forward_gain, self.straight_turn_rad_per_mm],
            [0.0, 0.0, self.turn_gain],
        ]
        if self.sidestep_mm_s > 0:
            rows.insert(2, [-self.sideways_gain, 0.0, 0.0])
        return np.array(rows)

    def range_reading(self, distance_mm: np.ndarray, bearing_rad: np.ndarray) -> np.ndarray:
        """The noise-free range reading at a distance and a (measured) bearing."""
        d, b = np.asarray(distance_mm, dtype=float), np.asarray(bearing_rad, dtype=float)
        a1, a2 = self.range_bearing_terms if self.reads_bearing else (0.0, 0.0)
        return self.range_gain * d + self.range_offset_mm + d * (a1 * b + a2 * b * b)

    def truth(self) -> JsonObject:
        """What the simulated robot really is, for meta.json (scoring only, never learned from)."""
        return {
            "kind": "diffdrive",
            "command_names": list(self.command_names),
            "action_coefficients": self.action_coefficients().tolist(),  # on (1, *command_names), whatever is logged
            "wheel_axle_mm": self.wheel_axle_mm,
            "delay_steps": self.delay_steps,
            "lag_s": self.lag_s,
            "motion_sd_per_step": [self.sideways_sd_mm, self.forward_sd_mm, self.heading_sd_rad],
            "range_bearing_terms": list(self.range_bearing_terms) if self.reads_bearing else [],
            "range_sigma_mm": self.range_sd_mm,
            "bearing_sigma_rad": self.bearing_sd_rad if self.reads_bearing else None,
            "sensor_mount": dict(zip(("forward_mm", "left_mm", "yaw_rad"), map(float, self.mounted_at), strict=True)),
            "config": asdict(self),  # the rest: range gain and offset, misreads, drift, the room, ...
        }


@dataclass(frozen=True, eq=False)
class DiffDriveRun:
    config: DiffDriveConfig
    commands: np.ndarray  # (T, 2) the controller's (v mm/s, omega rad/s), in force from step t to t+1
    poses: np.ndarray  # (T, 3) true (x mm, y mm, theta rad), theta wrapped
    obs_step: np.ndarray  # (K,)
    obs_landmark: np.ndarray  # (K,)
    obs_range_mm: np.ndarray
    obs_bearing_rad: np.ndarray
    obs_misread: np.ndarray  # (K,) True for a misread sighting
    side_commands: np.ndarray  # (T,) the controller's v_left (mm/s), all 0 for a differential drive

    def logged_commands(self) -> tuple[tuple[str, ...], np.ndarray]:
        """The commands as the log records them: (v, omega), the wheel speeds (``wheel_axle_mm``), or
        (v, v_left, omega) for a robot that side-steps (``sidestep_mm_s``)."""
        names = self.config.logged_command_names
        if self.config.wheel_axle_mm > 0:
            return names, wheel_speeds(self.commands, self.config.wheel_axle_mm)
        if self.config.sidestep_mm_s > 0:
            return names, np.column_stack([self.commands[:, 0], self.side_commands, self.commands[:, 1]])
        return names, self.commands

    def log(self, source: str | None = None) -> LandmarkLog:
        T = len(self.commands)
        names, logged = self.logged_commands()
        return LandmarkLog(
            "planar",
            self.config.dt_s,
            np.full(T, -1),
            np.zeros((0, len(names))),
            names,
            self.obs_step,
            self.obs_landmark,
            self.obs_range_mm,
            self.obs_bearing_rad if self.config.reads_bearing else np.full(self.obs_step.size, np.nan),
            np.asarray(self.config.landmarks_xy_mm),
            source=source or f"simulated {self.config.robot_kind}",
            reading_names=("range_mm",),
            step_commands=logged,
        )

    def groundtruth(self) -> dict[str, np.ndarray]:
        """The true poses as groundtruth.csv's columns (what `convert mrclam` writes from Vicon)."""
        return {"x_mm": self.poses[:, 0], "y_mm": self.poses[:, 1], "theta_rad": self.poses[:, 2]}


def _drive(
    cfg: DiffDriveConfig, rng_route: np.random.Generator, noise: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steer to random waypoints; the commands are logged, the robot follows them late and lagged.
    Returns the (v, omega) commands, the sideways commands (v_left) and the true poses."""
    T = len(noise)
    dt = cfg.dt_s
    hw, hl = 0.5 * cfg.room_width_mm - cfg.margin_mm, 0.5 * cfg.room_length_mm - cfg.margin_mm
    commands = np.zeros((T, 2))
    side = np.zeros(T)
    poses = np.empty((T, 3))
    x, y, th = (float(v) for v in cfg.start_pose)
    sidesteps = cfg.sidestep_mm_s > 0

    def new_goal() -> tuple[float, float, bool]:
        goal = (rng_route.uniform(-hw, hw), rng_route.uniform(-hl, hl))
        # a differential drive draws nothing more, so that its route is the same with or without this option
        return (*goal, bool(sidesteps and rng_route.random() < cfg.crab_share))

    gx, gy, crab = new_goal()
    wait = 0
    lag = 1.0 - math.exp(-dt / cfg.lag_s) if cfg.lag_s > 0 else 1.0
    fwd, turn, left = 0.0, 0.0, 0.0  # the velocities the robot has reached
    k = cfg.delay_steps
    for t in range(T):
        poses[t] = (x, y, th)
        v_cmd = w_cmd = l_cmd = 0.0
        if wait > 0:
            wait -= 1
        elif math.hypot(gx - x, gy - y) < cfg.arrive_mm:
            wait = int(rng_route.uniform(0, cfg.max_wait_s) / dt)
            gx, gy, crab = new_goal()
        else:
            # the robot's forward axis points at theta + pi/2 in the world (sec. 2.5.1)
            err = math.remainder(math.atan2(gy - y, gx - x) - th - 0.5 * math.pi, 2 * math.pi)
            if crab:  # walk at the waypoint as it lies, forward (or back) and to the side, without turning
                v_cmd, l_cmd = cfg.speed_mm_s * math.cos(err), cfg.sidestep_mm_s * math.sin(err)
            else:
                w_cmd = max(-cfg.turn_rate_rad_s, min(cfg.turn_rate_rad_s, cfg.steer_gain * err))
                if abs(err) < cfg.turn_in_place_rad:
                    v_cmd = cfg.speed_mm_s * (1.0 - 0.3 * abs(err) / cfg.turn_in_place_rad)
        commands[t] = (v_cmd, w_cmd)
        side[t] = l_cmd
        late = max(t - k, 0)  # the first command stands in before it, as the learner's
        v_late, w_late = commands[late]
        worn = cfg.change_at_s is not None and t * dt >= cfg.change_at_s
        if worn:
            v_late, w_late = cfg.change_factor * v_late, cfg.change_factor * w_late
        fwd += lag * (cfg.forward_bias_mm_s + cfg.forward_gain * v_late - fwd)
        reached = cfg.turn_bias_rad_s + cfg.turn_gain * w_late + cfg.straight_turn_rad_per_mm * v_late
        turn += lag * (reached - turn)
        if sidesteps:
            l_late = cfg.change_factor * side[late] if worn else side[late]
            left += lag * (cfg.sideways_bias_mm_s + cfg.sideways_gain * l_late - left)
        # eq. 2.28: the step's displacement in the robot frame (sideways to the right, forward, heading), rotated
        dx, dy, dth = noise[t, 0] - left * dt, fwd * dt + noise[t, 1], turn * dt + noise[t, 2]
        c, s = math.cos(th), math.sin(th)
        x, y, th = x + c * dx - s * dy, y + s * dx + c * dy, math.remainder(th + dth, 2 * math.pi)
    return commands, side, poses


def simulate_diffdrive(config: DiffDriveConfig | None = None) -> DiffDriveRun:
    """Drive the room for ``config.seconds`` and record commands, sightings and the true poses."""
    cfg = config or DiffDriveConfig()
    rng_motion, rng_route, rng_cam, rng_misread, rng_drift = (
        np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(5)
    )
    T = round(cfg.seconds / cfg.dt_s) + 1
    noise = rng_motion.normal(size=(T, 3)) * np.array([cfg.sideways_sd_mm, cfg.forward_sd_mm, cfg.heading_sd_rad])
    commands, side, poses = _drive(cfg, rng_route, noise)

    drift = np.zeros(T)
    if cfg.bearing_drift_sd_rad > 0:  # AR(1) of the OU process on the step grid, started stationary
        phi = math.exp(-cfg.dt_s / cfg.bearing_drift_tau_s)
        kick = rng_drift.normal(size=T) * cfg.bearing_drift_sd_rad * math.sqrt(1 - phi * phi)
        kick[0] = rng_drift.normal() * cfg.bearing_drift_sd_rad
        drift = lfilter([1.0], [1.0, -phi], kick)
    lm = np.asarray(cfg.landmarks_xy_mm)
    frames = np.arange(0, T, max(1, round(cfg.frame_period_s / cfg.dt_s)))
    at = sensor_poses(poses[frames], np.asarray(cfg.mounted_at, dtype=float))
    d = np.stack([landmark_distance(at, p) for p in lm], axis=1)  # (frames, landmarks)
    b = np.stack([landmark_bearing(at, p) for p in lm], axis=1)
    in_view = (d >= cfg.min_range_mm) & (d <= cfg.max_range_mm)
    if cfg.reads_bearing:
        in_view &= np.abs(b) <= 0.5 * np.deg2rad(cfg.fov_deg)
    seen = in_view & (rng_cam.random(in_view.shape) < cfg.detect_probability)
    fi, li = np.nonzero(seen)  # row-major: by frame, then landmark
    bearing = wrap_angle(b[fi, li] + rng_cam.normal(size=fi.size) * cfg.bearing_sd_rad + drift[frames[fi]])
    rng_mm = cfg.range_reading(d[fi, li], bearing) + rng_cam.normal(size=fi.size) * cfg.range_sd_mm
    misread = rng_misread.random(fi.size) < cfg.misread_rate
    half = 0.5 * np.deg2rad(cfg.fov_deg)
    rng_mm[misread] = rng_misread.uniform(cfg.min_range_mm, cfg.max_range_mm, misread.sum())
    bearing[misread] = rng_misread.uniform(-half, half, misread.sum())
    return DiffDriveRun(cfg, commands, poses, frames[fi], li, rng_mm, bearing, misread, side)
