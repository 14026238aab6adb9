"""The chapter-4 world: an Aibo walking on a 5.4 m x 3.6 m field with four known beacons
(secs. 2.5.1, 4.4.1 and 4.4.2).

* 40 actions (eqs. 4.29-4.31): turn fraction omega in {-1/2, -1/6, 0, 1/6, 1/2} times 8 walking
  directions psi, with a_x^2 + a_y^2 + a_theta^2 = 1.
* The true velocities are a distorted, cross-coupled version of the attempted ones: walking sideways
  is slower than walking straight, backward is slower than forward, turning slows the walk and
  forward walking drifts into a turn. The ranges are about 710 mm/s in x, 840 mm/s in y and pi rad/s.
* The head pans side to side; a beacon is seen when it lies within the 56.9 deg field of view and
  1275-4175 mm away. An observation is (height f(d) + noise, bearing + noise), eq. 4.19.
* Every 5 s a new action is chosen: among the least-used actions, one whose 5 s path stays on the
  field (the thesis used its localization for this; the simulator uses the true pose).
* Two presets: ``simulation`` (0.05 s steps, sigma_1 = 1 px, sigma_2 = 0.5 rad, sec. 4.4.2) and
  ``real_robot`` (30 Hz; the measured noise of sec. 4.4.1, 1.59 px and 0.0267 rad; 2 % false positives
  for the first-iteration pruning to remove).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from sensact.core.pose_models import apply_displacement, landmark_bearing, landmark_distance
from sensact.limits import steps_problem
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

OMEGAS = (-0.5, -1.0 / 6.0, 0.0, 1.0 / 6.0, 0.5)  # sec. 4.4.1
PSIS = tuple(k * np.pi / 4 for k in range(-3, 5))  # 0, ±pi/4, ±pi/2, ±3pi/4, pi
# The thesis gives no coordinates for its four beacons; one stands just beyond the middle of each side.
DEFAULT_LANDMARKS = ((0.0, -1950.0), (0.0, 1950.0), (-2900.0, 0.0), (2900.0, 0.0))


def attempted_commands() -> np.ndarray:
    """The 40 attempted (a_x, a_y, a_theta) of eqs. 4.29-4.31, rows ordered by omega then psi."""
    rows = []
    for w in OMEGAS:
        for psi in PSIS:
            r = np.sqrt(1.0 - w * w)
            rows.append((np.cos(psi) * r, np.sin(psi) * r, w))
    return np.round(np.array(rows), 12)


@dataclass(frozen=True)
class Field2DConfig:
    """Every knob of the simulated field. Overridable with ``--set name=value`` or ``--config``."""

    seconds: float = 900.0  # 15 minutes of data, sec. 4.4.1
    seed: int = 0
    dt_s: float = 0.05  # simulation steps of sec. 4.4.2 (the real robot ran at 30 Hz)
    action_hold_s: float = 5.0  # a new action every five seconds, sec. 4.4.1
    field_x_mm: float = 5400.0
    field_y_mm: float = 3600.0
    margin_mm: float = 250.0  # the controller keeps the planned path this far inside the field
    landmarks_xy_mm: tuple[tuple[float, float], ...] = DEFAULT_LANDMARKS
    start_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    # the true action model: gains and distortions of v = A(a)
    gain_x_mm_s: float = 355.0
    gain_y_mm_s: float = 430.0
    gain_theta_rad_s: float = 3.0
    backward_slowdown: float = 0.05  # backward walking is this much slower than forward
    sideways_loss: float = 0.12  # v_y loses this fraction at |a_x| = 1, v_x at |a_y| = 1
    turn_loss: float = 0.15  # v_theta loses this fraction at |a_x| = 1
    walk_drift_rad_s: float = 0.1  # forward walking turns slightly: v_theta += drift * a_y
    turn_side_step_mm_s: float = 40.0  # turning steps sideways: v_x += this * a_theta
    turn_slowdown_mm_s: float = 60.0  # turning slows the walk: v_y -= this * |a_theta|
    # white motion noise per sqrt(second), robot frame
    motion_noise_mm: float = 20.0
    motion_noise_rad: float = 0.08
    # the sensor (eq. 4.19): f(d) = k / (d + d0) + h0, like the camera-derived 38388.7 / d
    sensor_k_px_mm: float = 40200.0
    sensor_d0_mm: float = 110.0
    sensor_h0_px: float = -0.6
    sigma_height_px: float = 1.0  # sec. 4.4.2
    sigma_bearing_rad: float = 0.5  # sec. 4.4.2
    fov_deg: float = 56.9  # sec. 2.5.1
    min_range_mm: float = 1275.0  # sec. 4.4.1
    max_range_mm: float = 4175.0
    head_pan_deg: float = 90.0  # side-to-side head scan amplitude (the ERS-7 pans about +-93 deg)
    head_period_s: float = 1.5
    false_positive_rate: float = 0.0  # fraction of observations replaced by random sightings

    def __post_init__(self) -> None:
        problems = []
        if self.seconds <= 0 or self.dt_s <= 0 or self.action_hold_s < self.dt_s:
            problems.append("seconds, dt_s and action_hold_s must be > 0, action_hold_s >= dt_s")
        elif (too_long := steps_problem(self.seconds / self.dt_s, "seconds / dt_s")) is not None:
            problems.append(too_long)
        if len(self.landmarks_xy_mm) < 1:
            problems.append("at least one landmark")
        if not 0 < self.min_range_mm < self.max_range_mm:
            problems.append("need 0 < min_range_mm < max_range_mm")
        if self.sigma_height_px <= 0 or self.sigma_bearing_rad <= 0:
            problems.append("observation sigmas must be > 0")
        if not 0.0 <= self.false_positive_rate <= 1.0:
            problems.append("false_positive_rate must be in [0, 1], a share of the observations")
        if problems:
            raise ValueError("; ".join(problems))

    @classmethod
    def preset(cls, setting: str, **changes: Any) -> Field2DConfig:
        """``simulation`` (sec. 4.4.2) or ``real_robot`` (sec. 4.4.1: 30 Hz, sigma_2 = 0.0267 rad)."""
        if setting == "simulation":
            base = cls()
        elif setting == "real_robot":
            base = cls(dt_s=1.0 / 30.0, sigma_bearing_rad=0.0267, sigma_height_px=1.59, false_positive_rate=0.02)
        else:
            raise ValueError(f"unknown setting {setting!r}: use simulation or real_robot")
        return replace(base, **changes)

    def true_velocities(self, commands: np.ndarray | None = None) -> np.ndarray:
        """``A(a)`` for attempted ``(a_x, a_y, a_theta)`` rows: (v_x mm/s, v_y mm/s, v_theta rad/s)."""
        a = attempted_commands() if commands is None else np.atleast_2d(commands)
        ax, ay, at = a[:, 0], a[:, 1], a[:, 2]
        vy_gain = np.where(ay >= 0, self.gain_y_mm_s, self.gain_y_mm_s * (1 - self.backward_slowdown))
        vx = self.gain_x_mm_s * ax * (1 - self.sideways_loss * ay**2) + self.turn_side_step_mm_s * at
        vy = vy_gain * ay * (1 - self.sideways_loss * ax**2) - self.turn_slowdown_mm_s * np.abs(at)
        vt = self.gain_theta_rad_s * at * (1 - self.turn_loss * np.abs(ax)) + self.walk_drift_rad_s * ay
        return np.column_stack([vx, vy, vt])

    def height_px(self, distance_mm: np.ndarray | float) -> np.ndarray:
        return self.sensor_k_px_mm / (np.asarray(distance_mm, dtype=float) + self.sensor_d0_mm) + self.sensor_h0_px


@dataclass(frozen=True, eq=False)
class Field2DRun:
    config: Field2DConfig
    times_s: np.ndarray  # (T,)
    actions: np.ndarray  # (T,) action index in force from t to t+1
    poses: np.ndarray  # (T, 3) true (x mm, y mm, theta rad), theta unwrapped
    obs_step: np.ndarray  # (K,)
    obs_landmark: np.ndarray  # (K,)
    obs_height_px: np.ndarray
    obs_bearing_rad: np.ndarray
    obs_false: np.ndarray  # (K,) True for a simulated false positive

    @property
    def commands(self) -> np.ndarray:
        return attempted_commands()

    @property
    def true_velocities(self) -> np.ndarray:
        return self.config.true_velocities()


def _choose_action(cfg: Field2DConfig, pose: np.ndarray, counts: np.ndarray, vel: np.ndarray, rng) -> int:
    """Least-used action whose noise-free path for one hold stays on the field (sec. 4.4.1)."""
    n_sub = 10
    h = cfg.action_hold_s / n_sub
    hx, hy = 0.5 * cfg.field_x_mm - cfg.margin_mm, 0.5 * cfg.field_y_mm - cfg.margin_mm
    w = np.repeat(pose[None], len(vel), axis=0)
    safe = np.ones(len(vel), dtype=bool)
    for _ in range(n_sub):
        w = apply_displacement(w, vel * h)
        safe &= (np.abs(w[:, 0]) <= hx) & (np.abs(w[:, 1]) <= hy)
    if not safe.any():
        end = np.hypot(w[:, 0], w[:, 1])
        return int(np.argmin(end))
    order = np.lexsort((rng.random(len(vel)), counts))  # fewest uses first, ties at random
    for a in order:
        if safe[a]:
            return int(a)
    raise AssertionError("unreachable")


def simulate_field(config: Field2DConfig | None = None) -> Field2DRun:
    """Walk the field for ``config.seconds`` and record actions, observations and the true poses."""
    cfg = config or Field2DConfig()
    streams = np.random.SeedSequence(cfg.seed).spawn(4)
    rng_motion, rng_obs, rng_choice, rng_false = (np.random.default_rng(s) for s in streams)
    T = round(cfg.seconds / cfg.dt_s) + 1
    times = np.arange(T) * cfg.dt_s
    vel = cfg.true_velocities()
    hold = max(1, round(cfg.action_hold_s / cfg.dt_s))
    sd = np.array([cfg.motion_noise_mm, cfg.motion_noise_mm, cfg.motion_noise_rad]) * np.sqrt(cfg.dt_s)
    noise = rng_motion.normal(size=(T, 3)) * sd
    poses = np.empty((T, 3))
    actions = np.empty(T, dtype=np.int64)
    counts = np.zeros(len(vel))
    w = np.array(cfg.start_pose, dtype=float)
    a = 0
    for t in range(T):
        poses[t] = w
        if t % hold == 0:
            a = _choose_action(cfg, w, counts, vel, rng_choice)
            counts[a] += 1
        actions[t] = a
        w = apply_displacement(w, vel[a] * cfg.dt_s + noise[t])[0]
    # observations: every beacon inside the field of view and the recognition range
    lm = np.asarray(cfg.landmarks_xy_mm, dtype=float)
    pan = np.deg2rad(cfg.head_pan_deg) * np.sin(2 * np.pi * times / cfg.head_period_s)
    half_fov = 0.5 * np.deg2rad(cfg.fov_deg)
    steps, marks = [], []
    for j in range(len(lm)):
        d = landmark_distance(poses, lm[j])
        b = landmark_bearing(poses, lm[j])
        off = np.angle(np.exp(1j * (b - pan)))
        seen = (np.abs(off) <= half_fov) & (d >= cfg.min_range_mm) & (d <= cfg.max_range_mm)
        steps.append(np.flatnonzero(seen))
        marks.append(np.full(seen.sum(), j))
    step = np.concatenate(steps)
    mark = np.concatenate(marks)
    order = np.lexsort((mark, step))
    step, mark = step[order], mark[order]
    d = landmark_distance(poses[step], lm[mark])
    height = cfg.height_px(d) + rng_obs.normal(size=step.size) * cfg.sigma_height_px
    bearing = np.angle(
        np.exp(1j * (landmark_bearing(poses[step], lm[mark]) + rng_obs.normal(size=step.size) * cfg.sigma_bearing_rad))
    )
    # false positives of the object recognition: a sighting anywhere, of any plausible size
    false = rng_false.random(step.size) < cfg.false_positive_rate
    lo, hi = float(cfg.height_px(cfg.max_range_mm)), float(cfg.height_px(cfg.min_range_mm))
    height[false] = rng_false.uniform(lo, hi, false.sum())
    bearing[false] = rng_false.uniform(-np.pi, np.pi, false.sum())
    return Field2DRun(cfg, times, actions, poses, step, mark, height, bearing, false)


COMMAND_NAMES = ("a_x", "a_y", "a_theta")


def log_tables(run: Field2DRun) -> JsonObject:
    """The log-folder tables of a run (docs/formats.md), ready for ``sensact.io.write_log_folder``."""
    cfg = run.config
    lm = np.asarray(cfg.landmarks_xy_mm, dtype=float)
    return {
        "meta": {
            "platform": "field2d",
            "geometry": "planar",
            "dt_s": cfg.dt_s,
            "actions": {
                "column": "action_id",
                "names": list(COMMAND_NAMES),
                "table": run.commands.tolist(),
                "meaning": "index into table: attempted (a_x, a_y, a_theta), in force until the next row",
            },
            "landmarks": [{"id": j, "x_mm": float(x), "y_mm": float(y)} for j, (x, y) in enumerate(lm)],
            "observations": {"landmark": "landmark_id", "height": "height_px", "bearing": "bearing_rad"},
            "units": {"height_px": "px", "bearing_rad": "rad", "x_mm": "mm", "y_mm": "mm", "theta_rad": "rad"},
            "simulator": {"name": "field2d", "seed": cfg.seed, "config": asdict(cfg)},
            "truth": {
                "velocities": run.true_velocities.tolist(),
                "velocity_names": ["v_x_mm_s", "v_y_mm_s", "v_theta_rad_s"],
                "sensor": {
                    "kind": "k_over_d_plus_d0_plus_h0",
                    "k_px_mm": cfg.sensor_k_px_mm,
                    "d0_mm": cfg.sensor_d0_mm,
                    "h0_px": cfg.sensor_h0_px,
                },
                "sigma_height_px": cfg.sigma_height_px,
                "sigma_bearing_rad": cfg.sigma_bearing_rad,
            },
        },
        "actions": {"t_s": run.times_s, "action_id": run.actions.astype(float)},
        "observations": {
            "t_s": run.times_s[run.obs_step],
            "landmark_id": run.obs_landmark.astype(float),
            "height_px": run.obs_height_px,
            "bearing_rad": run.obs_bearing_rad,
        },
        "groundtruth": {
            "t_s": run.times_s,
            "x_mm": run.poses[:, 0],
            "y_mm": run.poses[:, 1],
            "theta_rad": np.angle(np.exp(1j * run.poses[:, 2])),
        },
    }


def to_landmark_log(run: Field2DRun) -> LandmarkLog:
    """The run as EM's input (what the robot recorded; no truth)."""
    cfg = run.config
    return LandmarkLog(
        "planar",
        cfg.dt_s,
        run.actions,
        run.commands,
        COMMAND_NAMES,
        run.obs_step,
        run.obs_landmark,
        run.obs_height_px,
        run.obs_bearing_rad,
        np.asarray(cfg.landmarks_xy_mm, dtype=float),
        tuple(f"beacon{j}" for j in range(len(cfg.landmarks_xy_mm))),
        f"field2d(seed={cfg.seed})",
    )
