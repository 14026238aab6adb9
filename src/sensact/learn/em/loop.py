"""The EM loop (secs. 4.1 and 4.4.1): alternate E- and M-steps and keep the most likely model.

The likelihood of an approximate EM fluctuates, so a stage ends when ``patience`` iterations (50 in the
thesis) pass without a new best ``log P(O | C, lambda)``, and EM at the end of its last stage, or at
``max_iterations``. What the M-step may move in each stage is data: a tuple of frozen ``Stage`` values
(``plan_stages``). Outliers are pruned in the first iteration (and, with ``prune_when_freed``, once more
when the robust readings take over), and stay pruned. Ctrl-C ends the loop cleanly with the best model
so far (``stop_reason == "interrupted"``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from dataclasses import replace as dc_replace
from functools import partial

import numpy as np

from sensact.errors import ConfigError
from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors, e_step, log_likelihood
from sensact.learn.em.fixed_point import STEP_BOUND_SD, STOP_SD, Information, rest_of_the_way
from sensact.learn.em.initial import initial_model, motion_sd_floor, motion_sd_start
from sensact.learn.em.late_outliers import bearing_outliers
from sensact.learn.em.mount import MountFreedom, mount_freedom
from sensact.learn.em.mstep import m_step
from sensact.learn.em.result import EMResult
from sensact.learn.em.searches.delay import DelaySearch, search_delay
from sensact.learn.em.searches.mount_search import MountSearch, search_mount
from sensact.learn.em.searches.ridge import RidgeSearch, search_ridge
from sensact.learn.em.searches.start_race import OnTrial, StartSearch, race_starts, start_candidates
from sensact.learn.em.space import LearnedSpace
from sensact.learn.em.squarem import (
    LOGLIK_SLACK,
    MIN_GAIN,
    STEP_FACTOR,
    STEP_MAX_LIMIT,
    STEP_MAX_START,
    Coordinates,
    S3Path,
)
from sensact.learn.em.stage import HELD, NO_MOUNT, Stage, holds_anything, plan_stages
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

# (iteration, loglik, best loglik, iterations since the best) -> None
OnIteration = Callable[[int, float, float, int], None]


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
    bests: list[float] = field(default_factory=list)  # the best likelihood after each iteration

    def record(self, it: int, model: EMModel, post: Posteriors) -> None:
        self.logliks.append(post.loglik)
        self.velocities.append(_action_parameters(model).copy())
        self.sigmas.append(list(model.sensor.sigmas))
        self.motion_sds.append(model.motion_sd.copy())
        self.keep_if_best(it, model, post)
        self.bests.append(self.best_ll)

    def gained(self, it: int, since: int) -> float:
        """How much the best likelihood rose over the iterations ``since..it`` (inf when it was reset there)."""
        if since < 0 or since >= len(self.bests) or not np.isfinite(self.bests[since]):
            return np.inf
        return self.bests[it] - self.bests[since]

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
    """The ridge search (``searches/ridge.py``), the delay search (``searches/delay.py``) and the mount
    search (``searches/mount_search.py``), each as configured: when a stage ends, and every
    ``search_every`` iterations into the last, since EM keeps crawling back along the ridge between them
    (docs/em-real.md)."""

    data: LandmarkLog
    cfg: EMConfig
    max_delay: int  # steps
    ridge_on: bool
    delay_on: bool
    mount_free: tuple[bool, bool, bool]
    ridge: list[RidgeSearch] = field(default_factory=list)
    delay: list[DelaySearch] = field(default_factory=list)
    mount: list[MountSearch] = field(default_factory=list)
    last: int = -1  # the iteration they last ran at

    @classmethod
    def for_fit(
        cls, data: LandmarkLog, model: EMModel, cfg: EMConfig, freedom: MountFreedom, on: bool = True
    ) -> _Searches:
        max_delay = round((cfg.action.delay_max_s or 0.0) / data.dt_s)
        delay_on = on and cfg.search.delay and max_delay > 0 and model.action.can_delay
        # the ridge trades the path against f's offset with the map held; a learned map moves itself
        ridge_on = on and cfg.search.ridge_mm is not None and model.landmarks is None
        return cls(data, cfg, max_delay, ridge_on, delay_on, freedom.free if on else NO_MOUNT)

    def due(self, it: int, stage_ends: bool, since: int | None) -> bool:
        """``since``: the iteration the last stage began at (None before it)."""
        # every ``every`` iterations from the stage's start (an accelerated loop visits some iterations only)
        again = since is not None and it - max(since, self.last) >= self.cfg.search.every
        return (self.ridge_on or self.delay_on or any(self.mount_free)) and (stage_ends or again)

    def run(
        self, it: int, model: EMModel, post: Posteriors, obs_use: np.ndarray, robust: bool
    ) -> tuple[EMModel, Posteriors]:
        self.last = it
        evaluate = partial(_stage_e_step, data=self.data, obs_use=obs_use, robust=robust)
        score = partial(stage_loglik, data=self.data, obs_use=obs_use, robust=robust)
        if self.ridge_on:
            model, post, info = search_ridge(model, post, score, evaluate, self.cfg.search.ridge_mm)
            self.ridge.append(dc_replace(info, iteration=it))
        if self.delay_on:
            model, post, info = search_delay(model, post, score, evaluate, self.max_delay)
            self.delay.append(dc_replace(info, iteration=it))
        if any(self.mount_free):  # due when the held stage ends and after: the mount is held before
            model, post, info = search_mount(model, post, score, evaluate, self.mount_free)
            self.mount.append(dc_replace(info, iteration=it))
        return model, post


@dataclass
class _Run:
    """One EM run's state between its E- and M-steps: the model, the stage it is in, the sightings used."""

    data: LandmarkLog
    cfg: EMConfig
    stages: tuple[Stage, ...]
    model: EMModel
    trace: _Trace
    searches: _Searches
    rng: np.random.Generator
    patience: int | None  # None: run every iteration (a race's trial)
    prune: float | None  # the first iteration's gate (None: none)
    freed_at: int = -1  # the iteration the last stage began at, after a held one (0: a learned start)
    stage: int = 0
    obs_use: np.ndarray | None = None
    n_late: int = 0
    began: list[tuple[str, int]] = field(default_factory=list)
    accelerated: int = 0  # SQUAREM's steps kept
    peaked: bool = False  # the accelerated loop's last EM step lowered the likelihood
    # the deterministic EM's last stage measures its steps in the observed information about its latest
    # model (fixed_point.py); None before
    info: Information | None = None
    stopped_because: str = ""  # the rule that ended the fit (EMResult.stopped_because)

    @property
    def current(self) -> Stage:
        return self.stages[self.stage]

    @property
    def last(self) -> bool:
        return self.stage == len(self.stages) - 1

    def move_to(self, model: EMModel) -> None:
        """``model`` is lambda from here; the next E-step reads a learned map from it."""
        self.model = model
        if model.landmarks is not None:
            self.data = self.searches.data = self.data.with_landmarks(model.landmarks.xy)

    def loglik(self, model: EMModel) -> float:
        """``model``'s likelihood in this stage, from the forward pass alone."""
        data = self.data if model.landmarks is None else self.data.with_landmarks(model.landmarks.xy)
        return stage_loglik(model, data, self.obs_use, self.current.robust)

    def e_step(self, it: int) -> Posteriors:
        """Sec. 4.2's E-step in this stage; in the first iteration the gate of sec. 4.4.1 (per frame)."""
        gate = self.prune if it == 0 and self.prune is not None else 0.0
        post = e_step(
            _stage_model(self.model, self.current.robust), self.data, obs_use=self.obs_use, prune_rad_per_step=gate
        )
        if it == 0:
            self.obs_use = post.obs_used
            if not post.weights.any():  # there are sightings (refuse_no_sightings), but none used
                raise ConfigError(
                    "the starting model uses no reading at all.",
                    file=self.data.source,
                    field="channels[].valid_min / valid_max",
                    fix="check each channel's window (in the state's unit) against its starting line.",
                )
            if self.freed_at == 0:  # a learned start: its robust readings take over at once
                post = self._robust_take_over(post)
        return post

    def stage_ends(self, it: int) -> bool:
        s = self.current
        patience = self.patience or 0
        stale = it - max(self.trace.best_it, self.freed_at) >= patience
        if self.cfg.accelerate and it - patience > max(self.freed_at, 0):
            # a deterministic map creeps: new bests by next to nothing do not keep it going
            stale |= self.trace.gained(it, it - patience) < MIN_GAIN
        converged = self.patience is not None and stale
        # a held stage or a race's trial is scored by its best: once EM's own step lowers the likelihood,
        # its best is behind it (accelerated; docs/em-real.md, "Start pose")
        converged |= self.peaked and (self.patience is None or s.ends_by is not None)
        return converged or (s.ends_by is not None and it >= s.ends_by)

    def at_fixed_point(self, it: int, model: EMModel, post: Posteriors, moved: EMModel, before: EMModel | None) -> bool:
        """Whether ``model`` (its E-step ``post``) is within ``STOP_SD`` standard errors of EM's fixed point
        in every parameter (``fixed_point.py``), judged by its EM step to ``moved`` and the one that led to
        it from ``before``: the deterministic EM's stop, in its last stage. Keeps the observed information
        about ``model`` (``info``) for the accelerated step's bound. At the fixed point ``model`` is the fit,
        not the best of the path."""
        if not (self.last and self.cfg.sigma_points and self.patience is not None) or before is None:
            return False
        score = partial(stage_loglik, data=self.data, obs_use=self.obs_use, robust=self.current.robust)
        self.info = info = Information(LearnedSpace.about(model, self.data, self.current.mount, score), post.loglik)
        rest = rest_of_the_way(info.step(before, model), info.step(model, moved))
        if rest is None or not info.length(rest) < STOP_SD:
            return False
        t = self.trace
        t.best_ll, t.best_it, t.best_model, t.best_post = post.loglik, it, model, post
        self.stopped_because = "fixed_point"
        return True

    def search_if_due(self, it: int, post: Posteriors, stage_ends: bool) -> Posteriors:
        since = (self.freed_at if self.freed_at >= 0 else 0) if self.last else None
        if not self.searches.due(it, stage_ends, since):
            return post
        self.model, post = self.searches.run(it, self.model, post, self.obs_use, robust=self.current.robust)
        self.trace.logliks[-1] = post.loglik  # lambda_it is now the moved model (its likelihood before: info)
        self.trace.keep_if_best(it, self.model, post)
        self.trace.bests[-1] = self.trace.best_ll
        return post

    def next_stage(self, it: int, post: Posteriors) -> Posteriors:
        was_robust = self.current.robust
        self.stage, self.freed_at, self.peaked = self.stage + 1, it, False
        self.began.append((self.current.name, it))
        return post if was_robust else self._robust_take_over(post)

    def _robust_take_over(self, post: Posteriors) -> Posteriors:
        """The robust readings take over: their likelihood is another function, with its own best from here;
        with prune_when_freed, the first iteration's gate again on the smoothed path (``late_outliers.py``)."""
        if not self.model.sensor.is_robust:
            return post
        self.trace.best_ll = -np.inf
        if self.cfg.robust.prune_when_freed:
            post, self.n_late = drop_late_outliers(post, self.data, self.cfg.thesis.prune_rad_per_step, self.model)
            self.obs_use = post.obs_used
        return post

    def m_step(self, post: Posteriors, floor: np.ndarray, delay_free: bool = True) -> EMModel:
        """Sec. 4.3's M-step from lambda's posteriors, moving what this stage frees (``delay_free`` False:
        lambda's command delay kept); the model is not yet lambda (``move_to``)."""
        s, n = self.current, self.model.prior_mean.size
        return m_step(
            post,
            self.data,
            self.model,
            n_samples=self.cfg.thesis.samples_per_frame,
            floor_var=floor,
            rng=self.rng,
            stage=s,
            motion_floor_sd=motion_sd_floor(self.cfg, n),
            max_delay_steps=self.searches.max_delay if delay_free else 0,
            sigma_points=self.cfg.sigma_points,
        )


