"""``calibrate_em(log, preset or config) -> Calibration``: what `sensact learn em DIR` does on a landmark
log (``app.calibrate`` is the door every kind goes through). It reads the settings (``settings.py``),
refuses what cannot run on the log in one line, runs EM (``learn.em.fit_em``; from a learned model placed
on the log, with ``start_from``), checks the fit without truth (``learn.em.checks``) and, when the log has
truth, scores it (``scores.py``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

from sensact.app.logs import OpenedLandmarkLog, learned_settings, read_model_and_log
from sensact.app.scores import Scores, Unscored, in_truth_frame, score_model
from sensact.app.settings import Settings, resolve_settings
from sensact.errors import ConfigError
from sensact.health import Health
from sensact.io.landmark_folder import LandmarkLogFile
from sensact.learn.em import EMConfig, EMResult, fit_em
from sensact.learn.em.checks.diagnostics import Diagnostics, diagnose
from sensact.learn.em.estep import Posteriors
from sensact.learn.em.fit import OnRestart, OnStartMoved
from sensact.learn.em.loop import OnIteration
from sensact.learn.em.result import FunctionBends, FunctionTurns, Unsettled
from sensact.learn.em.searches.start_race import OnTrial
from sensact.learn.em.uses.consistency import Consistency, consistency
from sensact.learn.em.uses.error_bars import Uncertainty
from sensact.learn.em.uses.place import Localized
from sensact.models.em_model import EMModel
from sensact.progress import Progress
from sensact.records import JsonObject, to_json


@dataclass(frozen=True)
class FitEvents:
    """What a calibration tells as it goes (each optional; the CLI shows them, a library user may pass none)."""

    progress: Progress | None = None  # a long step's share done: placing a start model, matching scans
    on_iteration: OnIteration | None = None  # every EM iteration
    on_race: OnTrial | None = None  # the start race's trials
    on_restart: OnRestart | None = None  # a restart from a tighter start (turn_restarts)
    on_start_moved: OnStartMoved | None = None  # a range-only start that moved metres
    on_placed: Callable[[StartFrom], None] | None = None  # ... and where it placed the robot, before EM
    on_settings: Callable[[Settings], None] | None = None  # the settings, once read, before any work


@dataclass(frozen=True)
class StartFrom:
    """The learned model a calibration started from (``start_from``), and where it placed the robot."""

    path: Path
    document: JsonObject  # its model.json
    placed: Localized
    log: OpenedLandmarkLog  # the log it was placed on (a Turtlebot CSV read onto the model's step)


@dataclass(frozen=True, eq=False)
class Calibration:
    """A calibration: the learned model and EM's record of it, the settings it ran with, its diagnostics
    and, when the log has truth, its scores (``Unscored`` with the reason when they could not be taken).
    Learning never reads the truth: the scores are taken when first asked for (``scores``)."""

    log: OpenedLandmarkLog
    settings: Settings
    result: EMResult
    diagnostics: Diagnostics
    start_from: StartFrom | None = None
    uncertainty: Uncertainty | None = None  # `--uncertainty B`'s error bars (app/uncertainty.py)

    @cached_property
    def scores(self) -> Scores | Unscored | None:
        """The learned model against the log's truth (``app/scores.py``); None when the log has none."""
        post = self.result.posteriors
        path = None if post is None else post.mean_gamma
        return score_model(self.log, self.model, learned_here=True, path=path, fit=self.result)

    def __repr__(self) -> str:
        """What was calibrated, how good the fit is, and how to write it: a few lines, never the arrays."""
        res, data = self.result, self.log.data
        health = self.diagnostics.health
        if isinstance(self.scores, Scores):
            path = (self.scores.evaluation.get("path") or {}).get("median_mm")
            bars = self.scores.bars
            scored = f"scored against {self.scores.against}" + (f": path median {path:.4g} mm" if path else "")
            scored += f", {sum(bars.values())} of {len(bars)} bars" if bars else ""
        else:
            scored = f"not scored ({self.scores.reason})" if self.scores is not None else "no truth to score against"
        return (
            f"Calibration of {self.log.name!r} ({data.geometry}, {data.n_steps} steps, {res.n_observations} readings)\n"
            f"  model: {type(self.model.action).__name__}, {type(self.model.sensor).__name__}\n"
            f"  EM: {res.stop_reason} after {res.iterations} iterations, log-likelihood {res.loglik_best:.6g}\n"
            f"  health: {'ok' if health.ok else 'flagged ' + ', '.join(f.code for f in health.flags)}; {scored}\n"
            "  write it with sensact.app.save_calibration(cal, 'model.json')"
        )

    @property
    def model(self) -> EMModel:
        return self.result.model

    @property
    def health(self) -> Health:
        return self.diagnostics.health

    @property
    def interrupted(self) -> bool:
        """Ctrl-C ended EM: the most likely model so far is the result."""
        return self.result.stop_reason == "interrupted"

    @cached_property
    def consistency(self) -> Consistency:
        """The model's one-step-ahead innovations on its own log, against its predictive law (on
        another run, `evaluate log` and `localize` give the same numbers, which decide whether a sigma holds)."""
        return consistency(self.model, self.log.data)

    @cached_property
    def in_truth_frame(self) -> tuple[LandmarkLogFile | None, Posteriors | None]:
        """The log folder and EM's posteriors as figures against the truth read them: on a learned map, the
        folder on its survey and the smoothed path aligned to it (``app/scores.in_truth_frame``)."""
        post, folder = self.result.posteriors, self.log.folder
        if self.model.landmarks is None or folder is None:
            return folder, post
        view = in_truth_frame(folder, self.model, None if post is None else post.mean_gamma, self.result)
        folder = replace(folder, data=view.data)
        if post is not None and view.path is not None:
            post = replace(post, mean_gamma=view.path)
        return folder, post

    @property
    def landmark_map(self) -> JsonObject | None:
        """model.json's ``map`` when EM learned the landmarks' positions (docs/map.md): ``landmarks`` (id, x_mm,
        y_mm, sd_x_mm, sd_y_mm, held, placed, sightings) in the log's frame and ``frame``; None on a surveyed map."""
        from sensact.learn.em.landmark_step import sightings_per_landmark

        learned, data = self.model.landmarks, self.log.data
        if learned is None:
            return None
        used = None if self.result.posteriors is None else self.result.posteriors.obs_used
        names = data.landmark_names or tuple(str(j) for j in range(len(learned.xy)))
        return learned.to_dict(names, sightings_per_landmark(data, used))

    @property
    def config(self) -> EMConfig:
        return self.settings.config

    def to_json(self) -> JsonObject:
        """The model file `learn em --out` writes (its key names are fixed: checks and reports read them)."""
        from sensact import __version__
        from sensact.models.wheel_drive import as_differential_drive
        from sensact.outputs import EM_MODEL, OUTPUT_KEY

        res, diag = self.result, self.diagnostics
        evaluation = self.scores.evaluation if isinstance(self.scores, Scores) else None
        if evaluation is not None:
            evaluation = evaluation | {"pruned_fraction": diag.pruned_fraction}
        signs = list(diag.lost_signs)
        return {
            "sensact_version": __version__,  # what EM learns has changed between versions: name the code
            OUTPUT_KEY: EM_MODEL,  # what this file is: an --out replaces only its own kind (io.atomic)
            "model": self.model.to_dict(),
            "summary": res.summary() | {"preset": self.settings.preset},
            "log": self.log.data.source,
            "dt_s": self.log.data.dt_s,
            "evaluation": evaluation,
            **({} if self.landmark_map is None else {"map": self.landmark_map}),
            # learn/em/checks/lost_signs.py: signs that EM lost the robot
            "range_function_turns": to_json([t for t in signs if isinstance(t, FunctionTurns)]),
            "range_function_bends": to_json([t for t in signs if isinstance(t, FunctionBends)]),
            "em_unsettled": to_json(next((t for t in signs if isinstance(t, Unsettled)), None)),
            "held_sideways_noise": diag.held_sideways,  # ... and that a robot that side-steps is held still
            # the share of sightings the gates dropped, and each channel's residuals' lag-1 autocorrelation
            "pruned_fraction": diag.pruned_fraction,
            "residual_lag1_autocorrelation": dict(diag.residual_lag1_autocorrelation),
            # per reading type, the filter's innovations in the model's 90 % interval, and their mean square
            "consistency": self.consistency.to_dict(),
            # on wheel speeds: gain, axle, ratio
            "differential_drive": to_json(as_differential_drive(self.model.action)),
            # a learned model EM started from, and where it placed the robot (learn/em/uses/warm_start.py)
            "start_from": None
            if self.start_from is None
            else {
                "model": str(self.start_from.path),
                "placed": self.start_from.placed.start,
                "loglik_per_sighting": self.start_from.placed.loglik_per_sighting,
            },
            "halves": None,  # `learn em --halves`: each half learned on from this model, and compared
            # `--uncertainty B`: each learned parameter's standard error and 90 % interval (learn/em/uses/error_bars.py)
            "uncertainty": None if self.uncertainty is None else self.uncertainty.to_dict(),
            "health": diag.health.to_dict(),  # learn/em/checks/fit_health.py: ok, or the flags of a degenerate fit
        }


