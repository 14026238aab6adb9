"""The EM loop (secs. 4.1 and 4.4.1): alternate E- and M-steps and keep the most likely model.

The likelihood of an approximate EM fluctuates, so the loop stops when ``patience`` iterations (50 in
the thesis) pass without a new best ``log P(O | C, lambda)``, or at ``max_iterations``. Outliers are
pruned in the first iteration (and, with ``prune_when_freed``, once more when the robust readings take
over), and stay pruned. Ctrl-C ends the loop cleanly with the best model so far (``stop_reason ==
"interrupted"``). Beyond the thesis, ``turn_restarts`` runs the loop again from a tighter start when a
range function turned over or bent or EM did not settle (``restart_while_lost``), and on a range-only
log from the start EM learned when the given one moved metres (``given_start.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from dataclasses import replace as dc_replace
from functools import partial
from typing import Any

import numpy as np

from sensact.errors import ConfigError, LogFormatError
from sensact.learn.em.checks import fall_per_sighting, lost_fit_signs
from sensact.learn.em.config import EMConfig, refuse_bearing_settings
from sensact.learn.em.delay_search import search_delay
from sensact.learn.em.estep import Posteriors, e_step, log_likelihood
from sensact.learn.em.forward import FLIP, drives_backward, turned_model, turned_posteriors
from sensact.learn.em.given_start import start_moved_mm
from sensact.learn.em.initial import initial_model, motion_sd_floor, motion_sd_start
from sensact.learn.em.mount import MountFreedom, mount_freedom, search_mount
from sensact.learn.em.mstep import m_step
from sensact.learn.em.outliers import bearing_outliers
from sensact.learn.em.ridge import search_ridge
from sensact.learn.em.start import OnTrial, race_starts, start_candidates
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.action_table import ActionTable
from sensact.models.em_model import EMModel
from sensact.models.linear_action import LinearActionModel

# (iteration, loglik, best loglik, iterations since the best) -> None
Progress = Callable[[int, float, float, int], None]
# (restart number from 1, the last fit's signs of being lost (checks.lost_fit_signs), the new start sigmas)
OnRestart = Callable[[int, list[dict[str, Any]], dict[str, float]], None]
# (how far the given start moved, mm; the learned start EM runs again from) -> None
OnStartMoved = Callable[[float, np.ndarray], None]


def refuse_no_sightings(data: LandmarkLog) -> None:
    """EM learns every sensor model, and places the robot, from the sightings of mapped landmarks (secs.
    4.2-4.3): a log with none has nothing to learn from. One line (``LogFormatError``), before EM."""
    if not data.n_observations:
        raise LogFormatError(
            "the log has no landmark sightings, and EM learns the sensor model and places the robot from them.",
            file=data.source,
            field="observations",
            fix="give a log in which the robot sees landmarks of the map (MRCLAM: Measurement.dat rows whose "
            "barcode is a landmark's, not another robot's).",
        )


def refuse_too_few_readings(model: EMModel, data: LandmarkLog) -> None:
    """Each channel's M-step (eqs. 4.25-4.28) fits its f_i and sigma_i to the channel's readings: with
    no more readings than those parameters the fit has nothing left over to measure the noise by, and EM
    would report a sigma of nothing. One line naming the channel (``LogFormatError``), before EM."""
    readings = data.obs_readings if data.obs_readings.ndim == 2 else data.obs_readings[:, None]
    for j, ch in enumerate(model.sensor.channels):
        col = data.reading_names.index(ch.name) if ch.name in data.reading_names else j
        n = int(np.isfinite(readings[:, col]).sum())
        p = ch.function.degree + 1 + len(ch.bearing_terms) + 1
        if n <= p:
            raise LogFormatError(
                f"{n} readings of {ch.name}, and its model has {p} parameters (f of degree {ch.function.degree}"
                + (f", {len(ch.bearing_terms)} bearing terms" if ch.bearing_terms else "")
                + ", sigma) to learn from them.",
                file=data.source,
                field=ch.name,
                fix="give a longer log, or lower the channel's degree in --config.",
            )


@dataclass(frozen=True, eq=False)
class EMResult:
    model: EMModel  # the model with the highest likelihood
    loglik_history: np.ndarray  # log P(O | C, lambda_i) for every iteration i
    velocity_history: np.ndarray  # (iterations, A, n) the action table (or beta) of every lambda_i
    sigma_history: np.ndarray  # (iterations, C+1) each channel's sigma, then sigma_2, of every lambda_i
    best_iteration: int
    stop_reason: str  # "converged", "max_iterations", "diverged" or "interrupted"
    n_observations: int
    n_pruned: int
    seconds: float
    config: EMConfig
    posteriors: Posteriors | None = field(default=None, repr=False)  # of the best model
    motion_sd_history: np.ndarray | None = None  # (iterations, G, n) Sigma_m's standard deviations
    start_search: dict[str, Any] | None = None  # what the start search tried and chose
    freed_at: int = -1  # the iteration after which Sigma_m, the terms and robust readings were freed (-1: never held)
    ridge: list[dict[str, Any]] | None = None  # each ridge search: its iteration, shift, likelihoods (ridge.py)
    delay_search: list[dict[str, Any]] | None = None  # each delay search: its iteration, delays, likelihoods
    restarts: list[dict[str, Any]] | None = None  # each run while the fit looked lost (restart_while_lost)
    n_pruned_when_freed: int = 0  # of n_pruned, those the gate dropped again when the robust readings took over
    # a range-only fit that ended facing backward, reported turned by pi (forward.py; the same likelihood)
    turned_to_face_forward: bool = False
    # a range-only fit whose given start moved metres: the start, where EM put it, both runs' likelihoods
    start_moved: dict[str, Any] | None = None
    # which of the sensor mount's components the M-step learned, and why the rest were held (mount.py)
    mount: MountFreedom | None = None
    mount_search: list[dict[str, Any]] | None = None  # each mount search (mount.search_mount)

    @property
    def iterations(self) -> int:
        return int(self.loglik_history.size)

    @property
    def n_used(self) -> int:
        """The sightings the best model's E-step used (after every prune)."""
        if self.posteriors is not None:
            return int(np.count_nonzero(self.posteriors.obs_used))
        return self.n_observations - self.n_pruned

    @property
    def loglik_best(self) -> float:
        return float(self.loglik_history[self.best_iteration])

    @property
    def pruned_fraction(self) -> float:
        """The share of the log's sightings that the gates dropped (sec. 4.4.1's, and prune_when_freed's)."""
        return (self.n_observations - self.n_used) / self.n_observations if self.n_observations else 0.0

    def summary(self) -> dict[str, Any]:
        return {
            "iterations": self.iterations,
            "best_iteration": self.best_iteration,
            "stop_reason": self.stop_reason,
            "loglik_start": float(self.loglik_history[0]),
            "loglik_best": self.loglik_best,
            "n_observations": self.n_observations,
            "n_used": self.n_used,
            "n_pruned": self.n_pruned,
            "n_pruned_when_freed": self.n_pruned_when_freed,
            "pruned_fraction": self.pruned_fraction,
            "sensor_mount": None if self.mount is None else self.mount.to_dict(),
            "mount_search": self.mount_search,
            # how far the likelihood fell on average after the best, per sighting used (checks.unsettled_fit)
            "fall_per_sighting": fall_per_sighting(self.loglik_history, self.best_iteration, self.n_used),
            "seconds": self.seconds,
            "start_search": self.start_search,
            "freed_at": self.freed_at,
            "ridge": self.ridge,
            "delay_search": self.delay_search,
            "restarts": self.restarts,
            **({"turned_to_face_forward": True} if self.turned_to_face_forward else {}),
            **({"start_moved": self.start_moved} if self.start_moved else {}),
            "config": asdict(self.config),
        }