def em_loop(run: _Run, iterations: int, on_iteration: OnIteration | None = None) -> str:
    """The thesis's loop (secs. 4.1, 4.4.1): E-step, M-step, until the last stage converges; why it stopped.
    Accelerated (``accelerate``), ``squarem_loop``."""
    if run.cfg.accelerate:
        return squarem_loop(run, iterations, on_iteration)
    floor = prior_floor_var(run.cfg, run.model.prior_mean.size)
    before: EMModel | None = None  # the model EM's last step left
    try:
        for it in range(iterations):
            post = run.e_step(it)
            if not post.ok:
                return "diverged"
            run.trace.record(it, run.model, post)
            if on_iteration is not None:
                on_iteration(it, post.loglik, run.trace.best_ll, it - run.trace.best_it)
            ending = not run.last and run.stage_ends(it)
            post = run.search_if_due(it, post, ending)  # the searches may move lambda_it
            if ending:
                post = run.next_stage(it, post)
            elif run.stage_ends(it):
                run.stopped_because = "patience"
                return "converged"
            moved = run.m_step(post, floor)
            if run.at_fixed_point(it, run.model, post, moved, before):
                return "converged"
            before = run.model
            run.move_to(moved)
    except KeyboardInterrupt:
        return "interrupted"
    return "max_iterations"