def refuse_table_on_continuous_commands(log: OpenedLandmarkLog, cfg: EMConfig) -> None:
    """The thesis's action table needs discrete actions; a planar log of continuous commands needs a basis."""
    data = log.data
    if not (data.is_continuous and cfg.action.basis == "table" and data.geometry.has_heading):
        return
    beside = log.settings_file
    raise ConfigError(
        f"{data.source} has continuous commands, and the action model is the thesis's table of discrete actions.",
        field="action.basis",
        fix=(
            f"pass --config {beside} (the settings written beside the log)"
            if beside is not None
            else "pass --preset differential_drive_camera (or --set action.basis=affine, or a --config with it; "
            "docs/em-real.md)"
        )
        + ".",
    )


def _placed_start(
    start_from: Path, doc: JsonObject, model: EMModel, log: OpenedLandmarkLog, settings: Settings, events: FitEvents
) -> tuple[EMModel, Settings, StartFrom]:
    """A learned model placed on the log (``learn/em/uses/warm_start.py``): the model EM starts from, the settings
    EM runs with and the placement."""
    from sensact.learn.em.uses.warm_start import start_from_model

    placed, cfg = start_from_model(model, log.data, settings.config, events.progress, source=str(start_from))
    start = StartFrom(start_from, doc, placed, log)
    if events.on_placed is not None:
        events.on_placed(start)
    return placed.model, replace(settings, config=cfg), start


