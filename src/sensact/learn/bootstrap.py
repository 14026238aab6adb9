"""Chapter 3: online learning of the inverse sensor model S(o) and the action model A(c) from each other.

Algorithm 1 (sec. 3.2.3) and its two halves (sec. 3.2.1 and 3.2.2) share one compiled step function,
``step_kernel``. The streaming learner (``BootstrapLearner.update``) calls it once per time step; the batch
path (``learn_bootstrap``) calls it from a compiled loop over the whole log. Both paths therefore give
bit-identical models.

Conventions
-----------
* A step ``k`` has a time ``t_k``, the command ``c_k`` that is in force from ``t_k`` until ``t_{k+1}``,
  and optionally an observation ``o_k`` taken at ``t_k``. The motion ``A(c_{k-1}) (t_k - t_{k-1})`` is
  integrated before ``o_k`` is used, so that ``w_a`` and ``o_k`` describe the same instant.
* Learned quantities have no absolute scale (sec. 3.1): ``S`` maps observations to positions in the
  learner's own unit, ``A`` maps commands to velocities in that unit per second.
* Regression inputs are normalized (``u = (o - center)/scale``, ``c / command_scale``, and eq. 3.2's
  cumulative sums in units of ``time_scale_s``) for conditioning only; the fitted polynomials do not
  depend on it (the ridge is used only when a solve is numerically singular).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from sensact.core.degree import N_STATS
from sensact.core.polyfit import renormalize
from sensact.health import MIN_EXPLAINED, MIN_READINGS, Health, HealthFlag
from sensact.learn.bootstrap_kernel import (
    A_READY,
    DEG_S,
    I_AUTO,
    I_DEG_MAX,
    I_LEARN_A,
    I_LEARN_S,
    I_P,
    I_Q,
    I_WINDOW,
    N_GATED,
    N_IPRM,
    N_OBS,
    N_PRM,
    N_SCAL,
    N_STEPS,
    P_ALPHA,
    P_CMD_SCALE,
    P_DEG_EVAL,
    P_DEG_THRESHOLD,
    P_DEG_WARMUP,
    P_DIV,
    P_GAMMA,
    P_GATE,
    P_OBS_CENTER,
    P_OBS_MAX,
    P_OBS_MIN,
    P_OBS_SCALE,
    P_REBASE,
    P_RIDGE,
    P_T_START,
    P_TIME_SCALE,
    REBASE_BOUND,
    S_READY,
    STATE_NAMES,
    STATUS,
    STATUS_DIVERGED,
    STATUS_OK,
    T_DIVERGED,
    W_A,
    W_S,
    run_kernel,
    step_kernel,
)
from sensact.models.polynomial import Polynomial1D
from sensact.progress import Progress
from sensact.records import JsonObject

A0Kind = Literal["linear", "sign", "constant"]


@dataclass(frozen=True)
class BootstrapConfig:
    """Algorithm 1's constants. Defaults are the thesis's (sec. 3.3.1 and 3.3.2)."""

    gamma: float = 0.999  # discount of regression weights per observation, sec. 3.3.2
    alpha: float = 1.0 / 30.0  # pull of w_a toward w_s per observation, sec. 3.3.2
    t_start_s: float = 20.0  # length of each ramp-up phase, sec. 3.3.2
    sensor_degree: int = 3  # cubic S, sec. 3.3.1
    action_degree: int = 4  # quartic A, sec. 3.3.1
    a0: A0Kind = "linear"  # starting action model A0(c) = c, sec. 3.3.2; sign and constant: sec. 3.3.3
    # Regress on the mean of this many consecutive observations (and of w_a at the same instants).
    # 1 is the thesis; the default averages 1 s at 20 Hz (errors-in-variables, see docs/bootstrap.md).
    observation_window: int = 20
    # Automatic degree of S (sec. 3.3.3); see sensact.core.degree for the rule.
    auto_sensor_degree: bool = False
    degree_start: int = 1  # "we start by fitting a first degree (linear) polynomial", sec. 3.3.3
    degree_max: int = 6
    degree_warmup_s: float = 40.0  # residuals are scored only after the fit has seen this much data
    degree_eval_s: float = 40.0  # ... and the ratio is tested only after this much more
    degree_threshold: float = 1.3  # raise the degree when global/local error ratio exceeds this
    # Input validity window: observations outside [min, max] are treated as missing (not in the thesis).
    observation_min: float | None = None
    observation_max: float | None = None
    # Outlier gate (not in the thesis; off by default): skip an observation whose |S(o) - w_a| exceeds
    # this many running RMS innovations. For sensors with gross outliers, such as the HC-SR04 sonar.
    outlier_gate: float | None = None
    # Normalization, for conditioning only. None: derived from the data (batch) or the first samples.
    command_scale: float | None = None
    observation_center: float | None = None
    observation_scale: float | None = None
    time_scale_s: float = 50.0  # ~ the regression memory, 1/(1-gamma) observations at 20 Hz
    ridge: float = 1e-10  # relative Tikhonov term, used only when a solve is numerically singular
    divergence_factor: float = 1e4  # |w| beyond this many times its ramp-up magnitude = runaway
    history_interval_s: float = 1.0  # model snapshots for learning curves (batch path)

    def __post_init__(self) -> None:
        checks = {
            "gamma must be in (0, 1]": 0.0 < self.gamma <= 1.0,
            "alpha must be in [0, 1]": 0.0 <= self.alpha <= 1.0,
            "t_start_s must be >= 0": self.t_start_s >= 0.0,
            "sensor_degree and action_degree must be in [0, 10]": 0 <= min(self.sensor_degree, self.action_degree)
            and max(self.sensor_degree, self.action_degree) <= 10,
            "need 0 <= degree_start <= degree_max <= 10": 0 <= self.degree_start <= self.degree_max <= 10,
            "t_start_s must be at most a day": self.t_start_s <= 86_400,
            "time_scale_s must be > 0": self.time_scale_s > 0,
            "observation_window must be >= 1": self.observation_window >= 1,
            "history_interval_s must be > 0": self.history_interval_s > 0,
            "outlier_gate must be > 0 (or null for off)": self.outlier_gate is None or self.outlier_gate > 0,
        }
        bad = [msg for msg, ok in checks.items() if not ok]
        if bad:
            raise ValueError("; ".join(bad))


# ---- Python side ----------------------------------------------------------------------------------------


def a0_function(a0: A0Kind | Callable[[float], float]) -> Callable[[float], float]:
    """The starting action model A0 (sec. 3.3.2 and 3.3.3) as a scalar function."""
    if callable(a0):
        return lambda c: float(a0(c))
    if a0 == "linear":
        return float
    if a0 == "sign":
        return lambda c: float((c > 0) - (c < 0))
    if a0 == "constant":
        return lambda c: 1.0
    raise ValueError(f"unknown A0 {a0!r}: use linear, sign, constant or a callable")


def _a0_vector(a0: A0Kind | Callable[[float], float], commands: np.ndarray) -> np.ndarray:
    if a0 == "linear":
        return commands.astype(float).copy()
    if a0 == "sign":
        return np.sign(commands).astype(float)
    if a0 == "constant":
        return np.ones_like(commands, dtype=float)
    f = a0_function(a0)
    return np.array([f(c) for c in commands], dtype=float)


@dataclass(frozen=True)
class Normalization:
    """Input scales used inside the regressions (conditioning only)."""

    command_scale: float
    observation_center: float
    observation_scale: float

    @classmethod
    def from_data(cls, commands: np.ndarray, observations: np.ndarray, config: BootstrapConfig) -> Normalization:
        c = np.asarray(commands, dtype=float)
        o = np.asarray(observations, dtype=float)
        o = o[np.isfinite(o)]
        if config.observation_min is not None:
            o = o[o >= config.observation_min]
        if config.observation_max is not None:
            o = o[o <= config.observation_max]
        cmax = float(np.max(np.abs(c))) if c.size else 0.0
        lo, hi = (float(o.min()), float(o.max())) if o.size else (0.0, 1.0)
        return cls(
            command_scale=config.command_scale or (cmax if cmax > 0 else 1.0),
            observation_center=(
                config.observation_center if config.observation_center is not None else 0.5 * (lo + hi)
            ),
            observation_scale=config.observation_scale or (0.5 * (hi - lo) if hi > lo else max(abs(lo), 1.0)),
        )


@dataclass(frozen=True)
class BootstrapHistory:
    """What the batch path records: per-step location estimates and periodic model snapshots."""

    times_s: np.ndarray  # (T,)
    w_a: np.ndarray  # (T,) action-based location estimate after each step
    w_s: np.ndarray  # (T,) sensor-based estimate, NaN where no observation was used
    snapshot_t_s: np.ndarray  # (K,) time since the start of the log
    snapshot_sensor_coef: np.ndarray  # (K, P) in the result's sensor normalization; NaN before ready
    snapshot_action_coef: np.ndarray  # (K, d+1) in the result's action normalization
    snapshot_sensor_degree: np.ndarray  # (K,)

    def arrays(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class BootstrapResult:
    """Learned models, how the run ended, and (batch path) its history."""

    sensor: Polynomial1D
    action: Polynomial1D
    status: Literal["ok", "diverged"]
    diverged_at_s: float | None  # seconds after the first command, where the clock starts
    sensor_degree: int
    n_steps: int
    n_observations: int
    n_gated: int
    mode: str
    config: BootstrapConfig
    normalization: Normalization
    history: BootstrapHistory | None = field(default=None, repr=False)

    def sensor_at(self, k: int) -> Polynomial1D | None:
        """The sensor model of history snapshot ``k`` (None if not yet learned)."""
        assert self.history is not None
        coef = self.history.snapshot_sensor_coef[k]
        deg = int(self.history.snapshot_sensor_degree[k])
        if not np.all(np.isfinite(coef[: deg + 1])):
            return None
        return Polynomial1D(
            tuple(coef[: deg + 1]),
            self.sensor.center,
            self.sensor.scale,
            self.sensor.input_name,
            self.sensor.input_unit,
            self.sensor.output_unit,
        )

    def action_at(self, k: int) -> Polynomial1D | None:
        assert self.history is not None
        coef = self.history.snapshot_action_coef[k]
        if not np.all(np.isfinite(coef)):
            return None
        return Polynomial1D(
            tuple(coef),
            self.action.center,
            self.action.scale,
            self.action.input_name,
            self.action.input_unit,
            self.action.output_unit,
        )

    def to_dict(self) -> JsonObject:
        from sensact.config import config_to_dict

        return {
            "kind": "bootstrap_result",
            "mode": self.mode,
            "status": self.status,
            "diverged_at_s": self.diverged_at_s,
            "sensor_degree": self.sensor_degree,
            "n_steps": self.n_steps,
            "n_observations": self.n_observations,
            "n_gated": self.n_gated,
            "sensor": self.sensor.to_dict(),
            "action": self.action.to_dict(),
            "normalization": dict(self.normalization.__dict__),
            "config": config_to_dict(self.config),
        }


class _Engine:
    """The compiled learner's arrays and their conversion to models."""

    def __init__(
        self,
        config: BootstrapConfig,
        norm: Normalization,
        *,
        learn_sensor: bool,
        learn_action: bool,
        fixed_sensor: Polynomial1D | None,
        fixed_action: Polynomial1D | None,
        units: tuple[str, str, str],
    ) -> None:
        self.config, self.norm = config, norm
        self.learn_sensor, self.learn_action = learn_sensor, learn_action
        self.units = units  # (command unit, observation unit, location unit)
        if learn_sensor:
            P = (config.degree_max if config.auto_sensor_degree else config.sensor_degree) + 1
        else:
            assert fixed_sensor is not None
            P = fixed_sensor.degree + 1
        Q = (config.action_degree if learn_action else fixed_action.degree) + 2  # type: ignore[union-attr]
        self.P, self.Q = P, Q
        self.Gs, self.hs, self.cs, self.cs_prev, self.Ls = (
            np.zeros((P, P)),
            np.zeros(P),
            np.zeros(P),
            np.zeros(P),
            np.zeros((P, P)),
        )
        self.Ga, self.ha, self.ca, self.ca_prev, self.La = (
            np.zeros((Q, Q)),
            np.zeros(Q),
            np.zeros(Q),
            np.zeros(Q),
            np.zeros((Q, Q)),
        )
        self.xa = np.zeros(Q)
        self.xa[0] = 1.0  # intercept w_0 of eq. 3.2
        self.xbar = np.zeros(Q)
        win = config.observation_window
        self.buf_o, self.buf_w, self.buf_x = np.zeros(win), np.zeros(win), np.zeros((win, Q))
        self.stats, self.ring = np.zeros(N_STATS), np.zeros(win)
        self.fixed_s = np.zeros(P)
        self.fixed_a = np.zeros(Q - 1)
        if fixed_sensor is not None:
            self.fixed_s[:] = renormalize(
                np.asarray(fixed_sensor.coef),
                fixed_sensor.center,
                fixed_sensor.scale,
                norm.observation_center,
                norm.observation_scale,
            )
        if fixed_action is not None:
            self.fixed_a[:] = renormalize(
                np.asarray(fixed_action.coef), fixed_action.center, fixed_action.scale, 0.0, norm.command_scale
            )
        self.sc = np.zeros(N_SCAL)
        self.sc[DEG_S] = config.degree_start if config.auto_sensor_degree else config.sensor_degree
        params = {
            P_GAMMA: config.gamma,
            P_ALPHA: config.alpha,
            P_T_START: config.t_start_s,
            P_CMD_SCALE: norm.command_scale,
            P_OBS_CENTER: norm.observation_center,
            P_OBS_SCALE: norm.observation_scale,
            P_TIME_SCALE: config.time_scale_s,
            P_RIDGE: config.ridge,
            P_DIV: config.divergence_factor,
            P_REBASE: REBASE_BOUND,
            P_DEG_THRESHOLD: config.degree_threshold,
            P_OBS_MIN: -np.inf if config.observation_min is None else config.observation_min,
            P_OBS_MAX: np.inf if config.observation_max is None else config.observation_max,
            P_GATE: config.outlier_gate or 0.0,
            P_DEG_WARMUP: config.degree_warmup_s,
            P_DEG_EVAL: config.degree_eval_s,
        }
        self.prm = np.zeros(N_PRM)
        self.prm[list(params)] = list(params.values())
        iparams = {
            I_LEARN_S: int(learn_sensor),
            I_LEARN_A: int(learn_action),
            I_AUTO: int(config.auto_sensor_degree),
            I_DEG_MAX: config.degree_max,
            I_P: P,
            I_Q: Q,
            I_WINDOW: win,
        }
        self.iprm = np.zeros(N_IPRM, dtype=np.int64)
        self.iprm[list(iparams)] = list(iparams.values())
        self.fixed_sensor, self.fixed_action = fixed_sensor, fixed_action

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The compiled state, in the order ``step_kernel`` unpacks it."""
        return tuple(getattr(self, name) for name in STATE_NAMES)

    @property
    def mode(self) -> str:
        if self.learn_sensor and self.learn_action:
            return "both"
        return "sensor_from_action" if self.learn_sensor else "action_from_sensor"

    def sensor_model(self) -> Polynomial1D:
        if not self.learn_sensor:
            return self.fixed_sensor  # type: ignore[return-value]
        deg = int(self.sc[DEG_S])
        coef = self.cs[: deg + 1] if self.sc[S_READY] == 1.0 else np.full(deg + 1, np.nan)
        return Polynomial1D(
            tuple(coef), self.norm.observation_center, self.norm.observation_scale, "o", self.units[1], self.units[2]
        )

    def action_model(self) -> Polynomial1D:
        if not self.learn_action:
            return self.fixed_action  # type: ignore[return-value]
        coef = self.ca[1:] / self.config.time_scale_s if self.sc[A_READY] == 1.0 else np.full(self.Q - 1, np.nan)
        return Polynomial1D(tuple(coef), 0.0, self.norm.command_scale, "c", self.units[0], f"{self.units[2]}/s")

    def result(self, history: BootstrapHistory | None) -> BootstrapResult:
        diverged = self.sc[STATUS] == STATUS_DIVERGED
        return BootstrapResult(
            sensor=self.sensor_model(),
            action=self.action_model(),
            status="diverged" if diverged else "ok",
            diverged_at_s=float(self.sc[T_DIVERGED]) if diverged else None,
            sensor_degree=int(self.sc[DEG_S]) if self.learn_sensor else self.P - 1,
            n_steps=int(self.sc[N_STEPS]),
            n_observations=int(self.sc[N_OBS]),
            n_gated=int(self.sc[N_GATED]),
            mode=self.mode,
            config=self.config,
            normalization=self.norm,
            history=history,
        )


class BootstrapLearner:
    """The streaming form of Algorithm 1: call ``update(t, command, observation_or_None)`` per step. Until
    the first non-zero command it waits: the clock starts there, as in ``learn_bootstrap``.

    Normalization (conditioning only) comes from ``normalization`` or the config; when neither gives it,
    it is taken from the first non-zero command and the first observation.
    """

    def __init__(
        self,
        config: BootstrapConfig | None = None,
        *,
        a0: A0Kind | Callable[[float], float] | None = None,
        normalization: Normalization | None = None,
        units: tuple[str, str, str] = ("", "", "w"),
    ) -> None:
        self.config = config or BootstrapConfig()
        self._a0 = a0_function(a0 if a0 is not None else self.config.a0)
        cfg = self.config
        self._pending_cmd = normalization is None and cfg.command_scale is None
        self._pending_obs = normalization is None and (cfg.observation_center is None or cfg.observation_scale is None)
        norm = normalization or Normalization(
            cfg.command_scale or 1.0, cfg.observation_center or 0.0, cfg.observation_scale or 1.0
        )
        self._engine = _Engine(
            cfg, norm, learn_sensor=True, learn_action=True, fixed_sensor=None, fixed_action=None, units=units
        )
        self._arrays = self._engine.arrays()

    def update(self, t: float, command: float, observation: float | None = None) -> None:
        o = math.nan if observation is None else float(observation)
        if self._pending_cmd and command != 0.0:
            self._set_norm(command_scale=abs(float(command)))
        if self._pending_obs and o == o:
            self._set_norm(observation_center=o, observation_scale=abs(o) if o != 0.0 else 1.0)
        step_kernel(self._arrays, float(t), float(command), self._a0(command), o)

    def _set_norm(self, **kw: float) -> None:
        e = self._engine
        e.norm = Normalization(**{**e.norm.__dict__, **kw})
        e.prm[P_CMD_SCALE] = e.norm.command_scale
        e.prm[P_OBS_CENTER] = e.norm.observation_center
        e.prm[P_OBS_SCALE] = e.norm.observation_scale
        if "command_scale" in kw:
            self._pending_cmd = False
        if "observation_center" in kw:
            self._pending_obs = False

    @property
    def sensor_model(self) -> Polynomial1D:
        return self._engine.sensor_model()

    @property
    def action_model(self) -> Polynomial1D:
        return self._engine.action_model()

    @property
    def w_a(self) -> float:
        return float(self._engine.sc[W_A])

    @property
    def w_s(self) -> float:
        return float(self._engine.sc[W_S])

    @property
    def status(self) -> str:
        return "diverged" if self._engine.sc[STATUS] == STATUS_DIVERGED else "ok"

    def result(self) -> BootstrapResult:
        return self._engine.result(None)


def _check_arrays(times: np.ndarray, commands: np.ndarray, observations: np.ndarray) -> tuple[np.ndarray, ...]:
    t = np.ascontiguousarray(times, dtype=float)
    c = np.ascontiguousarray(commands, dtype=float)
    o = np.ascontiguousarray(observations, dtype=float)
    if not (t.ndim == c.ndim == o.ndim == 1 and len(t) == len(c) == len(o)):
        raise ValueError("times, commands and observations must be 1-D arrays of one length")
    if len(t) < 2:
        raise ValueError("a log needs at least two steps")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be finite and strictly increasing")
    if not np.all(np.isfinite(c)):
        raise ValueError("commands must be finite")
    return t, c, o


def _run_engine(
    engine: _Engine,
    t: np.ndarray,
    c: np.ndarray,
    a0v: np.ndarray,
    o: np.ndarray,
    progress: Progress | None,
    chunk: int = 200_000,
) -> BootstrapResult:
    T = len(t)
    n_snap_max = int((t[-1] - t[0]) / engine.config.history_interval_s) + 3
    w_a = np.full(T, np.nan)
    w_s = np.full(T, np.nan)
    snap_t = np.full(n_snap_max, np.nan)
    snap_s = np.full((n_snap_max, engine.P), np.nan)
    snap_a = np.full((n_snap_max, engine.Q - 1), np.nan)
    snap_deg = np.zeros(n_snap_max)
    n_snap = np.zeros(1, dtype=np.int64)
    for k0 in range(0, T, chunk):
        k1 = min(T, k0 + chunk)
        run_kernel(
            engine.arrays(),
            t,
            c,
            a0v,
            o,
            k0,
            k1,
            w_a,
            w_s,
            snap_t,
            snap_s,
            snap_a,
            snap_deg,
            n_snap,
            engine.config.history_interval_s,
        )
        if progress is not None:
            progress("Algorithm 1", k1, T)
        if engine.sc[STATUS] != STATUS_OK:
            break
    K = int(n_snap[0])
    hist = BootstrapHistory(t, w_a, w_s, snap_t[:K], snap_s[:K], snap_a[:K], snap_deg[:K].astype(np.int64))
    return engine.result(hist)


def first_command_s(times_s: np.ndarray, commands: np.ndarray) -> float | None:
    """Seconds into the log of the first non-zero command, where Algorithm 1's clock starts (``step_kernel``
    waits for it), or None when the robot is never commanded."""
    moved = np.flatnonzero(np.asarray(commands, dtype=float) != 0.0)
    return None if moved.size == 0 else float(times_s[moved[0]] - times_s[0])


def learn_bootstrap(
    times_s: np.ndarray,
    commands: np.ndarray,
    observations: np.ndarray,
    config: BootstrapConfig | None = None,
    *,
    a0: A0Kind | Callable[[float], float] | None = None,
    normalization: Normalization | None = None,
    units: tuple[str, str, str] = ("", "", "w"),
    progress: Progress | None = None,
) -> BootstrapResult:
    """Algorithm 1 over a whole log (the compiled batch path). ``observations`` is NaN where none. Its
    clock starts at the first non-zero command (``first_command_s``); the steps before are not learned from."""
    config = config or BootstrapConfig()
    t, c, o = _check_arrays(times_s, commands, observations)
    if first_command_s(t, c) is None:
        raise ValueError("every command is zero: Algorithm 1 starts when the robot is first commanded")
    norm = normalization or Normalization.from_data(c, o, config)
    engine = _Engine(
        config, norm, learn_sensor=True, learn_action=True, fixed_sensor=None, fixed_action=None, units=units
    )
    return _run_engine(engine, t, c, _a0_vector(a0 if a0 is not None else config.a0, c), o, progress)


def learn_sensor_from_action(
    times_s: np.ndarray,
    commands: np.ndarray,
    observations: np.ndarray,
    action: Polynomial1D | None = None,
    config: BootstrapConfig | None = None,
    *,
    units: tuple[str, str, str] = ("", "", "w"),
    progress: Progress | None = None,
) -> BootstrapResult:
    """Sec. 3.2.1: regress ``(o_t, w_a,t)`` with ``w_a`` integrated from a given action model.

    With ``action=None`` the action is taken as constant (A = 1), which fits ``(o_t, t)``: the thesis's
    sensor model from a constant action of unknown speed. With ``config.auto_sensor_degree`` the degree is
    chosen online (sec. 3.3.3).
    """
    config = config or BootstrapConfig()
    t, c, o = _check_arrays(times_s, commands, observations)
    norm = Normalization.from_data(c, o, config)
    fixed = (
        action if action is not None else Polynomial1D((1.0,), 0.0, norm.command_scale, "c", units[0], f"{units[2]}/s")
    )
    engine = _Engine(
        config, norm, learn_sensor=True, learn_action=False, fixed_sensor=None, fixed_action=fixed, units=units
    )
    return _run_engine(engine, t, c, np.zeros_like(c), o, progress)


def learn_action_from_sensor(
    times_s: np.ndarray,
    commands: np.ndarray,
    observations: np.ndarray,
    sensor: Polynomial1D,
    config: BootstrapConfig | None = None,
    *,
    units: tuple[str, str, str] = ("", "", "w"),
    progress: Progress | None = None,
) -> BootstrapResult:
    """Sec. 3.2.2: fit ``A`` so that ``w_0 + sum_j a_j dt sum_{i<t} c_i^j`` matches ``S(o_t)`` (eq. 3.2)."""
    config = config or BootstrapConfig()
    t, c, o = _check_arrays(times_s, commands, observations)
    engine = _Engine(
        config,
        Normalization.from_data(c, o, config),
        learn_sensor=False,
        learn_action=True,
        fixed_sensor=sensor,
        fixed_action=None,
        units=units,
    )
    return _run_engine(engine, t, c, np.zeros_like(c), o, progress)


def bootstrap_health(
    res: BootstrapResult, commands: np.ndarray, observations: np.ndarray, t: np.ndarray | None = None
) -> Health:
    """Algorithm 1's result as EM's are flagged (docs/errors.md): diverged, learned from a command or a reading
    that never varies (A's slope or S's shape is then whatever the start said); given ``t``, a first ramp-up as
    long as the log, in which A never left A0 (sec. 3.3.2); and S and A that do not explain each other."""
    c = np.asarray(commands, dtype=float)
    o = np.asarray(observations, dtype=float)
    span = float(t[-1] - t[0]) if t is not None and len(t) else float("inf")
    o = o[np.isfinite(o)]
    flags = [
        HealthFlag(
            "ramp_up_too_long",
            f"t_start_s ({res.config.t_start_s:g} s) is as long as the {span:.4g}-s log: the action model never "
            "left its start (sec. 3.3.2); record longer, or shorten t_start_s.",
        )
        if res.config.t_start_s >= span
        else None,
        HealthFlag("diverged", "Algorithm 1 diverged; the models are those before it did.")
        if res.status == "diverged"
        else None,
        HealthFlag("command_constant", f"the command never varies (always {c[0]:g}).")
        if c.size and np.ptp(c) == 0
        else None,
        HealthFlag("reading_constant", f"the reading never varies (always {o[0]:g}).")
        if o.size and np.ptp(o) == 0
        else None,
    ]
    if res.status == "ok" and o.size and np.ptp(o) > 0:
        flags += _agreement(res)
    return Health.of(*flags)


def _agreement(res: BootstrapResult) -> list[HealthFlag]:
    """EM's ``reading_explains_nothing`` and ``gain_sign_flips`` for Algorithm 1, with no truth: once A_t is in
    use (t > 2 t_start, line 6), its location estimate w_a and the sensor's w_s = S_t(o) must agree (eq. 3.2).
    A sonar that reads noise gives an S fitted to noise and an A that hardly moves; neither explains the other."""
    h = res.history
    if h is None:
        return []
    ok = np.isfinite(h.w_s) & np.isfinite(h.w_a) & (h.times_s - h.times_s[0] > 2.0 * res.config.t_start_s)
    ws, wa = h.w_s[ok], h.w_a[ok]
    if ws.size < MIN_READINGS or np.var(ws) == 0.0:
        return []
    explained = 1.0 - float(np.var(ws - wa)) / float(np.var(ws))
    if explained < MIN_EXPLAINED:
        return [
            HealthFlag(
                "reading_explains_nothing",
                f"S(o) and A's path explain {max(explained, 0.0):.0%} of each other's variance: the reading is "
                "noise, or the log never moved the robot enough to tell.",
            )
        ]
    half = ws.size // 2
    halves = ((wa[:half], ws[:half]), (wa[half:], ws[half:]))
    if all(np.ptp(x) > 0 for x, _ in halves):
        slopes = [float(np.polyfit(x, y, 1)[0]) for x, y in halves]
        if slopes[0] * slopes[1] < 0:
            return [
                HealthFlag(
                    "gain_sign_flips",
                    f"S(o) rises with A's path in one half of the log and falls in the other (slopes "
                    f"{slopes[0]:.3g} and {slopes[1]:.3g}): the models are fitted to noise.",
                )
            ]
    return []