def squarem_loop(run: _Run, iterations: int, on_iteration: OnIteration | None = None) -> str:
    """``em_loop`` with SQUAREM's cycles (``squarem.py``): from lambda_0, two EM steps, S3's step from the
    three, and an EM step from there that begins the next cycle. Every E-step on EM's path is an iteration,
    and is recorded; stages, searches and the stop are judged at each cycle's lambda_0, as ``em_loop`` judges
    each of its own. Within a cycle the discrete choices are frozen: the M-steps keep lambda_1's command
    delay and read the same sightings. A step whose likelihood falls more
    than ``LOGLIK_SLACK`` below lambda_0's is refused, and EM goes on from lambda_2."""
    floor = prior_floor_var(run.cfg, run.model.prior_mean.size)
    step_max, it = STEP_MAX_START, 0

    def evaluate(model: EMModel) -> Posteriors | None:
        """lambda := ``model`` and its E-step (None at the iteration budget)."""
        if it >= iterations:
            return None
        run.move_to(model)
        return run.e_step(it)

    def keep(model: EMModel, post: Posteriors) -> None:
        """``model`` is lambda_it: EM's path goes through it."""
        nonlocal it
        if post.ok:
            run.trace.record(it, model, post)
            if on_iteration is not None:
                on_iteration(it, post.loglik, run.trace.best_ll, it - run.trace.best_it)
        it += 1

    def visit(model: EMModel) -> Posteriors | None:
        post = evaluate(model)
        if post is not None:
            keep(model, post)
        return post

    try:
        post = visit(run.model)
        while post is not None:
            if not post.ok:
                return "diverged"
            at = it - 1
            ending = not run.last and run.stage_ends(at)
            post = run.search_if_due(at, post, ending)
            if ending:
                post = run.next_stage(at, post)
            elif run.stage_ends(at):
                run.stopped_because = "patience"
                return "converged"
            start, post0 = run.model, post
            m1 = run.m_step(post0, floor)
            post1 = visit(m1)
            if post1 is None or not post1.ok:
                post = post1
                continue
            run.peaked = post1.loglik < post0.loglik
            m2 = run.m_step(post1, floor, delay_free=False)
            if run.at_fixed_point(it - 1, m1, post1, m2, start):
                return "converged"
            path = _s3_path(start, m1, m2, post0, post1, run.data)
            step, a = (m2, 0.0) if path is None else _at(path, path.length(step_max), m2)
            if run.info is not None:  # bounded in the parameters (fixed_point.py), judged by nothing else
                info, clipped = run.info, False
                while step is not m2 and not info.length(info.step(m2, step)) <= STEP_BOUND_SD:
                    step, a = _at(path, max(a / STEP_FACTOR, 1.0), m2)  # type: ignore[arg-type]
                    clipped = True
                if clipped:
                    step_max = max(STEP_MAX_START, step_max / STEP_FACTOR)
                elif a >= step_max:
                    step_max = min(step_max * STEP_FACTOR, STEP_MAX_LIMIT)
            elif step is not m2 and not run.loglik(step) >= post0.loglik - LOGLIK_SLACK:  # a forward pass each
                step_max = max(STEP_MAX_START, step_max / STEP_FACTOR)
                while step is not m2:  # back along S3's path
                    step, a = _at(path, max(a / STEP_FACTOR, 1.0), m2)
                    if step is m2 or run.loglik(step) >= post0.loglik - LOGLIK_SLACK:
                        break
            elif a >= step_max:
                step_max = min(step_max * STEP_FACTOR, STEP_MAX_LIMIT)
            post_s = visit(step)
            if post_s is None or not post_s.ok:
                post = post_s
                continue
            run.accelerated += step is not m2
            post = visit(run.m_step(post_s, floor, delay_free=False))
    except KeyboardInterrupt:
        return "interrupted"
    return "max_iterations"


