"""EM's settings, in groups: the thesis's constants (ch. 4, with their source), then what extends it to
real robots (``docs/em-real.md``): the action model, the motion noise, the reading channels, robust
readings, and the searches and restarts. Each default leaves the thesis's algorithm unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from sensact.errors import ConfigError
from sensact.models.landmark_sensor import check_robust, student_t_params
from sensact.models.linear_action import BASES
from sensact.records import JsonObject

ACTION_BASES = ("table", *BASES)
MOTION_NOISE = ("fixed", "shared", "per_action", "turning")
POSE_DRAWS = ("sigma_points", "random")


@dataclass(frozen=True)
class ChannelConfig:
    """One reading channel: its polynomial, its starting straight line and where it can be trusted."""

    name: str  # a column of the log's readings
    degree: int = 3
    start_intercept: float = 20.0
    start_slope: float = -0.002
    start_sigma: float = 10.0
    valid_min: float = -math.inf  # distance window (mm): readings are used only while the robot is predicted inside it
    valid_max: float = math.inf
    robust: str = "none"  # "none", "student_t" or "gate"
    robust_param: float = 0.0  # Student-t degrees of freedom, or the gate in innovation sigmas
    # m of the camera's bearing terms d * (a_1 b + .. + a_m b^m), learned from 0 (0 = the thesis's f(d))
    bearing_degree: int = 0

    def __post_init__(self) -> None:
        if self.bearing_degree < 0:
            raise ValueError(f"channel {self.name}: bearing_degree must be >= 0")
        if self.degree < 1:
            raise ValueError(f"channel {self.name}: degree must be >= 1")
        if not self.start_sigma > 0:
            raise ValueError(f"channel {self.name}: start_sigma must be > 0")
        if not self.valid_min < self.valid_max:
            raise ValueError(f"channel {self.name}: valid_min must be below valid_max")
        check_robust(self.robust, self.robust_param, f"channel {self.name}")


def _check(problems: list[str]) -> None:
    if problems:
        raise ValueError("; ".join(problems))


@dataclass(frozen=True)
class ThesisSettings:
    """Sec. 4.4.1's constants: the thesis's EM as it ran on the Aibo."""

    # the fixed motion noise Sigma_m, per time step (sec. 4.4.1: 10 mm, 10 mm, 0.1 rad at 30 Hz;
    # sec. 4.4.3: 10 mm on the track); the starting value when it is learned
    motion_sd_mm: float = 10.0
    motion_sd_rad: float = 0.1
    sensor_degree: int = 3  # f is a cubic, sec. 4.1
    samples_per_frame: int = 1  # N_s, sec. 4.3.2
    patience: int = 50  # stop after this many iterations without a new best likelihood, sec. 4.4.1
    max_iterations: int = 5000
    prune_rad_per_step: float = 0.6  # first-iteration outlier gate on the bearing innovation, sec. 4.4.1
    seed: int = 0  # the M-step's sampling
    # the starting model (sec. 4.4.1): no motion, a poor linear f, sigma_1 = 10 px, sigma_2 = 0.2 rad
    start_height_intercept_px: float = 20.0
    start_height_slope_px_per_mm: float = -0.002
    start_sigma_height_px: float = 10.0
    start_sigma_bearing_rad: float = 0.2
    # the starting prior pi(w_0); on a track only the first entries are used
    start_prior_mean: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_prior_sd: tuple[float, float, float] = (300.0, 300.0, 0.3)
    prior_floor_sd: tuple[float, float] = (1.0, 1e-3)  # keeps pi = gamma_0 from collapsing (mm, rad)

    def __post_init__(self) -> None:
        problems = []
        if not (self.motion_sd_mm > 0 and self.motion_sd_rad > 0):
            problems.append("motion_sd_mm and motion_sd_rad must be > 0")
        if self.sensor_degree < 1:
            problems.append("sensor_degree must be >= 1")
        if self.samples_per_frame < 1:
            problems.append("samples_per_frame must be >= 1")
        if self.patience < 1 or self.max_iterations < 1:
            problems.append("patience and max_iterations must be >= 1")
        if not (self.start_sigma_height_px > 0 and self.start_sigma_bearing_rad > 0):
            problems.append("start sigmas must be > 0")
        if min(self.start_prior_sd) <= 0:
            problems.append("start_prior_sd must be > 0")
        _check(problems)


@dataclass(frozen=True)
class ActionSettings:
    """The action model beyond the thesis's table (docs/em-real.md, section 2)."""

    # "table": one velocity per discrete action (eq. 4.18); "affine", "cross", "polynomial": A(c) = Phi(c) beta
    basis: str = "table"
    degree: int = 2  # of the polynomial basis
    delay_max_s: float | None = None  # learn a command delay up to this long (continuous models; None: none)
    # velocity components whose mean is held at 0, e.g. ("v_x_mm_s",): a differential drive cannot side-step
    zero_mean: tuple[str, ...] = ()
    # "velocity:command+command" entries: that velocity depends on those commands only, e.g.
    # ("v_y_mm_s:v_mm_s", "v_theta_rad_s:omega_rad_s") for a differential drive; a bracketed sum or
    # difference is one input, "v_theta_rad_s:(right_mm_s-left_mm_s)" on wheel speeds (models/linear_action.py)
    inputs: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        problems = []
        if self.basis not in ACTION_BASES:
            problems.append(f"action.basis must be one of {ACTION_BASES}")
        if self.delay_max_s is not None and not self.delay_max_s > 0:
            problems.append("action.delay_max_s must be > 0, or null for none")
        if self.degree < 1:
            problems.append("action.degree must be >= 1")
        if (self.zero_mean or self.inputs) and self.basis == "table":
            problems.append(
                "action.zero_mean and action.inputs need a continuous action.basis (affine, cross or polynomial)"
            )
        _check(problems)