def fit_em(
    data: LandmarkLog,
    initial: EMModel | None = None,
    config: EMConfig | None = None,
    *,
    progress: Progress | None = None,
    on_restart: OnRestart | None = None,
    on_race: OnTrial | None = None,
    on_start_moved: OnStartMoved | None = None,
) -> EMResult:
    """Learn the action table, the sensor model and the prior from ``data`` by EM (Algorithm of ch. 4);
    with ``turn_restarts``, EM again from a tighter start while a channel's f turns over or bends or EM did not
    settle (``on_restart`` hears of each restart before it runs; none after Ctrl-C). ``on_race`` hears of the
    start race's trials (``start.race_starts``), before ``progress`` hears of the first iteration. A fit
    whose sensor reads no bearing runs again from its learned start when that moved metres from the given
    one (``given_start.py``; ``on_start_moved`` hears of it first), and is reported facing the way the
    robot drives (``facing_forward``)."""
    cfg = config or EMConfig()
    res = facing_forward(_fit_while_lost(data, initial, cfg, progress, on_restart, on_race), data)
    start = initial or initial_model(data, cfg)
    moved = None if res.stop_reason == "interrupted" else start_moved_mm(start, res.model, data, cfg)
    if moved is None:
        return res
    # a range-only start metres off: again from where EM put it, facing forward (given_start.py); the
    # given heading was as wrong as the position, and ranges cannot tell it, so the headings race there
    if on_start_moved is not None:
        on_start_moved(moved, res.model.prior_mean.copy())
    winner, race = race_starts(data, headings_at(start, res.model.prior_mean[:2]), cfg, fit_em_once, on_trial=on_race)
    again = _fit_while_lost(data, winner, cfg, progress, on_restart, on_race)
    best, scores = most_likely([res, again], data)
    info = {
        "given": start.prior_mean.tolist(),
        "learned": res.model.prior_mean.tolist(),
        "moved_mm": moved,
        "heading_race": {"winner": race["winner"], "headings_rad": [float(h) for h in race_headings(start)]},
        "loglik": [float(s) for s in scores],
        "kept": ["first", "again"][best],
    }
    kept = res if best == 0 else facing_forward(again, data)
    return dc_replace(kept, start_moved=info, seconds=res.seconds + again.seconds)


