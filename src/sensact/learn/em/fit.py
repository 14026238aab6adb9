"""EM as a calibration runs it: the loop of secs. 4.1 and 4.4.1 (``loop.py``) inside policies that all
take and give a fit, composed, so that the loop reads like the paper. Beyond the thesis: ``restart_while_lost``
runs EM again from a tighter start when a range function turned over or bent or EM did not settle (``turn_restarts``);
``rerun_moved_start`` runs it again, on a range-only log, from the start EM learned when the given one
moved metres (``searches/given_start.py``); ``face_forward`` turns a range-only fit that drives backward by pi.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import replace as dc_replace
from functools import partial

import numpy as np

from sensact.errors import ConfigError, LogFormatError
from sensact.learn.em.checks.lost_signs import lost_fit_signs
from sensact.learn.em.config import EMConfig, refuse_bearing_settings
from sensact.learn.em.estep import counting_passes
from sensact.learn.em.initial import initial_model
from sensact.learn.em.loop import OnIteration, fit_em_once, held_trial, stage_loglik
from sensact.learn.em.result import EMResult, HeadingRace, LostSign, RestartRun, StartMoved, Unsettled
from sensact.learn.em.searches.facing import FLIP, drives_backward, turned_model, turned_posteriors
from sensact.learn.em.searches.given_start import start_moved_mm
from sensact.learn.em.searches.start_race import OnTrial, race_starts
from sensact.learn.em.unsurveyed.anchors import anchor_fit
from sensact.learn.em.unsurveyed.rounds import Fit, map_rounds
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

__all__ = ["EMResult", "OnIteration", "fit_em", "fit_em_once"]

# (restart number from 1, the last fit's signs of being lost (checks/lost_signs.lost_fit_signs), the new start sigmas)
OnRestart = Callable[[int, list[LostSign], dict[str, float]], None]
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


def fit_em(
    data: LandmarkLog,
    initial: EMModel | None = None,
    config: EMConfig | None = None,
    *,
    on_iteration: OnIteration | None = None,
    on_restart: OnRestart | None = None,
    on_race: OnTrial | None = None,
    on_start_moved: OnStartMoved | None = None,
) -> EMResult:
    """Learn the action model, the sensor model and the prior from ``data`` by EM (the Algorithm of ch. 4),
    from ``initial`` (by default sec. 4.4.1's poor start): ``fit_em_once`` inside ``POLICIES``, composed.
    ``on_iteration`` hears of every iteration, ``on_race`` of the start race's trials, ``on_restart`` of each
    restart before it runs, ``on_start_moved`` of a range-only start that moved metres."""
    cfg = config or EMConfig()
    refuse_settings_for_log(cfg, data, initial)
    start = initial or initial_model(data, cfg)
    refuse_too_few_readings(start, data)
    heard = Heard(on_restart, on_race, on_start_moved)
    began = time.perf_counter()
    with counting_passes() as passes:
        res = _fit(data, start, cfg, heard, on_iteration)
    return dc_replace(
        res, seconds=time.perf_counter() - began, e_steps=passes.e_steps, forward_passes=passes.forward_only
    )


def _fit(data: LandmarkLog, start: EMModel, cfg: EMConfig, heard: Heard, on_iteration: OnIteration | None) -> EMResult:
    def composed(log: LandmarkLog, settings: EMConfig) -> Fit:
        fit: Fit = partial(fit_em_once, log, config=settings, on_iteration=on_iteration, on_race=heard.on_race)
        for policy in POLICIES:
            fit = policy(fit, log, settings, heard)
        return fit

    if start.landmarks is not None:  # a map nobody surveyed: learned in rounds (unsurveyed/rounds.py)
        if not start.sensor.reads_bearing:  # range-only anchors, placed on a path the given ones fix
            return anchor_fit(composed, data, start, cfg)
        return map_rounds(composed, data, start, cfg)
    return composed(data, cfg)(start)


@dataclass(frozen=True)
class Heard:
    """What the policies tell as they go (``fit_em``'s callbacks)."""

    on_restart: OnRestart | None
    on_race: OnTrial | None
    on_start_moved: OnStartMoved | None


# a policy: (the fit it wraps, the log, the settings, the callbacks) -> a fit
Policy = Callable[[Fit, LandmarkLog, EMConfig, Heard], Fit]


def restart_while_lost(fit: Fit, data: LandmarkLog, cfg: EMConfig, heard: Heard) -> Fit:
    """Beyond the thesis, on a planar log with ``turn_restarts``: while the last fit has a channel whose f
    turns over or bends within its distances, or has not settled (``checks/lost_signs.lost_fit_signs``), EM again from
    the start with that channel's start sigma (every channel's when the fit has not settled) a third of the
    last one's, at most ``turn_restarts`` times, and none after Ctrl-C. EM maximizes the likelihood, so the
    fit kept is the most likely one, each scored with the configured readings model on the sightings that
    every run kept after its first-iteration prune. ``restarts`` of the result lists every run."""
    if cfg.search.turn_restarts == 0 or not data.geometry.has_heading:
        return fit

    def restarting(start: EMModel) -> EMResult:
        runs, turns, sigmas = [fit(start)], [], []
        for k in range(cfg.search.turn_restarts + 1):
            last = runs[-1]
            turns.append(
                []
                if last.posteriors is None
                else lost_fit_signs(last.model, last.posteriors, data, last.loglik_history, last.best_iteration, cfg)
            )
            sigmas.append({ch.name: ch.sigma for ch in start.sensor.channels})
            if (
                not turns[-1] or k == cfg.search.turn_restarts or last.stop_reason == "interrupted"
            ):  # Ctrl-C ends it all
                break
            start, turned = tighter_start(start, turns[-1], cfg.search.restart_sigma_factor)
            if heard.on_restart is not None:
                heard.on_restart(
                    k + 1, turns[-1], {ch.name: ch.sigma for ch in start.sensor.channels if ch.name in turned}
                )
            runs.append(fit(start))
        return runs[0] if len(runs) == 1 else _kept_run(runs, turns, sigmas, data)

    return restarting


def tighter_start(start: EMModel, signs: list[LostSign], factor: float) -> tuple[EMModel, set[str]]:
    """``start`` with the start sigma of each channel the signs name (every channel's when one names none,
    an unsettled fit) ``factor`` of its last (``restart_sigma_factor``), and those channels."""
    turned = {t.channel for t in signs if not isinstance(t, Unsettled)}
    if any(isinstance(t, Unsettled) for t in signs):  # an unsettled fit names no channel: every one
        turned = {ch.name for ch in start.sensor.channels}
    channels = tuple(
        dc_replace(ch, sigma=ch.sigma * factor) if ch.name in turned else ch for ch in start.sensor.channels
    )
    return start.replace(sensor=dc_replace(start.sensor, channels=channels)), turned


def _kept_run(
    runs: list[EMResult], turns: list[list[LostSign]], sigmas: list[dict[str, float]], data: LandmarkLog
) -> EMResult:
    best, scores = most_likely(runs, data)
    info = [
        RestartRun(sigmas[i], float(scores[i]), r.loglik_best, r.iterations, r.stop_reason, tuple(turns[i]), i == best)
        for i, r in enumerate(runs)
    ]
    return dc_replace(runs[best], restarts=info, seconds=sum(r.seconds for r in runs))


def face_forward(fit: Fit, data: LandmarkLog, cfg: EMConfig, heard: Heard) -> Fit:
    """Each fit reported facing the way its robot drives, when its sensor cannot tell (``facing_forward``)."""
    return lambda start: facing_forward(fit(start), data)


def rerun_moved_start(fit: Fit, data: LandmarkLog, cfg: EMConfig, heard: Heard) -> Fit:
    """A fit whose sensor reads no bearing runs again from its learned start when that moved metres from the
    given one (``searches/given_start.py``): the given heading was as wrong as the position, and ranges cannot tell
    it, so headings race there first; the more likely of the two runs is kept."""

    def rerun(start: EMModel) -> EMResult:
        res = fit(start)
        moved = None if res.stop_reason == "interrupted" else start_moved_mm(start, res.model, data, cfg)
        if moved is None:
            return res
        if heard.on_start_moved is not None:
            heard.on_start_moved(moved, res.model.prior_mean.copy())
        trial = partial(held_trial, cfg=cfg)
        candidates = headings_at(start, res.model.prior_mean[:2], cfg.search.moved_start_headings)
        winner, race = race_starts(data, candidates, cfg, trial, on_trial=heard.on_race)
        again = fit(winner)
        best, scores = most_likely([res, again], data)
        headings = tuple(float(h) for h in race_headings(start, len(candidates)))
        info = StartMoved(
            tuple(start.prior_mean.tolist()),
            tuple(res.model.prior_mean.tolist()),
            moved,
            HeadingRace(race.winner, headings),
            tuple(float(s) for s in scores),
            ("first", "again")[best],
        )
        return dc_replace([res, again][best], start_moved=info, seconds=res.seconds + again.seconds)

    return rerun


# innermost first: the restarts wrap one EM run; each run faces forward; a moved start reruns all of it
POLICIES: tuple[Policy, ...] = (restart_while_lost, face_forward, rerun_moved_start)


def race_headings(start: EMModel, n: int) -> np.ndarray:
    """``n`` headings evenly round the circle from the given one."""
    return start.prior_mean[2] + 2.0 * np.pi * np.arange(n) / n


def headings_at(start: EMModel, position: np.ndarray, n: int) -> list[EMModel]:
    """``start`` placed at ``position`` facing each of ``race_headings``, its heading sd half the gap between
    them: the candidates of a range-only start's heading race."""
    cov = start.prior_cov.copy()
    cov[2, 2] = (np.pi / n) ** 2
    return [
        start.replace(prior_mean=np.array([position[0], position[1], h]), prior_cov=cov)
        for h in race_headings(start, n)
    ]


def most_likely(runs: list[EMResult], data: LandmarkLog) -> tuple[int, list[float]]:
    """Which of ``runs`` is the most likely, and each one's log-likelihood with the configured readings
    model on the sightings that every run kept after its first-iteration prune (runs without
    posteriors score -inf)."""
    scored = [r for r in runs if r.posteriors is not None]
    if not scored:
        return 0, [-np.inf] * len(runs)
    common = np.logical_and.reduce([r.posteriors.obs_used for r in scored])
    scores = [stage_loglik(r.model, data, common, robust=True) if r.posteriors is not None else -np.inf for r in runs]
    return int(np.argmax(scores)), scores


def facing_forward(res: EMResult, data: LandmarkLog) -> EMResult:
    """``res`` with its robot facing the way it drives, when its sensor cannot tell (``searches/facing.py``):
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


def refuse_settings_for_log(cfg: EMConfig, data: LandmarkLog, initial: EMModel | None) -> None:
    """Settings this log cannot be learned with, each one line naming the field, before any work."""
    if cfg.search.ridge_mm is not None and not data.geometry.has_heading:
        raise ConfigError(
            "search.ridge_mm moves the path along the robot's heading and needs a planar log.",
            file=data.source,
            field="search.ridge_mm",
            fix="set search.ridge_mm: null for a track.",
        )
    if cfg.motion_noise.sideways_mm is not None and not data.geometry.has_heading:
        raise ConfigError(
            "motion_noise.sideways_mm is a planar robot's sideways noise, and a track has no sideways.",
            file=data.source,
            field="motion_noise.sideways_mm",
            fix="remove it or set it to null.",
        )
    refuse_no_sightings(data)
    refuse_bearing_settings(cfg, data)
    if cfg.search.warm_start and initial is None:
        raise ConfigError(
            "search.warm_start starts EM from a learned model, and none was given.",
            file=data.source,
            field="search.warm_start",
            fix="give the model to start from (sensact learn em --start-from MODEL.json), or set "
            "search.warm_start: false.",
        )