def _s3_path(
    start: EMModel, m1: EMModel, m2: EMModel, post0: Posteriors, post1: Posteriors, data: LandmarkLog
) -> S3Path | None:
    """The cycle's S3 path, or None where it changed a discrete choice (the delay, the sightings read)."""
    same = start.action.delay_steps == m1.action.delay_steps == m2.action.delay_steps and np.array_equal(
        post0.obs_used, post1.obs_used
    )
    if not same:
        return None
    p0, p1, p2 = (np.asarray(m.action.parameters, dtype=float).ravel() for m in (start, m1, m2))
    moving = (p0 != p1) | (p1 != p2)  # a held parameter (a zero mean) stays exactly where it is
    return S3Path.through(Coordinates.about(start, data, moving), (start, m1, m2))


def _at(path: S3Path, a: float, m2: EMModel) -> tuple[EMModel, float]:
    """S3's model at length ``a`` (``m2`` itself at 1) and ``a``; ``m2`` and 0 where that is no model."""
    if a <= 1.0:
        return m2, a
    model = path.model_at(a)
    return (m2, 0.0) if model is None else (model, a)


def prior_floor_var(cfg: EMConfig, n: int) -> np.ndarray:
    """pi(w_0)'s variance floor per state component (``prior_floor_sd``: mm, then rad)."""
    return np.array(
        [cfg.thesis.prior_floor_sd[0] ** 2] * min(n, 2) + ([cfg.thesis.prior_floor_sd[1] ** 2] if n == 3 else [])
    )