# the headings a range-only start that moved races at its learned position (given_start.py)
START_HEADINGS = 8


def race_headings(start: EMModel) -> np.ndarray:
    """``START_HEADINGS`` headings evenly round the circle from the given one."""
    return start.prior_mean[2] + 2.0 * np.pi * np.arange(START_HEADINGS) / START_HEADINGS


def headings_at(start: EMModel, position: np.ndarray) -> list[EMModel]:
    """``start`` placed at ``position`` facing each of ``race_headings``, its heading sd half the gap between
    them: the candidates of a range-only start's heading race."""
    cov = start.prior_cov.copy()
    cov[2, 2] = (np.pi / START_HEADINGS) ** 2
    return [
        start.replace(prior_mean=np.array([position[0], position[1], h]), prior_cov=cov) for h in race_headings(start)
    ]


def _fit_while_lost(
    data: LandmarkLog,
    initial: EMModel | None,
    cfg: EMConfig,
    progress: Progress | None,
    on_restart: OnRestart | None,
    on_race: OnTrial | None,
) -> EMResult:
    """``fit_em_once``, and with ``turn_restarts`` on a planar log ``restart_while_lost``."""
    res = fit_em_once(data, initial, cfg, progress=progress, on_race=on_race)
    if cfg.turn_restarts == 0 or data.geometry != "planar":
        return res
    return restart_while_lost(
        data, initial or initial_model(data, cfg), cfg, res, progress, on_restart, on_race=on_race
    )


def most_likely(runs: list[EMResult], data: LandmarkLog) -> tuple[int, list[float]]:
    """Which of ``runs`` is the most likely, and each one's log-likelihood with the configured readings
    model on the sightings that every run kept after its first-iteration prune (runs without
    posteriors score -inf)."""
    scored = [r for r in runs if r.posteriors is not None]
    if not scored:
        return 0, [-np.inf] * len(runs)
    common = np.logical_and.reduce([r.posteriors.obs_used for r in scored])
    scores = [_stage_loglik(r.model, data, common, robust=True) if r.posteriors is not None else -np.inf for r in runs]
    return int(np.argmax(scores)), scores