@dataclass(frozen=True)
class MotionNoiseSettings:
    """Sigma_m beyond the thesis's constant (its start is ``thesis.motion_sd_mm``/``motion_sd_rad``)."""

    # "fixed" (the thesis), or learned "shared" or "per_action", or "turning" (shared, with a heading variance
    # a + b |turn rate|: EMModel.turn_var), never below the floor
    kind: str = "fixed"
    floor_mm: float = 0.05
    floor_rad: float = 5e-4
    # the sideways sd per step on a planar log, if not motion_sd_mm (None: motion_sd_mm). The sightings hardly
    # pin it, so a learned Sigma_m keeps about its start (docs/em-real.md, Known limits): a
    # differential drive, which cannot side-step, can start it small
    sideways_mm: float | None = None

    def __post_init__(self) -> None:
        problems = []
        if self.kind not in MOTION_NOISE:
            problems.append(f"motion_noise.kind must be one of {MOTION_NOISE}")
        if not (self.floor_mm > 0 and self.floor_rad > 0):
            problems.append("motion_noise.floor_mm and floor_rad must be > 0")
        if self.sideways_mm is not None and not self.sideways_mm > 0:
            problems.append("motion_noise.sideways_mm must be > 0, or null for motion_sd_mm")
        _check(problems)


@dataclass(frozen=True)
class RobustSettings:
    """Readings that are sometimes far wrong (each channel's own kind is in ``ChannelConfig``)."""

    bearing: str = "none"  # "none", "student_t" or "gate"
    bearing_param: float = 0.0  # Student-t degrees of freedom, or the gate in innovation sigmas
    # a sighting's student_t readings (its range channels and its bearing) share one weight, as one
    # multivariate t: a reading its sighting's others show to be false does not count in full because it
    # alone happens to fit (a misread barcode; docs/em-real.md). Every student_t reading needs the same nu
    joint_student_t: bool = False
    # when the robust readings take over from the Gaussian ones, apply prune_rad_per_step's gate again to
    # every sighting's bearing about the smoothed pose of its own step (k = 1; learn/em/late_outliers.py); a
    # config without robust readings (or without a held stage, unless from a learned model: warm_start)
    # has no such moment, and this does nothing
    prune_when_freed: bool = False

    def __post_init__(self) -> None:
        check_robust(self.bearing, self.bearing_param, "robust.bearing")