def calibrate_em(
    log: OpenedLandmarkLog,
    preset: str | None = None,
    config: EMConfig | Path | None = None,
    *,
    sets: Sequence[str] = (),
    start_from: Path | None = None,
    events: FitEvents | None = None,
) -> Calibration:
    """Learn ``log``'s action and sensor models by EM (ch. 4), as `sensact learn em` does.

    Settings: ``config`` as an ``EMConfig`` is taken whole; otherwise ``resolve_settings`` (``preset``, a
    settings YAML ``config``, ``sets``; with ``start_from``, the start model's own settings are the base).
    ``start_from``: a model.json of `learn em` to start from instead of the thesis's poor guess, placed on
    the log first. Ctrl-C ends EM cleanly with the most likely model so far (``stop_reason``)."""
    events = events or FitEvents()
    base = doc = model = None
    if start_from is not None:  # read once; a Turtlebot CSV onto the model's step
        doc, model, log = read_model_and_log(log.path, start_from, log.bins, use="start")
        base = learned_settings(doc, str(start_from))
    if isinstance(config, EMConfig):
        settings = Settings(config, preset, "given")
    else:
        settings = resolve_settings(log, preset=preset, config=config, sets=sets, base=base)
    if events.on_settings is not None:
        events.on_settings(settings)
    refuse_table_on_continuous_commands(log, settings.config)
    start = placed = None  # None: fit_em starts from sec. 4.4.1's poor guess, once it has refused what cannot run
    if start_from is not None:
        start, settings, placed = _placed_start(start_from, doc, model, log, settings, events)
    result = fit_em(
        log.data,
        start,
        settings.config,
        on_iteration=events.on_iteration,
        on_restart=events.on_restart,
        on_race=events.on_race,
        on_start_moved=events.on_start_moved,
    )
    if result.model.landmarks is not None:  # what reads the log from here on reads it on the learned map
        log = replace(log, data=log.data.with_landmarks(result.model.landmarks.xy))
    return Calibration(log, settings, result, diagnose(result, log.data, settings.config), placed)