def facing_forward(res: EMResult, data: LandmarkLog) -> EMResult:
    """``res`` with its robot facing the way it drives, when its sensor cannot tell (``forward.py``):
    the model, its posteriors and its action history turned by pi, ``turned_to_face_forward`` set."""
    if not drives_backward(res.model, data):
        return res
    return dc_replace(
        res,
        model=turned_model(res.model),
        posteriors=None if res.posteriors is None else turned_posteriors(res.posteriors),
        velocity_history=res.velocity_history * FLIP,  # planar: (iterations, A, 3)
        turned_to_face_forward=True,
    )


# each restart's start sigma for a channel whose f turned or bent (every channel's when EM did not settle): a third of
# the last one's (docs/em-real-results.md, Short logs: on quarter-length MRCLAM logs, trusting the poor line's
# readings more held the robot's scale)
RESTART_SIGMA_FACTOR = 1.0 / 3.0


def restart_while_lost(
    data: LandmarkLog,
    start: EMModel,
    cfg: EMConfig,
    first: EMResult,
    progress: Progress | None = None,
    on_restart: OnRestart | None = None,
    *,
    on_race: OnTrial | None = None,
) -> EMResult:
    """Beyond the thesis: while the last fit has a channel whose f turns over or bends within its distances,
    or has not settled (``checks.lost_fit_signs``), EM again from ``start`` with that channel's start sigma
    (every channel's when the fit has not settled) a third of the last one's, at most ``cfg.turn_restarts``
    times, and none after Ctrl-C. EM maximizes the likelihood, so the fit kept is the most likely one, each
    scored with the configured readings model on the sightings that every run kept after its
    first-iteration prune. ``restarts`` of the result lists every run."""
    runs, turns, sigmas = [first], [], []
    for k in range(cfg.turn_restarts + 1):
        last = runs[-1]
        turns.append(
            []
            if last.posteriors is None
            else lost_fit_signs(last.model, last.posteriors, data, last.loglik_history, last.best_iteration)
        )
        sigmas.append({ch.name: ch.sigma for ch in start.sensor.channels})
        if not turns[-1] or k == cfg.turn_restarts or last.stop_reason == "interrupted":  # Ctrl-C ends it all
            break
        turned = {t["channel"] for t in turns[-1] if "channel" in t}
        if any("channel" not in t for t in turns[-1]):  # an unsettled fit names no channel: every one
            turned = {ch.name for ch in start.sensor.channels}
        channels = tuple(
            dc_replace(ch, sigma=ch.sigma * RESTART_SIGMA_FACTOR) if ch.name in turned else ch
            for ch in start.sensor.channels
        )
        start = start.replace(sensor=dc_replace(start.sensor, channels=channels))
        if on_restart is not None:
            on_restart(k + 1, turns[-1], {ch.name: ch.sigma for ch in channels if ch.name in turned})
        runs.append(fit_em_once(data, start, cfg, progress=progress, on_race=on_race))
    if len(runs) == 1:
        return first
    best, scores = most_likely(runs, data)
    info = [
        {
            "start_sigma": sigmas[i],
            "loglik": float(scores[i]),
            "loglik_best": r.loglik_best,
            "iterations": r.iterations,
            "stop_reason": r.stop_reason,
            "f_turns": turns[i],
            "kept": i == best,
        }
        for i, r in enumerate(runs)
    ]
    return dc_replace(runs[best], restarts=info, seconds=sum(r.seconds for r in runs))


def _refuse_settings_for_log(cfg: EMConfig, data: LandmarkLog, initial: EMModel | None) -> None:
    """Settings this log cannot be learned with, each one line naming the field, before any work."""
    if cfg.ridge_search_mm > 0 and data.geometry != "planar":
        raise ConfigError(
            "ridge_search_mm moves the path along the robot's heading and needs a planar log.",
            file=data.source,
            field="ridge_search_mm",
            fix="set ridge_search_mm: 0 for a track.",
        )
    if cfg.motion_sd_sideways_mm > 0 and data.geometry != "planar":
        raise ConfigError(
            "motion_sd_sideways_mm is a planar robot's sideways noise, and a track has no sideways.",
            file=data.source,
            field="motion_sd_sideways_mm",
            fix="remove it or set it to 0.",
        )
    refuse_no_sightings(data)
    refuse_bearing_settings(cfg, data)
    if cfg.warm_start and initial is None:
        raise ConfigError(
            "warm_start starts EM from a learned model, and none was given.",
            file=data.source,
            field="warm_start",
            fix="give the model to start from (sensact learn em --start-from MODEL.json), or set warm_start: false.",
        )