@dataclass(frozen=True)
class SearchSettings:
    """The held stage, the searches and the restarts: directions EM climbs too slowly itself, and the signs
    that it lost the robot (docs/em-real.md; each measured in docs/em-real.md). By the part of the loop
    each steers (the fields keep their order and flat names: they are the keys of every settings file
    and of each model.json's ``config``):

    * the stages (``stage.py``): ``refine_from``, ``warm_start``;
    * the start (``searches/start_race.py``, ``searches/given_start.py``): ``start_s``, ``start_grid_mm``,
      ``start_candidates``, ``start_trial_iterations``, ``moved_start_sds``, ``moved_start_headings``;
    * the ridge, delay and mount searches (``searches/``): ``ridge_mm``, ``delay``, ``every``;
    * the signs of a lost fit (``checks/lost_signs.py``): ``lost_bend_ratio``, ``lost_fall_per_sighting``;
    * the restarts they start (``fit.py``): ``turn_restarts``, ``restart_sigma_factor``."""

    # a learned Sigma_m, the channels' bearing terms, the mount and the robust readings are held before this
    # iteration, or until EM has converged without them: learned from a poor start, they let EM settle on a
    # trajectory shifted behind the robot, so the thesis's fixed-Sigma_m model pins the trajectory first
    refine_from: int = 100
    # the starting model is a learned one (`learn em --start-from`; learn/em/uses/warm_start.py), placed on
    # the log already: nothing is held (it has settled), the start is not searched for, and
    # prune_when_freed's gate runs on the first E-step
    warm_start: bool = False
    # choose pi(w_0) among a grid of poses by the forward likelihood of the first seconds (None: no search);
    # for a log with no idea where the robot starts (planar, with a landmark map)
    start_s: float | None = None
    start_grid_mm: float = 500.0
    # the best few distinct grid poses race: EM from each on the whole log, the better half kept every
    # start_trial_iterations held iterations, until one is left (1 = the grid's best, no race)
    start_candidates: int = 6
    start_trial_iterations: int = 20
    # the searches below run when the held stage ends and every ``every`` iterations after (with nothing held:
    # every ``every`` from the start). Along the ridge where the path and every range function's offset trade
    # against each other, this far (mm; learn/em/searches/ridge.py; None: no ridge search, the thesis):
    ridge_mm: float | None = None
    # over the command delay 0..action.delay_max_s by the E-step likelihood (learn/em/searches/delay.py; only
    # when a delay is learned):
    delay: bool = True
    every: int = 50
    # when a channel's learned f turns over, or (a reading in the map's unit) bends, within the distances
    # it was fitted on, or EM's likelihood after its best stays far below it (a planar log;
    # learn/em/checks/lost_signs.py), the signs that EM lost the robot, EM starts again with that channel's (when EM
    # did not settle, every channel's) start sigma restart_sigma_factor of the last, up to this many times,
    # and keeps the most likely fit (0 = never, the thesis)
    turn_restarts: int = 0
    # the signs that a fit lost its robot, which start turn_restarts and are warned of: a length-reading f
    # whose slope changes more than this many times over its fitted distances without turning (1.00-1.15 on
    # the MRCLAM fits that found their robot, 1.70 on one 182 mm off Vicon, 2.91 on a quarter that lost it;
    # docs/em-real.md, "What you see without ground truth"), ...
    lost_bend_ratio: float = 2.0
    # ... or the iterations after the best falling below it by more than this many log-units a sighting used,
    # on average (0.008-0.029 on the 51 MRCLAM fits that found their robot, 0.002-0.005 on simulated
    # differential drives, 0.03-1.45 on the 9 that lost it; docs/em-real.md, "Fewer landmarks")
    lost_fall_per_sighting: float = 0.1
    # each restart's start sigma over the last one's: on quarter-length MRCLAM logs, trusting the poor line's
    # readings more held the robot's scale (docs/em-real.md, Short logs)
    restart_sigma_factor: float = 1.0 / 3.0
    # a range-only start that EM moved more than this many of the prior's position sd was not where the robot
    # was given to be: EM runs again from where it put it (learn/em/searches/given_start.py) ...
    moved_start_sds: float = 3.0
    moved_start_headings: int = 8  # ... facing each of this many headings in a race, since ranges cannot tell it

    def __post_init__(self) -> None:
        problems = []
        if self.refine_from < 0:
            problems.append("search.refine_from must be >= 0")
        if self.start_s is not None and not self.start_s > 0:
            problems.append("search.start_s must be > 0, or null for none")
        if self.start_grid_mm <= 0:
            problems.append("search.start_grid_mm must be > 0")
        if self.start_candidates < 1 or self.start_trial_iterations < 1:
            problems.append("search.start_candidates and start_trial_iterations must be >= 1")
        if self.ridge_mm is not None and not self.ridge_mm > 0:
            problems.append("search.ridge_mm must be > 0, or null for none")
        if self.every < 1:
            problems.append("search.every must be >= 1")
        if self.turn_restarts < 0:
            problems.append("search.turn_restarts must be >= 0 (0 = no restart)")
        if not (self.lost_bend_ratio > 1 and self.lost_fall_per_sighting > 0 and 0 < self.restart_sigma_factor < 1):
            problems.append(
                "search.lost_bend_ratio must be > 1, lost_fall_per_sighting > 0 and restart_sigma_factor in (0, 1)"
            )
        if not (self.moved_start_sds > 0 and self.moved_start_headings >= 1):
            problems.append("search.moved_start_sds must be > 0 and moved_start_headings >= 1")
        _check(problems)


