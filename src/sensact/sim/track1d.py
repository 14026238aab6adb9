"""The chapter-3 world: an Aibo walking forward and backward while facing a beacon (sec. 3.3).

The robot picks an attempted velocity uniformly from [0, 300] mm/s when walking toward the beacon and
from [-300, 0] when backing away, holds it for 3 s, and turns around when the (smoothed) beacon height
crosses thresholds that keep it about 1.2 to 3.6 m away. It sees the beacon at 20 Hz.

The truth is deliberately not what a naive model assumes:

* the beacon height ``f(d) = k / (d + d0) + h0`` is monotone and close to the camera-derived
  38388.7/d of sec. 2.5.1, but not equal to it;
* the action model ``A(c)`` is a monotone cubic (PCHIP) through knots: slower than attempted at high
  speed, with a dead band near zero, like the measured curve of Figure 3.8a.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.signal import lfilter

from sensact.limits import steps_problem
from sensact.logs.landmark_log import LandmarkLog
from sensact.records import JsonObject

# A curve with the shape of Figure 3.8a: a small dead band (|c| <= 25 mm/s), near-unit gain at low speed,
# and saturation near 175 mm/s, slightly faster forward than backward. Chosen so that the measured-model
# reference errors match the real Aibo's (sec. 3.3.2): taking A0(c) = c as the model is 41.7 mm/s off after
# the optimal scale (thesis: 43.0) and the best quartic reaches 17.4 mm/s (thesis: 17.2).
DEFAULT_ACTION_KNOTS_C = (-300.0, -240.0, -180.0, -120.0, -70.0, -25.0, 0.0, 25.0, 70.0, 120.0, 180.0, 240.0, 300.0)
DEFAULT_ACTION_KNOTS_V = (-165.0, -164.0, -162.0, -152.0, -105.0, 0.0, 0.0, 0.0, 110.0, 162.0, 174.0, 177.0, 178.0)


@dataclass(frozen=True)
class TrackTruth:
    """The true models of the 1-D world; enough to recompute every measured curve."""

    action_knots_c_mm_s: tuple[float, ...] = DEFAULT_ACTION_KNOTS_C
    action_knots_v_mm_s: tuple[float, ...] = DEFAULT_ACTION_KNOTS_V
    sensor_k_px_mm: float = 40200.0
    sensor_d0_mm: float = 110.0
    sensor_h0_px: float = -0.6

    def __post_init__(self) -> None:
        c = np.asarray(self.action_knots_c_mm_s)
        v = np.asarray(self.action_knots_v_mm_s)
        if c.shape != v.shape or c.size < 2:
            raise ValueError("action knots: c and v need the same length, at least 2")
        if np.any(np.diff(c) <= 0):
            raise ValueError("action_knots_c_mm_s must be strictly increasing")
        if np.any(np.diff(v) < 0):
            raise ValueError("action_knots_v_mm_s must be non-decreasing (a monotone action model)")
        if self.sensor_k_px_mm <= 0:
            raise ValueError("sensor_k_px_mm must be > 0")

    def velocity_mm_s(self, command_mm_s: np.ndarray | float) -> np.ndarray:
        """True mean velocity toward the beacon for an attempted velocity (PCHIP through the knots)."""
        interp = PchipInterpolator(self.action_knots_c_mm_s, self.action_knots_v_mm_s, extrapolate=True)
        return np.asarray(interp(np.asarray(command_mm_s, dtype=float)))

    def height_px(self, distance_mm: np.ndarray | float) -> np.ndarray:
        """Mean beacon height f(d)."""
        d = np.asarray(distance_mm, dtype=float)
        return self.sensor_k_px_mm / (d + self.sensor_d0_mm) + self.sensor_h0_px

    def distance_mm(self, height_px: np.ndarray | float) -> np.ndarray:
        """The true inverse sensor model S = f^-1."""
        h = np.asarray(height_px, dtype=float)
        return self.sensor_k_px_mm / (h - self.sensor_h0_px) - self.sensor_d0_mm

    def to_dict(self) -> JsonObject:
        return {
            "action": {
                "kind": "pchip_knots",
                "c_mm_s": list(self.action_knots_c_mm_s),
                "v_mm_s": list(self.action_knots_v_mm_s),
            },
            "sensor": {
                "kind": "k_over_d_plus_d0_plus_h0",
                "k_px_mm": self.sensor_k_px_mm,
                "d0_mm": self.sensor_d0_mm,
                "h0_px": self.sensor_h0_px,
            },
        }

    @classmethod
    def from_dict(cls, data: JsonObject) -> TrackTruth:
        a, s = data["action"], data["sensor"]
        return cls(tuple(a["c_mm_s"]), tuple(a["v_mm_s"]), float(s["k_px_mm"]), float(s["d0_mm"]), float(s["h0_px"]))


@dataclass(frozen=True)
class Track1DConfig:
    """Every knob of the simulated track. Overridable with ``--set name=value`` or ``--config file.yaml``."""

    seconds: float = 150.0  # trial length, sec. 3.3.2
    seed: int = 0
    dt_s: float = 0.05  # simulation step
    observation_rate_hz: float = 20.0  # images processed at roughly 20 Hz, sec. 3.3.2
    command_hold_s: float = 3.0  # each action is held for three seconds, sec. 3.3
    command_max_mm_s: float = 300.0  # a_y in [-300, 300] mm/s, sec. 3.3
    start_distance_mm: float = 2400.0
    turn_near_px: float | None = None  # back away above this height; None: f(1200 mm)
    turn_far_px: float | None = None  # walk forward below this height; None: f(3600 mm)
    turn_filter_n: int = 20  # the turn test uses the mean of the last n heights (1 s): covers 1.2-3.6 m
    action_knots_c_mm_s: tuple[float, ...] = DEFAULT_ACTION_KNOTS_C
    action_knots_v_mm_s: tuple[float, ...] = DEFAULT_ACTION_KNOTS_V
    motion_noise_mm_s: float = 20.0  # white velocity noise, drawn every step
    speed_jitter_frac: float = 0.03  # relative speed error, drawn once per held command
    sensor_k_px_mm: float = 40200.0  # f(d) = k / (d + d0) + h0
    sensor_d0_mm: float = 110.0
    sensor_h0_px: float = -0.6
    observation_noise_px: float = 1.5
    # the lag-1 autocorrelation of the reading noise from one observation to the next (an AR(1) error whose
    # stationary sd is observation_noise_px); 0: white noise, as eq. 4.19 assumes
    observation_noise_ar1: float = 0.0
    observation_dropout: float = 0.0  # probability that a frame misses the beacon
    min_distance_mm: float = 300.0  # the robot never walks into the beacon
    command_levels: int = 0  # 0: commands uniform in the range; N: N evenly spaced levels (sec. 4.4.3 uses 21)
    change_at_s: float | None = None  # from this time on the robot walks slower (sec. 4.4.3) ...
    change_factor: float = 0.75  # ... as if the attempted velocity were multiplied by this

    def __post_init__(self) -> None:
        problems = []
        if self.seconds <= 0:
            problems.append("seconds must be > 0")
        if self.dt_s <= 0:
            problems.append("dt_s must be > 0")
        elif (
            not self.seconds <= 0
            and (too_long := steps_problem(self.seconds / self.dt_s, "seconds / dt_s")) is not None
        ):
            problems.append(too_long)
        if self.observation_rate_hz <= 0 or (self.dt_s > 0 and self.observation_rate_hz > 1.0 / self.dt_s + 1e-9):
            problems.append("observation_rate_hz must be in (0, 1/dt_s]")
        noise = {k: getattr(self, k) for k in ("motion_noise_mm_s", "observation_noise_px", "speed_jitter_frac")}
        problems += [f"{k} must be >= 0, a noise's size" for k, v in noise.items() if not v >= 0]
        if self.command_hold_s <= 0:
            problems.append("command_hold_s must be > 0")
        if not 0.0 <= self.observation_noise_ar1 < 1.0:
            problems.append("observation_noise_ar1 must be in [0, 1)")
        if not 0.0 <= self.observation_dropout < 1.0:
            problems.append("observation_dropout must be in [0, 1)")
        if self.turn_filter_n < 1:
            problems.append("turn_filter_n must be >= 1")
        if self.command_levels < 0 or self.command_levels == 1:
            problems.append("command_levels must be 0 (continuous) or >= 2")
        if problems:
            raise ValueError("; ".join(problems))
        self.truth()  # validates the knots and the sensor

    def truth(self) -> TrackTruth:
        return TrackTruth(
            tuple(self.action_knots_c_mm_s),
            tuple(self.action_knots_v_mm_s),
            self.sensor_k_px_mm,
            self.sensor_d0_mm,
            self.sensor_h0_px,
        )

    def levels_mm_s(self) -> np.ndarray:
        """The discrete command levels (empty when commands are continuous)."""
        if self.command_levels == 0:
            return np.zeros(0)
        return np.linspace(-self.command_max_mm_s, self.command_max_mm_s, self.command_levels)

    def thresholds_px(self) -> tuple[float, float]:
        truth = self.truth()
        near = self.turn_near_px if self.turn_near_px is not None else float(truth.height_px(1200.0))
        far = self.turn_far_px if self.turn_far_px is not None else float(truth.height_px(3600.0))
        if not near > far:
            raise ValueError("turn_near_px must be larger than turn_far_px")
        return near, far


@dataclass(frozen=True)
class TrackRun:
    """A simulated log: per-step arrays plus the truth that produced them."""

    config: Track1DConfig
    times_s: np.ndarray  # (T,)
    commands_mm_s: np.ndarray  # (T,) attempted velocity in force from t_k to t_{k+1}
    heights_px: np.ndarray  # (T,) NaN where no observation
    distance_mm: np.ndarray  # (T,) true distance to the beacon
    velocity_mm_s: np.ndarray  # (T,) true velocity toward the beacon over [t_k, t_{k+1})

    @property
    def truth(self) -> TrackTruth:
        return self.config.truth()


def simulate_track(config: Track1DConfig | None = None) -> TrackRun:
    """Run the walk-toward-and-away behaviour of sec. 3.3 and record what the robot saw and did."""
    cfg = config or Track1DConfig()
    truth = cfg.truth()
    # one generator per random stream, so that a longer run extends a shorter one with the same seed
    rng_motion, rng_obs, rng_drop, rng = (np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(4))
    T = round(cfg.seconds / cfg.dt_s) + 1
    times = np.arange(T) * cfg.dt_s
    obs_every = max(1, round(1.0 / (cfg.observation_rate_hz * cfg.dt_s)))
    near_px, far_px = cfg.thresholds_px()
    levels = cfg.levels_mm_s()

    motion_noise = rng_motion.normal(0.0, cfg.motion_noise_mm_s, T)
    obs_noise = rng_obs.normal(0.0, cfg.observation_noise_px, T)
    if cfg.observation_noise_ar1:  # AR(1) from one observation to the next, stationary from the start
        phi = cfg.observation_noise_ar1 ** (1.0 / obs_every)  # per step, so that it is phi per observation
        kick = obs_noise * np.sqrt(1.0 - phi * phi)
        kick[0] = obs_noise[0]
        obs_noise = lfilter([1.0], [1.0, -phi], kick)
    dropped = rng_drop.random(T) < cfg.observation_dropout

    commands = np.empty(T)
    heights = np.full(T, np.nan)
    dist = np.empty(T)
    vel = np.empty(T)
    recent: list[float] = []
    d = cfg.start_distance_mm
    direction = 1.0  # +1 walks toward the beacon
    hold_left = 0.0
    c = v_cmd = 0.0
    for k in range(T):
        dist[k] = d
        if k % obs_every == 0 and not dropped[k]:
            h = float(truth.height_px(d)) + obs_noise[k]
            heights[k] = h
            recent.append(h)
            if len(recent) > cfg.turn_filter_n:
                recent.pop(0)
            mean_h = sum(recent) / len(recent)
            if direction > 0 and mean_h > near_px:
                direction, hold_left = -1.0, 0.0
                recent.clear()
            elif direction < 0 and mean_h < far_px:
                direction, hold_left = 1.0, 0.0
                recent.clear()
        if hold_left <= 1e-9:
            if levels.size:
                allowed = levels[levels * direction >= 0]
                c = float(allowed[rng.integers(allowed.size)])
            else:
                c = direction * rng.uniform(0.0, cfg.command_max_mm_s)
            changed = cfg.change_at_s is not None and times[k] >= cfg.change_at_s
            factor = cfg.change_factor if changed else 1.0
            v_cmd = float(truth.velocity_mm_s(factor * c)) * (1.0 + cfg.speed_jitter_frac * rng.normal())
            hold_left = cfg.command_hold_s
        hold_left -= cfg.dt_s
        commands[k] = c
        vel[k] = v_cmd + motion_noise[k]
        d = max(cfg.min_distance_mm, d - vel[k] * cfg.dt_s)
    return TrackRun(cfg, times, commands, heights, dist, vel)


def log_tables(run: TrackRun) -> JsonObject:
    """The log-folder tables of a run (docs/formats.md), ready for ``sensact.io.write_log_folder``."""
    from dataclasses import asdict

    return {
        "meta": {
            "platform": "track1d",
            "dt_s": run.config.dt_s,
            "action": {
                "column": "command_mm_s",
                "unit": "mm/s",
                "meaning": "attempted velocity toward the beacon, in force until the next row",
            },
            "sensor": {"column": "height_px", "unit": "px", "meaning": "beacon height in the image"},
            "groundtruth": {"column": "distance_mm", "unit": "mm"},
            "units": {"height_px": "px"},
            "simulator": {"name": "track1d", "seed": run.config.seed, "config": asdict(run.config)},
            "truth": run.truth.to_dict(),
        },
        "actions": {"t_s": run.times_s, "command_mm_s": run.commands_mm_s},
        "observations": {"t_s": run.times_s, "height_px": run.heights_px},
        "groundtruth": {"t_s": run.times_s, "distance_mm": run.distance_mm, "velocity_mm_s": run.velocity_mm_s},
    }


def to_landmark_log(run: TrackRun) -> LandmarkLog:
    """A run with discrete command levels as EM's input (sec. 4.4.3): one action per level, no truth."""
    levels = run.config.levels_mm_s()
    if levels.size == 0:
        raise ValueError("EM needs discrete actions: simulate with command_levels > 0 (sec. 4.4.3 uses 21)")
    actions = np.abs(run.commands_mm_s[:, None] - levels[None]).argmin(axis=1)
    seen = np.flatnonzero(np.isfinite(run.heights_px))
    levels_a_y = levels / run.config.command_max_mm_s
    source = f"track1d(seed={run.config.seed})"
    return LandmarkLog.track(run.config.dt_s, actions, levels_a_y, "a_y", seen, run.heights_px[seen], source)