def run_stages(
    data: LandmarkLog,
    model: EMModel,
    cfg: EMConfig,
    stages: Sequence[Stage],
    iterations: int,
    *,
    freedom: MountFreedom,
    patience: int | None,
    prune: float | None,
    on_iteration: OnIteration | None = None,
    start_search: StartSearch | None = None,
    searches_on: bool = True,
) -> EMResult:
    """``em_loop`` from ``model`` through ``stages``, as an ``EMResult`` (``searches_on``: the searches as
    configured; off, none)."""
    if model.landmarks is not None:  # EM learns the map: every E-step reads the model's
        data = data.with_landmarks(model.landmarks.xy)
    trace = _Trace(model)
    searches = _Searches.for_fit(data, model, cfg, freedom, searches_on)
    warm = cfg.search.warm_start and holds_anything(
        cfg, model, freedom
    )  # a learned start has settled: freed from the first
    run = _Run(
        data, cfg, tuple(stages), model, trace, searches, np.random.default_rng(cfg.thesis.seed), patience, prune
    )
    run.freed_at = 0 if warm else -1
    run.began.append((run.current.name, 0))
    start = time.perf_counter()
    reason = em_loop(run, iterations, on_iteration)
    obs_use = run.obs_use
    n_pruned = 0 if obs_use is None else int(data.n_observations - obs_use.sum())
    logliks, velocities, sigmas, motion_sds = trace.arrays(run.model)
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
        start_search=start_search,
        freed_at=run.freed_at,
        ridge=searches.ridge or None,
        delay_search=searches.delay or None,
        n_pruned_when_freed=run.n_late,
        mount=freedom,
        mount_search=searches.mount or None,
        stages=tuple(run.began),
        accelerated=run.accelerated,
        stopped_because=run.stopped_because or reason,
    )