GROUPS = {
    "thesis": ThesisSettings,
    "action": ActionSettings,
    "motion_noise": MotionNoiseSettings,
    "robust": RobustSettings,
    "search": SearchSettings,
}
# a flat name, as settings files, --set and model files before the groups wrote them -> "group.field"
FLAT = {
    **{f: f"thesis.{f}" for f in ThesisSettings.__dataclass_fields__},
    "action_basis": "action.basis",
    "action_degree": "action.degree",
    "action_delay_max_s": "action.delay_max_s",
    "action_zero_mean": "action.zero_mean",
    "action_inputs": "action.inputs",
    "motion_sd_floor_mm": "motion_noise.floor_mm",
    "motion_sd_floor_rad": "motion_noise.floor_rad",
    "motion_sd_sideways_mm": "motion_noise.sideways_mm",
    "bearing_robust": "robust.bearing",
    "bearing_robust_param": "robust.bearing_param",
    "joint_student_t": "robust.joint_student_t",
    "prune_when_freed": "robust.prune_when_freed",
    **{f: f"search.{f}" for f in SearchSettings.__dataclass_fields__},
    "start_search_s": "search.start_s",
    "start_search_grid_mm": "search.start_grid_mm",
    "ridge_search_mm": "search.ridge_mm",
    "delay_search": "search.delay",
    "search_every": "search.every",
}
# the flat settings that are off when None (a model file written before that was so has 0 there)
ZERO_WAS_OFF = ("action_delay_max_s", "motion_sd_sideways_mm", "start_search_s", "ridge_search_mm")