@dataclass
class _Trace:
    """Every lambda_i's likelihood and parameters, as ``EMResult`` keeps them, and the most likely so far."""

    best_model: EMModel
    logliks: list[float] = field(default_factory=list)
    velocities: list[np.ndarray] = field(default_factory=list)
    sigmas: list[list[float]] = field(default_factory=list)
    motion_sds: list[np.ndarray] = field(default_factory=list)
    best_ll: float = -np.inf
    best_it: int = -1
    best_post: Posteriors | None = None

    def record(self, it: int, model: EMModel, post: Posteriors) -> None:
        self.logliks.append(post.loglik)
        self.velocities.append(_action_parameters(model).copy())
        self.sigmas.append([c.sigma for c in model.sensor.channels] + [model.sensor.sigma_bearing_rad or np.nan])
        self.motion_sds.append(model.motion_sd.copy())
        self.keep_if_best(it, model, post)

    def keep_if_best(self, it: int, model: EMModel, post: Posteriors) -> None:
        if post.loglik > self.best_ll:
            self.best_ll, self.best_it, self.best_model, self.best_post = post.loglik, it, model, post

    def arrays(self, model: EMModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The likelihoods, action parameters, sigmas and Sigma_m's sds, shaped even when no iteration ran."""
        return (
            np.asarray(self.logliks, dtype=float),
            np.asarray(self.velocities, dtype=float).reshape(-1, *_action_parameters(model).shape),
            np.asarray(self.sigmas, dtype=float).reshape(-1, len(model.sensor.channels) + 1),
            np.asarray(self.motion_sds, dtype=float).reshape(-1, *model.motion_sd.shape),
        )


@dataclass
class _Searches:
    """The ridge search (``ridge.py``) and the delay search (``delay_search.py``), each as configured: when
    the held stage ends, and again every ``search_every`` iterations, since EM keeps crawling back along
    the ridge between them (docs/em-real.md). Each search's record goes to ``EMResult``."""

    data: LandmarkLog
    cfg: EMConfig
    max_delay: int  # steps
    ridge_on: bool
    delay_on: bool
    mount_free: tuple[bool, bool, bool]  # the mount's components searched (mount.search_mount)
    ridge: list[dict[str, Any]] = field(default_factory=list)
    delay: list[dict[str, Any]] = field(default_factory=list)
    mount: list[dict[str, Any]] = field(default_factory=list)

    @classmethod
    def for_fit(cls, data: LandmarkLog, model: EMModel, cfg: EMConfig, freedom: MountFreedom) -> _Searches:
        max_delay = round(cfg.action_delay_max_s / data.dt_s)
        delay_on = cfg.delay_search and max_delay > 0 and isinstance(model.action, LinearActionModel)
        return cls(data, cfg, max_delay, cfg.ridge_search_mm > 0, delay_on, freedom.free)

    def due(self, it: int, ending_held: bool, since: int) -> bool:
        """``since``: the iteration the held stage ended at (0 with nothing held; -1 while held)."""
        again = since >= 0 and it > since and (it - since) % self.cfg.search_every == 0
        return (self.ridge_on or self.delay_on or any(self.mount_free)) and (ending_held or again)

    def run(
        self, it: int, model: EMModel, post: Posteriors, obs_use: np.ndarray, robust: bool
    ) -> tuple[EMModel, Posteriors]:
        evaluate = partial(_stage_e_step, data=self.data, obs_use=obs_use, robust=robust)
        score = partial(_stage_loglik, data=self.data, obs_use=obs_use, robust=robust)
        if self.ridge_on:
            model, post, info = search_ridge(model, post, score, evaluate, self.cfg.ridge_search_mm)
            self.ridge.append({"iteration": it, **info})
        if self.delay_on:
            model, post, info = search_delay(model, post, score, evaluate, self.max_delay)
            self.delay.append({"iteration": it, **info})
        if any(self.mount_free):  # due when the held stage ends and after: the mount is held before
            model, post, info = search_mount(model, post, score, evaluate, self.mount_free)
            self.mount.append({"iteration": it, **info})
        return model, post


def _searched_start(
    data: LandmarkLog, model: EMModel, cfg: EMConfig, on_race: OnTrial | None
) -> tuple[EMModel, dict[str, Any] | None, int]:
    """Where the robot starts when nobody says (``start.py``): the model placed there, what the search
    tried, and the held iterations the start race already gave the model (0 without a race)."""
    if not (cfg.start_search_s > 0 and data.geometry == "planar" and not cfg.warm_start):
        return model, None, 0
    candidates, info = start_candidates(data, model, cfg)
    model, spent = candidates[0], 0
    if len(candidates) > 1:
        model, info["race"] = race_starts(data, candidates, cfg, fit_em_once, on_trial=on_race)
        spent = info["race"]["winner_iterations"]  # before this fit's history begins
    info["prior_mean"] = model.prior_mean.tolist()
    return model, info, spent


def fit_em_once(
    data: LandmarkLog,
    initial: EMModel | None = None,
    config: EMConfig | None = None,
    *,
    progress: Progress | None = None,
    on_race: OnTrial | None = None,
) -> EMResult:
    """One EM run from one start (the Algorithm of ch. 4, with the start search and searches configured).

    Sigma_m, the bearing terms and the robust readings are held while EM first settles (the held stage),
    then freed; a race as long as ``refine_from`` has held the stage already."""
    cfg = config or EMConfig()
    _refuse_settings_for_log(cfg, data, initial)
    model = initial or initial_model(data, cfg)
    refuse_too_few_readings(model, data)
    rng = np.random.default_rng(cfg.seed)
    n = model.prior_mean.size
    if cfg.motion_noise == "fixed":  # the thesis: Sigma_m is the configured constant, whatever the start says
        model = model.replace(motion_sd=motion_sd_start(cfg, n))
    model, start_info, spent = _searched_start(data, model, cfg, on_race)
    floor = np.array([cfg.prior_floor_sd[0] ** 2] * min(n, 2) + ([cfg.prior_floor_sd[1] ** 2] if n == 3 else []))
    freedom = mount_freedom(model, cfg.sensor_mount is not None, model.sensor.sigma_bearing_rad is not None)
    trace = _Trace(model)
    searches = _Searches.for_fit(data, model, cfg, freedom)
    obs_use = None
    reason = "max_iterations"
    learns_sigma_m = cfg.motion_noise != "fixed"
    staged = (
        learns_sigma_m or model.sensor.is_robust or any(c.bearing_terms for c in model.sensor.channels) or freedom.any
    )
    refine_from = cfg.refine_from - spent
    # a race as long as refine_from has held the stage already: it ends at this fit's first iteration (so the
    # searches and prune_when_freed run then); refine_from 0 with no race holds nothing, and neither does a
    # learned start (warm_start), whose first E-step prune_when_freed reads
    refining = not staged or (refine_from <= 0 and spent == 0) or cfg.warm_start
    freed_at = 0 if staged and cfg.warm_start else -1  # a learned start has settled: freed from the first
    n_late = 0
    start = time.perf_counter()
    try:
        for it in range(max(cfg.max_iterations - spent, 1)):  # the race's iterations count
            post = e_step(
                _stage_model(model, refining),
                data,
                obs_use=obs_use,
                prune_rad_per_step=cfg.prune_rad_per_step if it == 0 else 0.0,
            )
            if it == 0:
                obs_use = post.obs_used
                if not post.weights.any():  # there are sightings (refuse_no_sightings), but none used
                    raise ConfigError(
                        "the starting model uses no reading at all.",
                        file=data.source,
                        field="channels[].valid_min / valid_max",
                        fix="check each channel's window (in the state's unit) against its starting line.",
                    )
                if freed_at == 0 and model.sensor.is_robust and cfg.prune_when_freed:
                    post, n_late = drop_late_outliers(post, data, cfg.prune_rad_per_step, model)
                    obs_use = post.obs_used
            if not post.ok:
                reason = "diverged"
                break
            trace.record(it, model, post)
            if progress is not None:
                progress(it, post.loglik, trace.best_ll, it - trace.best_it)
            ending_held = not refining and (it >= refine_from or it - trace.best_it >= cfg.patience)
            since = freed_at if freed_at >= 0 else (0 if refining else -1)
            if searches.due(it, ending_held, since):
                model, post = searches.run(it, model, post, obs_use, robust=refining)
                trace.logliks[-1] = post.loglik  # lambda_it is now the moved model (its likelihood before: info)
                trace.keep_if_best(it, model, post)
            if ending_held:
                refining, freed_at = True, it  # converged with Sigma_m and the terms held: free them
                if model.sensor.is_robust:
                    trace.best_ll = -np.inf  # the robust likelihood is another function: its own best from here
                    if cfg.prune_when_freed:  # what the first iteration's gate could not see (outliers.py)
                        post, n_late = drop_late_outliers(post, data, cfg.prune_rad_per_step, model)
                        obs_use = post.obs_used
            if it - max(trace.best_it, freed_at) >= cfg.patience:
                reason = "converged"
                break
            model = m_step(
                post,
                data,
                model,
                n_samples=cfg.samples_per_frame,
                floor_var=floor,
                rng=rng,
                learn_motion_noise=learns_sigma_m and refining,
                motion_floor_sd=motion_sd_floor(cfg, n),
                max_delay_steps=searches.max_delay,
                fit_bearing_terms=refining,
                mount_free=freedom.free if refining else (False, False, False),  # held with the terms
            )
    except KeyboardInterrupt:
        reason = "interrupted"
    n_pruned = 0 if obs_use is None else int(data.n_observations - obs_use.sum())
    logliks, velocities, sigmas, motion_sds = trace.arrays(model)
    return EMResult(
        model=trace.best_model,
        loglik_history=logliks,
        velocity_history=velocities,
        sigma_history=sigmas,
        best_iteration=max(trace.best_it, 0),
        stop_reason=reason,
        n_observations=data.n_observations,
        n_pruned=n_pruned,
        seconds=time.perf_counter() - start,
        config=cfg,
        posteriors=trace.best_post,
        motion_sd_history=motion_sds,
        start_search=start_info,
        freed_at=freed_at,
        ridge=searches.ridge or None,
        delay_search=searches.delay or None,
        n_pruned_when_freed=n_late,
        mount=freedom,
        mount_search=searches.mount or None,
    )


def drop_late_outliers(
    post: Posteriors, data: LandmarkLog, gate_rad_per_step: float, model: EMModel
) -> tuple[Posteriors, int]:
    """``prune_when_freed``: the first iteration's gate again, on the smoothed path (``outliers.py``); the
    posteriors with those sightings no longer used (so that this M-step leaves them out already), and
    how many."""
    late = bearing_outliers(post, data, gate_rad_per_step, model.sensor.mount.as_array())
    return dc_replace(post, obs_used=post.obs_used & ~late), int(late.sum())


def _stage_model(model: EMModel, robust: bool) -> EMModel:
    """The model the loop's current stage runs: Gaussian readings while held, the configured ones after."""
    return model if robust else model.replace(sensor=model.sensor.gaussian())


def _stage_e_step(model: EMModel, data: LandmarkLog, obs_use: np.ndarray, robust: bool) -> Posteriors:
    return e_step(_stage_model(model, robust), data, obs_use=obs_use)


def _stage_loglik(model: EMModel, data: LandmarkLog, obs_use: np.ndarray, robust: bool) -> float:
    """``_stage_e_step``'s likelihood from its forward pass alone (the searches compare, then smooth one)."""
    return log_likelihood(_stage_model(model, robust), data, obs_use=obs_use)


def _action_parameters(model: EMModel) -> np.ndarray:
    a = model.action
    return a.velocities if isinstance(a, ActionTable) else a.coefficients