def held_trial(data: LandmarkLog, model: EMModel, iterations: int, cfg: EMConfig) -> EMResult:
    """A start race's trial: ``iterations`` of the held stage alone from ``model``, ungated and without a
    stop, so that every candidate's likelihood is one function (``searches/start_race.race_starts``)."""
    freedom = mount_freedom(model, cfg.sensor_mount is not None, model.sensor.reads_bearing)
    stage = HELD if holds_anything(cfg, model, freedom) else plan_stages(cfg, model, freedom)[0]
    return run_stages(
        data, model, cfg, (stage,), iterations, freedom=freedom, patience=None, prune=None, searches_on=False
    )


def searched_start(
    data: LandmarkLog, model: EMModel, cfg: EMConfig, on_race: OnTrial | None
) -> tuple[EMModel, StartSearch | None, int]:
    """Where the robot starts when nobody says (``searches/start_race.py``): the model placed there, what the search
    tried, and the held iterations the start race already gave the model (0 without a race)."""
    frame_from_start = model.landmarks is not None and model.landmarks.held.sum() < 2  # the start is the frame
    if not (cfg.search.start_s is not None and data.geometry.has_heading and not cfg.search.warm_start) or (
        frame_from_start
    ):
        return model, None, 0
    candidates, info = start_candidates(data, model, cfg)
    model, spent = candidates[0], 0
    if len(candidates) > 1:
        trial = partial(held_trial, cfg=cfg)
        model, race = race_starts(data, candidates, cfg, trial, on_trial=on_race)
        info, spent = dc_replace(info, race=race), race.winner_iterations  # before this fit's history begins
    return model, dc_replace(info, prior_mean=tuple(model.prior_mean.tolist())), spent


def fit_em_once(
    data: LandmarkLog,
    initial: EMModel | None = None,
    config: EMConfig | None = None,
    *,
    on_iteration: OnIteration | None = None,
    on_race: OnTrial | None = None,
) -> EMResult:
    """One EM run from one start (the Algorithm of ch. 4): the start searched for when configured, then
    ``em_loop`` through ``plan_stages``; a race's held iterations count toward ``max_iterations``."""
    cfg = config or EMConfig()
    model = initial or initial_model(data, cfg)
    if cfg.motion_noise.kind == "fixed":  # the thesis: Sigma_m is the configured constant, whatever the start says
        model = model.replace(motion_sd=motion_sd_start(cfg, model.prior_mean.size))
    model, start_info, spent = searched_start(data, model, cfg, on_race)
    freedom = mount_freedom(model, cfg.sensor_mount is not None, model.sensor.reads_bearing)
    stages = plan_stages(cfg, model, freedom, spent)
    iterations = max(cfg.thesis.max_iterations - spent, 1)
    return run_stages(
        data, model, cfg, stages, iterations, freedom=freedom, patience=cfg.thesis.patience,
        prune=cfg.thesis.prune_rad_per_step, on_iteration=on_iteration, start_search=start_info,
    )  # fmt: skip


def drop_late_outliers(
    post: Posteriors, data: LandmarkLog, gate_rad_per_step: float, model: EMModel
) -> tuple[Posteriors, int]:
    """``prune_when_freed``: the first iteration's gate again, on the smoothed path (``late_outliers.py``); the
    posteriors with those sightings no longer used (so that this M-step leaves them out already), and
    how many."""
    late = bearing_outliers(post, data, gate_rad_per_step, model.sensor.mount.as_array())
    return dc_replace(post, obs_used=post.obs_used & ~late), int(late.sum())


def _stage_model(model: EMModel, robust: bool) -> EMModel:
    """The model a stage runs: Gaussian readings while held, the configured ones after."""
    return model if robust else model.replace(sensor=model.sensor.gaussian())


def _stage_e_step(model: EMModel, data: LandmarkLog, obs_use: np.ndarray, robust: bool) -> Posteriors:
    return e_step(_stage_model(model, robust), data, obs_use=obs_use)


def stage_loglik(model: EMModel, data: LandmarkLog, obs_use: np.ndarray, robust: bool) -> float:
    """``_stage_e_step``'s likelihood from its forward pass alone (the searches compare, then smooth one)."""
    return log_likelihood(_stage_model(model, robust), data, obs_use=obs_use)


def _action_parameters(model: EMModel) -> np.ndarray:
    a = model.action
    return a.parameters