@dataclass(frozen=True)
class EMConfig:
    """EM's settings in groups; each field's default is the thesis's, or leaves the thesis's algorithm as it
    is. ``EMConfig.of(**fields)`` and ``replace(**fields)`` take a group (``action=ActionSettings(...)``), a
    field by its group (``**{"action.basis": "affine"}``) or by its flat name (``action_basis="affine"``)."""

    thesis: ThesisSettings = field(default_factory=ThesisSettings)
    action: ActionSettings = field(default_factory=ActionSettings)
    motion_noise: MotionNoiseSettings = field(default_factory=MotionNoiseSettings)
    # reading channels; empty = the thesis's one beacon-height channel from the thesis.start_height_* fields
    channels: tuple[ChannelConfig, ...] = ()
    robust: RobustSettings = field(default_factory=RobustSettings)
    search: SearchSettings = field(default_factory=SearchSettings)
    # SQUAREM on EM's map (squarem.py): its fixed point in fewer E-steps; False: plain EM, the thesis's
    accelerate: bool = False
    # how the M-step takes its expectations over gamma (eqs. 4.25-4.28): "sigma_points", the unscented
    # transform's 2n points, a deterministic map as SQUAREM needs; "random", sec. 4.3.2's samples_per_frame
    # draws; None: sigma_points when accelerated, else random (the thesis's)
    pose_draws: str | None = None
    # where the sensor sits on the robot, (forward mm, left mm, yaw rad counterclockwise), held there; None:
    # learned by the M-step wherever the log pins it, from the robot's own point (learn/em/mount.py)
    sensor_mount: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        problems = []
        if self.motion_noise.kind == "per_action" and self.action.basis != "table":
            problems.append(
                "motion_noise.kind=per_action needs action.basis=table (continuous commands have no actions)"
            )
        if len({c.name for c in self.channels}) != len(self.channels):
            problems.append("channel names must be distinct")
        if not isinstance(self.accelerate, bool):
            problems.append(f"accelerate must be true or false, not {self.accelerate!r}")
        if self.pose_draws is not None and self.pose_draws not in POSE_DRAWS:
            problems.append(f"pose_draws must be one of {', '.join(POSE_DRAWS)}, not {self.pose_draws!r}")
        elif self.accelerate and self.pose_draws == "random":
            problems.append(
                "accelerate=true needs pose_draws=sigma_points: random draws make EM's map noisy, and SQUAREM's "
                "steps multiply the noise (set accelerate=false for the thesis's EM)"
            )
        if self.sensor_mount is not None and (
            len(self.sensor_mount) != 3 or not all(math.isfinite(v) for v in self.sensor_mount)
        ):
            problems.append("sensor_mount must be three finite numbers (forward mm, left mm, yaw rad), or null")
        r = self.robust
        nus = set(student_t_params(self.channels, r.bearing, r.bearing_param))
        if r.joint_student_t and len(nus) > 1:
            problems.append(
                f"robust.joint_student_t reads a sighting as one multivariate t, so every student_t reading needs "
                f"the same robust_param (degrees of freedom), not {sorted(nus)}"
            )
        _check(problems)

    @staticmethod
    def regroup(fields: JsonObject) -> JsonObject:
        """``fields`` as the groups hold them: a flat name (``action_basis``) or a dotted one
        (``action.basis``) put under its group, a ``motion_noise`` given as a word read as its kind; a
        group given whole (a mapping or a settings value) kept, and merged with its single fields. Other
        names are left for ``config_from_dict`` to refuse, naming the nearest."""
        out: JsonObject = {}
        singles: list[tuple[str, str, Any]] = []
        for key, value in fields.items():
            path = FLAT.get(key, key)
            if key == "motion_noise" and isinstance(value, str):
                path = "motion_noise.kind"
            group, dot, name = path.partition(".")
            if dot and group in GROUPS:
                singles.append((group, name, value))
            else:
                out[key] = value
        for group, name, value in singles:
            given = out.get(group)
            if given is None:
                out[group] = {name: value}
            elif isinstance(given, Mapping):
                out[group] = {**given, name: value}
            else:  # a settings value given whole
                out[group] = replace(given, **{name: value})
        return out

    @classmethod
    def accepts(cls, name: str) -> bool:
        """Whether ``name`` names a setting: a field, a group's field by its flat or dotted name."""
        return name in cls.__dataclass_fields__ or name in FLAT or name.partition(".")[0] in GROUPS

    @classmethod
    def of(cls, **fields: Any) -> EMConfig:
        """The defaults with ``fields`` (flat, dotted or whole groups: ``regroup``)."""
        return cls().replace(**fields)

    def replace(self, **fields: Any) -> EMConfig:
        """These settings with ``fields`` changed (flat, dotted or whole groups: ``regroup``)."""
        changes = {}
        for key, value in self.regroup(fields).items():
            if key in GROUPS and isinstance(value, Mapping):
                value = replace(getattr(self, key), **value)
            changes[key] = value
        return replace(self, **changes)

    @property
    def sigma_points(self) -> bool:
        """Whether the M-step takes its expectations at sigma points (``pose_draws``)."""
        return (self.pose_draws or ("sigma_points" if self.accelerate else "random")) == "sigma_points"

    def channel_configs(self, reading_names: tuple[str, ...]) -> tuple[ChannelConfig, ...]:
        """The configured channels, or the thesis's single height channel for the log's first reading."""
        if not self.channels:
            return (
                ChannelConfig(
                    reading_names[0],
                    self.thesis.sensor_degree,
                    self.thesis.start_height_intercept_px,
                    self.thesis.start_height_slope_px_per_mm,
                    self.thesis.start_sigma_height_px,
                ),
            )
        missing = [c.name for c in self.channels if c.name not in reading_names]
        if missing:
            raise ConfigError(
                f"channel(s) {', '.join(missing)} are not readings of this log.",
                field="channels[].name",
                fix=f"name the log's readings: {', '.join(reading_names)}.",
            )
        return self.channels


def upgrade_settings(fields: JsonObject) -> JsonObject:
    """Settings a model file keeps (``summary.config``), read as today's: a file written before the groups
    has flat names (``regroup`` reads them), and where one of ``ZERO_WAS_OFF`` was off it held 0, which is
    None now."""
    return {k: None if k in ZERO_WAS_OFF and v == 0 else v for k, v in fields.items()}


def refuse_bearing_settings(config: EMConfig, data: Any) -> None:
    """A planar log (``LandmarkLog``) without a single bearing cannot run settings that need one: a channel
    with bearing terms predicts none of its readings (they count as missing), and the start search scores
    poses by bearings. One line naming the field (``ConfigError``), before EM would fail on it."""
    if not data.geometry.has_heading or np.isfinite(data.obs_bearing_rad).any():
        return
    source = data.source
    for i, ch in enumerate(config.channels):
        if ch.bearing_degree > 0:
            raise ConfigError(
                f"{source} has no bearings, and channel {ch.name} has bearing terms (its reading depends on the "
                "bearing), so none of its readings could be used.",
                field=f"channels[{i}].bearing_degree",
                fix="set bearing_degree: 0 for that channel in your --config.",
            )
    if config.search.start_s is not None:
        raise ConfigError(
            f"{source} has no bearings, and the start search scores start poses by them.",
            field="search.start_s",
            fix="pass --set search.start_s=null and give where the robot starts: start_prior_mean (x mm, y mm, heading "
            "rad) and start_prior_sd.",
        )
