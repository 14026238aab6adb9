"""A fleet of robots (`sensact fleet learn`, `sensact evaluate fleet`): each log calibrated as a job of an
engine (``sensact.engine``), what `sensact learn em LOG --out OUT` does, where a worker runs it
(``learn_fleet``); and every model scored on every robot's log (beyond the thesis, whose robots had one
log each): does one robot's learned model serve another robot of its kind?

Two scores, each a grid of (model, log) pairs:

* against the **ground truth**, when every log has recorded poses: ``score_against_truth`` of the model
  on the log, with From-Truth fitted on that log, and the real-data bars (``real.bar_checks``);
* by the **likelihood**, with no ground truth at all: the model placed on the log by the E-step alone
  (``learn.em.localize``, sec. 4.2 with the model held) and its ``log P(O | C, lambda)`` (eq. 4.14) per
  sighting. On one log the models read the same sightings unless the first-iteration gate (sec. 4.4.1)
  drops different ones (each cell says how many it used), so the fall of a model below the log's most
  likely one says how much worse it explains that robot's run.

A Turtlebot CSV (``RangeLog``, read onto each model's step) has no recorded poses but a ``range``
column: each model placed on it is also scored against the range, as `evaluate log` scores it
(``range_cell``: the action gain and the best sensor through the optimal scale and offset of sec. 4.4.3,
against the Turtlebot's bars (docs/em-real.md)).

A pair is the robot's *own* when the model was learned on that log; it has a small edge there, having
been fitted to those very sightings. MRCLAM's five robots are one kind of robot: their action models
carry over, their cameras' range functions do not (docs/em-real.md, "One robot's model on another
robot").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sensact.app.uncertainty import ErrorBars
from sensact.errors import ConfigError
from sensact.evaluate.bars import BARS, bar_checks
from sensact.evaluate.landmark_truth import score_against_truth
from sensact.evaluate.turtlebot_em import (
    GAIN_BAR_PCT,
    SENSOR_BAR_PCT,
    best_sensor,
    range_column_problem,
    score_turtlebot_em,
)
from sensact.evaluate.turtlebot_em import scorecard as turtlebot_scorecard
from sensact.health import Health
from sensact.learn.em.config import EMConfig
from sensact.learn.em.uses.place import Localized, localize
from sensact.progress import Progress
from sensact.records import JsonObject
from sensact.reprs import compact_repr


@dataclass(frozen=True)
class LearnOptions:
    """What `learn em` is given besides the log; every log of the fleet gets the same."""

    preset: str | None = None
    config: Path | None = None  # a settings YAML (where each worker can read it)
    sets: tuple[str, ...] = ()
    report: bool = True  # report.html beside each model
    uncertainty: ErrorBars | None = None  # `--uncertainty`: the error bars, in the log's own job


@dataclass(frozen=True)
class Learned:
    """A log calibrated: where its model is and how EM ended (the model's JSON has the rest)."""

    __repr__ = compact_repr  # a line, never the arrays

    log: str
    model: str  # its model.json
    stop_reason: str
    iterations: int
    loglik_best: float
    n_used: int
    seconds: float  # EM's own time
    warnings: tuple[str, ...]  # the diagnostics' lines (``Diagnostics.warnings``)
    written: tuple[str, ...]
    health: Health = field(default_factory=Health)  # learn/em/checks/fit_health.py: flagged fits end the fleet with 3
    job_seconds: float = 0.0  # the whole job's wall time: read, learn, write
    cpu_seconds: float = 0.0  # its process's CPU time meanwhile (the job's own, on a worker of one thread)

    def to_dict(self) -> JsonObject:
        return {
            "status": "learned",
            "log": self.log,
            "model": self.model,
            "stop_reason": self.stop_reason,
            "iterations": self.iterations,
            "loglik_best": self.loglik_best,
            "n_used": self.n_used,
            "seconds": self.seconds,
            "warnings": list(self.warnings),
            "written": list(self.written),
            "health": self.health.to_dict(),
            "job_seconds": self.job_seconds,
            "cpu_seconds": self.cpu_seconds,
        }


def learn_log(log: Path, out: Path, options: LearnOptions, *, progress: Progress | None = None) -> Learned:
    """``log`` calibrated and written at ``out`` exactly as `sensact learn em LOG --out OUT` writes it (with
    ``options.uncertainty``, as `learn em --uncertainty` does: a bootstrap's replicates one after another here)."""
    import time
    from dataclasses import replace

    from sensact.app.log_kinds import landmark_log

    t0, c0 = time.perf_counter(), time.process_time()
    learned = calibrate_and_save(landmark_log(log, "fleet learn"), out, options, progress=progress)[1]
    return replace(learned, job_seconds=time.perf_counter() - t0, cpu_seconds=time.process_time() - c0)


def calibrate_and_save(
    opened: Any,
    out: Path,
    options: LearnOptions,
    *,
    progress: Progress | None = None,
    finish: Callable[[Any], Any] | None = None,
) -> tuple[Any, Learned]:
    """``learn_log`` on a log already open; ``finish`` turns the calibration into the one written (the
    shared map's fleet attaches its map). Returns the calibration too."""
    from sensact.app.em import FitEvents, calibrate_em
    from sensact.app.save import save_em_calibration

    events = FitEvents()
    if progress is not None:
        show = progress
        events = FitEvents(
            progress=show,
            on_iteration=lambda it, ll, best, since: show(
                f"EM: log-likelihood {ll:.1f} (best {best:.1f})", it + 1, None
            ),
            on_race=lambda done, planned: show("start race: EM from each start", done, planned),
        )
    cal = calibrate_em(opened, options.preset, options.config, sets=options.sets, events=events)
    if finish is not None:
        cal = finish(cal)
    out.parent.mkdir(parents=True, exist_ok=True)
    saved = save_em_calibration(cal, out, report=options.report)
    if options.uncertainty is not None:  # after the model is written, as `learn em --uncertainty` does
        from sensact.app.uncertainty import error_bars

        done = [0]
        asked = options.uncertainty

        def replicated(i: int, outcome: Any) -> None:
            done[0] += 1
            if progress is not None:
                progress("bootstrap: replicates learned", done[0], asked.replicates)

        cal = error_bars(cal, asked, on_done=replicated)
        saved = save_em_calibration(cal, out, report=options.report)
    res = cal.result
    return cal, Learned(
        log=str(opened.path),
        model=str(out),
        stop_reason=res.stop_reason,
        iterations=res.iterations,
        loglik_best=res.loglik_best,
        n_used=res.n_used,
        seconds=res.seconds,
        warnings=cal.diagnostics.warnings,
        written=tuple(str(p) for p in saved.written),
        health=cal.diagnostics.health,
    )


# the bars' own keys for the action model and for the sensor
ACTION_BARS = ("action_translation_ratio", "action_rotation_ratio", "action_translation_abs")


def fleet_cell(sc: JsonObject) -> JsonObject:
    """The numbers of one (model, log) pair that a fleet table shows, from a ``score_against_truth`` result."""
    a, r, b = sc["action"], sc["range"], sc["bearing"]
    return {
        "translation_ratio": a["ratio_translation"],
        "rotation_ratio": a["ratio_rotation"],
        "translation_rms_mm_s": a["learned"]["translation_rms_mm_s"],
        "rotation_rms_rad_s": a["learned"]["rotation_rms_rad_s"],
        "delay_s": a["learned_delay_s"],
        "range_residual_rms_mm": r["learned_residual_rms_mm"],
        "range_from_truth_rms_mm": r["from_truth_residual_rms_mm"],
        "range_sigma_ratio": r["sigma_ratio"],
        "bearing_sigma_ratio": None if b is None else b["sigma_ratio"],  # None: the model reads no bearing
        # a model on another robot's log has no path of its own: every cell is barred alike, without one
        "bars": bar_checks({k: v for k, v in sc.items() if k != "path"}),
    }


@dataclass(frozen=True)
class RangeLog:
    """A Turtlebot CSV in a fleet, read onto each model's step: ``reads[model]`` is what EM reads and the
    ``range`` column (mm at each step; None when the file has none, NaN where a step has none). A CSV's
    step is its reader's choice, the file's median, so models learned on two runs have steps a hair apart,
    and each is placed on the file as `evaluate log` reads it for that model. No recorded poses. A track
    folder with a recorded distance (``distance_mm``) is one too, read once on its own step."""

    reads: Mapping[str, tuple[Any, np.ndarray | None]]

    def truth_poses(self) -> None:
        return None

    @property
    def range_problem(self) -> str | None:
        """Why the range cannot score a model (``range_column_problem``), or None: it is there at every step."""
        return range_column_problem(next(iter(self.reads.values()))[1])


def recorded_truth(log: Any) -> tuple[Any, Any] | None:
    """A log's recorded poses, or None where there are none to score against (``score_against_truth``
    scores a log of continuous commands)."""
    truth = log.truth_poses()
    return truth if truth is not None and log.data.is_continuous else None


def score_fleet(
    models: JsonObject,
    logs: JsonObject,
    own: Mapping[str, str] | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
    configs: Mapping[str, EMConfig] | None = None,
) -> JsonObject:
    """Every model of ``models`` ({name: EMModel}) on every log of ``logs`` ({name: anything with ``data``
    and ``truth_poses()``}: an ``MrclamLog``, a log folder or a ``RangeLog``). ``own`` maps a model's name
    to the log it was learned on. Against the truth (``cells``, ``summary``) when every log has recorded
    poses; by the likelihood (``likelihood``) when ``configs`` gives each model the settings ``localize``
    places the robot with (``uses/place.learned_config``), and then, on the Turtlebot CSVs whose range is
    there at every step, against the range (``range``). Cells are keyed ``cells[model][log]``. Here, a log
    after another; ``score_fleet_on`` scores the logs as jobs of an engine."""
    columns = {}
    for k, (name, log) in enumerate(logs.items()):
        step = None if progress is None else _column_progress(progress, k, len(logs))
        columns[name] = score_column(models, log, configs, step)
    return assemble_fleet(columns, list(models), own)


def _column_progress(progress: Callable[[str, int, int | None], None], k: int, n_logs: int) -> Any:
    return lambda desc, done, total: progress(desc, k * (total or 0) + done, n_logs * (total or 0))


def score_column(
    models: JsonObject,
    log: Any,
    configs: Mapping[str, EMConfig] | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
) -> JsonObject:
    """Every model on one log: ``truth`` (``fleet_cell`` per model, None when the log has no recorded
    poses) and the log's recorded heading doubt; with ``configs``, ``likelihood`` (``likelihood_cell``) and,
    on a ``RangeLog`` whose range is there at every step, ``range`` (``range_cell``). Plain values: a
    column may be scored on another machine."""
    truth = recorded_truth(log)
    column: JsonObject = {"truth": None, "truth_heading_doubt": None, "likelihood": None, "range": None}
    steps = len(models) * ((truth is not None) + (configs is not None))
    done = 0
    if truth is not None:
        poses, valid = truth
        column["truth"] = {}
        for name, model in models.items():
            sc = score_against_truth(model, log.data, poses, valid)
            column["truth"][name] = fleet_cell(sc)
            column["truth_heading_doubt"] = sc.get("truth_heading_doubt", column["truth_heading_doubt"])
            done += 1
            if progress:
                progress("scoring models against the truth", done, steps)
    if configs is None:
        return column
    ranged = isinstance(log, RangeLog)
    column["likelihood"] = {}
    column["range"] = {} if ranged and log.range_problem is None else None
    for name, model in models.items():
        data, range_mm = log.reads[name] if ranged else (log.data, None)
        loc = place(model, data, configs[name])
        column["likelihood"][name] = likelihood_cell(loc)
        if column["range"] is not None:
            column["range"][name] = range_cell(loc, data, range_mm)
        done += 1
        if progress:
            progress("placing each model on each log", done, steps)
    if ranged:
        column["range_problem"] = log.range_problem
    return column


def assemble_fleet(
    columns: Mapping[str, JsonObject], models: list[str], own: Mapping[str, str] | None = None
) -> JsonObject:
    """``score_fleet``'s result from each log's ``score_column``."""
    own = dict(own or {})
    out: JsonObject = {"bars": dict(BARS), "models": list(models), "logs": list(columns), "own": own}
    if all(c["truth"] is not None for c in columns.values()):
        cells = {m: {g: c["truth"][m] for g, c in columns.items()} for m in models}
        out.update(cells=cells, summary=fleet_summary(cells, own))
        doubts = {g: c["truth_heading_doubt"] for g, c in columns.items() if c["truth_heading_doubt"]}
        if doubts:
            out["truth_heading_doubts"] = doubts
    else:
        out["no_truth"] = [g for g, c in columns.items() if c["truth"] is None]
    if all(c["likelihood"] is not None for c in columns.values()):
        out.update(likelihood_grid(columns, models, own))
    return out


def place(model: Any, data: Any, config: EMConfig) -> Localized | str:
    """One model placed on one log by the E-step alone, or why the filter failed from every start."""
    try:
        return localize(model, data, config)
    except ConfigError as exc:
        return exc.problem


def likelihood_cell(loc: Localized | str) -> JsonObject:
    """A placed model's log-likelihood, over how many sightings, and per sighting; a model the filter failed
    with (``place`` gave why) is a cell without a likelihood."""
    if isinstance(loc, str):
        return {"loglik": None, "n_used": 0, "per_sighting": None, "failed": loc}
    post = loc.posteriors
    return {
        "loglik": float(post.loglik),
        "n_used": int(post.n_used),
        "per_sighting": float(loc.loglik_per_sighting),
        "filter_ok": bool(post.ok),
    }


def likelihood_grid(columns: Mapping[str, JsonObject], models: list[str], own: Mapping[str, str]) -> JsonObject:
    """``{"likelihood": ...}``: each model placed on each log (``likelihood_cell``), and each one's fall per
    sighting below the log's most likely model (``below_best``: 0 for that model); and ``"range"``, each
    placed model scored on each ``RangeLog`` whose range is there at every step (``range_grid``)."""
    cells: dict[str, JsonObject] = {m: {g: dict(c["likelihood"][m]) for g, c in columns.items()} for m in models}
    for g in columns:
        scored = [cells[m][g]["per_sighting"] for m in models if cells[m][g]["per_sighting"] is not None]
        best = max(scored) if scored else None
        for m in models:
            c = cells[m][g]
            c["below_best"] = None if c["per_sighting"] is None else best - c["per_sighting"]
    out: JsonObject = {"likelihood": {"cells": cells, "summary": likelihood_summary(cells, list(columns), own)}}
    ranged = {g: c for g, c in columns.items() if "range_problem" in c}
    if ranged:
        range_cells = {m: {g: c["range"][m] for g, c in ranged.items() if c["range"] is not None} for m in models}
        out["range"] = range_grid(range_cells, {g: c["range_problem"] for g, c in ranged.items()}, own)
    return out


def range_cell(loc: Localized | str, data: Any, range_mm: np.ndarray) -> JsonObject:
    """A placed model scored against a Turtlebot CSV's range as `evaluate log` scores it
    (``score_turtlebot_em``): the action gain's error (None on a log that holds one command) and each
    sensor's error in % of its span, with the Turtlebot's two bars (docs/em-real.md; ``gain`` None where not scored)."""
    if isinstance(loc, str):
        return {"failed": loc, "gain_error_pct": None, "best_sensor": None, "best_sensor_pct": None, "bars": {}}
    sc = score_turtlebot_em(loc, data, range_mm)
    best, pct = best_sensor(sc)
    gain, sensor = turtlebot_scorecard({"score": sc})  # the bars `reproduce real` holds a Turtlebot run to
    return {
        "gain_learned": sc["gain_learned"],
        "gain_true": sc["gain_true"],
        "gain_error_pct": sc["gain_error_pct"],
        "one_command_share": sc["one_command_share"],
        "sensors_pct_of_span": {k: v["rms_pct_of_span"] for k, v in sc["sensors"].items()},
        "best_sensor": best,
        "best_sensor_pct": pct,
        "bars": {"gain": gain.cleared, "sensor": sensor.cleared},
    }


def range_grid(cells: dict[str, JsonObject], problems: Mapping[str, str | None], own: Mapping[str, str]) -> JsonObject:
    """The pairs scored against the range, the logs they are on (``logs``), the Turtlebot CSVs that could not
    score (``no_range``, with why), and over the robots' own pairs and the others how many clear each bar."""
    scored = [g for g, problem in problems.items() if problem is None]
    no_range = {g: problem for g, problem in problems.items() if problem is not None}
    groups: dict[str, list[JsonObject]] = {"own": [], "other": []}
    for m, row in cells.items():
        for g, c in row.items():
            groups["own" if own.get(m) == g else "other"].append(c)

    def describe(cs: list[JsonObject]) -> JsonObject:
        gains = [c["gain_error_pct"] for c in cs if c["gain_error_pct"] is not None]
        return {
            "pairs": len(cs),
            "gain_scored": len(gains),
            "clear_gain_bar": sum(bool(c["bars"].get("gain")) for c in cs),
            "clear_sensor_bar": sum(bool(c["bars"].get("sensor")) for c in cs),
            "gain_error_pct_max": float(max(gains)) if gains else None,
        }

    return {
        "bars": {"gain_pct_max": GAIN_BAR_PCT, "sensor_pct_max": SENSOR_BAR_PCT},
        "logs": scored,
        "no_range": no_range,
        "cells": cells,
        "summary": {name: describe(cs) for name, cs in groups.items()},
    }


def likelihood_summary(cells: dict[str, JsonObject], logs: list[str], own: Mapping[str, str]) -> JsonObject:
    """Per log, the most likely model, and the most likely of the others (a log's own model left out, or
    the runner-up where no model is its own) with its fall; and on how many logs the own model wins."""
    owner = {g: m for m, g in own.items() if m in cells}
    per_log: JsonObject = {}
    for g in logs:
        ranked = sorted(
            (m for m in cells if cells[m][g]["per_sighting"] is not None), key=lambda m: -cells[m][g]["per_sighting"]
        )
        if not ranked:
            per_log[g] = {"most_likely": None, "closest_other": None, "closest_other_below": None}
            continue
        others = [m for m in ranked if m != owner.get(g, ranked[0])]
        per_log[g] = {
            "most_likely": ranked[0],
            "closest_other": others[0] if others else None,
            "closest_other_below": cells[others[0]][g]["below_best"] if others else None,
        }
    with_own = [g for g in logs if g in owner]
    return {
        "per_log": per_log,
        "logs_with_own": len(with_own),
        "own_most_likely": sum(per_log[g]["most_likely"] == owner[g] for g in with_own),
    }


def fleet_summary(cells: dict[str, JsonObject], own: Mapping[str, str]) -> JsonObject:
    """Over the pairs that are a robot's own and those that are not (every pair is "other" when ``own`` is
    empty): how many clear the action bars and the sigma bars, the worst action ratios, and the range
    residual's span."""
    groups: dict[str, list[JsonObject]] = {"own": [], "other": []}
    for model_name, row in cells.items():
        for log_name, c in row.items():
            groups["own" if own.get(model_name) == log_name else "other"].append(c)

    def describe(cs: list[JsonObject]) -> JsonObject:
        if not cs:
            return {"pairs": 0}
        rng = [c["range_residual_rms_mm"] for c in cs]
        return {
            "pairs": len(cs),
            "clear_action_bars": sum(all(c["bars"][k] for k in ACTION_BARS) for c in cs),
            "clear_range_sigma_bar": sum(c["bars"]["range_sigma"] for c in cs),
            "clear_bearing_sigma_bar": sum(c["bars"].get("bearing_sigma", False) for c in cs),
            "bearing_pairs": sum("bearing_sigma" in c["bars"] for c in cs),
            "translation_ratio_max": float(max(c["translation_ratio"] for c in cs)),
            "rotation_ratio_max": float(max(c["rotation_ratio"] for c in cs)),
            "range_residual_rms_mm": [float(np.min(rng)), float(np.max(rng))],
        }

    return {name: describe(cs) for name, cs in groups.items()}


# A fleet given by paths, as `evaluate fleet` and `fleet learn` give it: each log is scored as a job of an
# engine (``sensact.engine``), which reads the models and the log where it runs.


@dataclass(frozen=True)
class FleetModel:
    """A model.json of `learn em` in a fleet: its short name, the document, the model and the settings
    ``localize`` places the robot with (``uses/place.learned_config``)."""

    name: str
    path: Path
    document: JsonObject
    model: Any
    config: EMConfig


def fleet_names(paths: Sequence[Path], name: Callable[[Path], str]) -> list[str]:
    """Short, distinct names, each one folder's name under a fleet's ``--out``: ``name(path)`` (a folder's or
    a file's own name); where two would share one, the path's last folders joined by ``_`` (``a/r1`` and
    ``b/r1`` are ``a_r1`` and ``b_r1``), as many as tell them apart, never a path that leaves ``--out``."""
    short = [name(p) for p in paths]
    out = []
    for p, s in zip(paths, short, strict=True):
        if short.count(s) == 1:
            out.append(s)
            continue
        parts = [q for q in Path(p).resolve().parts[1:-1] if q not in ("", "..")]
        others = [Path(q).resolve().parts[1:-1] for q, t in zip(paths, short, strict=True) if t == s and q != p]
        k = 1
        while k < len(parts) and any(tuple(parts[-k:]) == tuple(o[-k:]) for o in others):
            k += 1
        out.append("_".join([*parts[-k:], s]) if parts else s)
    for i, s in enumerate(out):  # the same folder twice, or tails that still agree: numbered
        if out.count(s) > 1:
            out[i] = f"{s}-{out[: i + 1].count(s)}"
    return out


def log_name(path: Path) -> str:
    """A log's short name: a folder's own name ("." names the folder it is), a CSV's without ``.csv``."""
    return path.stem if path.is_file() else path.resolve().name


def read_fleet_models(paths: Sequence[Path], names: Sequence[str] | None = None) -> list[FleetModel]:
    """Each model.json, named ``names`` or by its file's stem (its path where two share one)."""
    from sensact.app.logs import read_em_model
    from sensact.learn.em.uses.place import learned_config

    out = []
    for path, name in zip(paths, names or fleet_names(paths, lambda p: p.stem), strict=True):
        doc, m = read_em_model(path)
        out.append(FleetModel(name, path, doc, m, learned_config((doc.get("summary") or {}).get("config"), str(path))))
    return out


def read_fleet_log(path: Path, models: Sequence[FleetModel]) -> Any:
    """A log as the fleet scores it, each model refused in one line where it does not fit: a Turtlebot CSV
    read onto each model's own step (a ``RangeLog``), a track folder with a recorded distance as a
    ``RangeLog`` on its own step, any other folder as its ``LogFolder`` (a track1d folder's commands binned
    as `evaluate log` bins them)."""
    from sensact.app.logs import open_landmark_log, refuse_model_for_log

    opened = open_landmark_log(path, bins=21)
    if opened.folder is None:  # a CSV of timed rows: read onto each model's own step
        on_step = {fm.name: open_landmark_log(path, dt_s=fm.document.get("dt_s")) for fm in models}
        log: Any = RangeLog({name: (o.data, o.recorded_distance_mm) for name, o in on_step.items()})
    else:
        distance = opened.recorded_distance_mm
        log = opened.folder if distance is None else RangeLog({fm.name: (opened.data, distance) for fm in models})
    for fm in models:
        data = log.reads[fm.name][0] if isinstance(log, RangeLog) else log.data
        refuse_model_for_log(dict(fm.document), fm.model, data, fm.path, path)
    return log


def score_log_job(
    log: Path, model_paths: tuple[Path, ...], names: tuple[str, ...], *, progress: Any = None
) -> JsonObject:
    """One column of the fleet's grid as an engine's job: the models (named ``names``) and ``log`` read where
    it runs, every model scored on it (``score_column``)."""
    models = read_fleet_models(model_paths, names)
    read = read_fleet_log(log, models)
    return score_column({fm.name: fm.model for fm in models}, read, {fm.name: fm.config for fm in models}, progress)


def learned_on_log(doc: JsonObject, log: Path) -> bool:
    """Whether model.json says it was learned on ``log``: ``learn em`` records the folder as it was given, so
    a relative one matches the end of the log's full path (it may have been run from another folder)."""
    recorded = doc.get("log")
    if not recorded:
        return False
    path, full = Path(str(recorded)), log.resolve()
    parts = tuple(q for q in path.parts if q != ".")
    if path.is_absolute() or not parts or ".." in parts:  # "." or "../x" name a folder only from where it ran
        return path.resolve() == full
    return full.parts[-len(parts) :] == parts


def score_fleet_on(
    engine: Any,
    model_paths: Sequence[Path],
    logs: Sequence[Path],
    on_progress: Any = None,
    on_done: Any = None,
    model_names: Sequence[str] | None = None,
) -> JsonObject:
    """``score_fleet`` of the models at ``model_paths`` (named ``model_names``, or by their files) on the logs
    at ``logs``, a job per log on ``engine`` (``sensact.engine``); a model that does not fit a log is refused
    in one line (``JobFailed`` from a cluster)."""
    from sensact.engine import Job

    models = read_fleet_models(model_paths, model_names)
    given = tuple(fm.name for fm in models)
    names = fleet_names(logs, log_name)
    own = {fm.name: g for fm in models for p, g in zip(logs, names, strict=True) if learned_on_log(fm.document, p)}
    args = [(p, tuple(model_paths), given) for p in logs]
    jobs = [Job(score_log_job, a, g, cost=_log_cost(a[0])) for a, g in zip(args, names, strict=True)]
    columns = engine.run(jobs, on_progress=on_progress, on_done=on_done)
    return assemble_fleet(dict(zip(names, columns, strict=True)), [fm.name for fm in models], own)


def _log_cost(path: Path) -> float:
    """A log's size on disk, as a guess of how long its jobs take (its steps and sightings)."""
    files = [path] if path.is_file() else [p for p in path.glob("*.csv") if p.is_file()]
    return float(sum(p.stat().st_size for p in files))


# `sensact fleet learn`: every log calibrated as a job of an engine, then every model scored on every log.


@dataclass(frozen=True)
class FleetEvents:
    """What a fleet run tells as it goes (each optional): a log's progress and its end while learning (by
    the log's index), and a log's progress while the models are scored on it."""

    learning: Callable[[int, str, int, int | None], None] | None = None
    learned: Callable[[int, Any], None] | None = None
    scoring: Callable[[int, str, int, int | None], None] | None = None


@dataclass(frozen=True)
class FleetRun:
    """A fleet learned: each log's outcome (``app.fleet.Learned`` or ``engine.Failed``), by its short name,
    and every model on every log (``score_fleet``'s result; None when fewer than two logs were learned or
    it was not asked for, ``cross_scores_skipped`` saying why when a model did not fit another log)."""

    logs: tuple[Path, ...]
    names: tuple[str, ...]
    outcomes: tuple[Any, ...]
    cross_scores: JsonObject | None
    cross_scores_skipped: str | None
    where: str
    workers: int
    seconds: float

    @property
    def jobs_seconds(self) -> float:
        """The learned logs' own wall times summed: the fleet's work one after another, at the same threads
        (an upper bound: two jobs at once on shared cores and memory each run a little slower than alone)."""
        return float(sum(getattr(o, "job_seconds", 0.0) for o in self.outcomes))

    @property
    def cpu_seconds(self) -> float:
        return float(sum(getattr(o, "cpu_seconds", 0.0) for o in self.outcomes))

    @property
    def speedup_at_most(self) -> float | None:
        """The logs' own times summed over the fleet's wall time (None when nothing was learned): a bound on
        the speedup over the same logs one after another, since a job beside another runs slower than alone
        (MRCLAM robots 1-4 on two cores: 1.87 printed, 1.56 measured by benchmarks/fleet_speedup.py)."""
        return self.jobs_seconds / self.seconds if self.jobs_seconds > 0 and self.seconds > 0 else None

    @property
    def n_failed(self) -> int:
        from sensact.engine import Failed

        return sum(isinstance(o, Failed) for o in self.outcomes)

    def to_json(self) -> JsonObject:
        """fleet.json (its key names are fixed: checks read them)."""
        from sensact.engine import Failed

        def entry(path: Path, o: Any) -> JsonObject:
            if isinstance(o, Failed):
                return {"status": "failed", "log": str(path), "error": o.error, "bad_input": o.bad_input}
            return o.to_dict()

        return {
            "logs": {g: entry(p, o) for p, g, o in zip(self.logs, self.names, self.outcomes, strict=True)},
            "learned": len(self.outcomes) - self.n_failed,
            "failed": self.n_failed,
            "engine": {"where": self.where, "workers": self.workers},
            "seconds": self.seconds,
            "jobs_seconds": self.jobs_seconds,
            "cpu_seconds": self.cpu_seconds,
            "speedup_at_most": self.speedup_at_most,
            "cross_scores": self.cross_scores,
            "cross_scores_skipped": self.cross_scores_skipped,
        }


def learn_fleet(
    engine: Any,
    logs: Sequence[Path],
    out: Path,
    options: Any = None,
    *,
    cross_scores: bool = True,
    events: FleetEvents | None = None,
) -> FleetRun:
    """Each log of ``logs`` calibrated as `learn em LOG --out OUT/NAME/model.json` would (``app.fleet.learn_log``),
    a job each on ``engine``; a log that fails is its one line and the others go on. Then, with
    ``cross_scores`` and two or more models learned, every model on every log learned (``score_fleet_on``)."""
    import time

    from sensact.engine import Failed, Job

    events = events or FleetEvents()
    t0 = time.perf_counter()
    names = fleet_names(logs, log_name)
    opts = options if options is not None else LearnOptions()
    jobs = [
        Job(learn_log, (p, out / g / "model.json", opts), g, cost=_log_cost(p) if p.exists() else 0.0)
        for p, g in zip(logs, names, strict=True)
    ]
    outcomes = engine.run(jobs, isolate=True, on_progress=events.learning, on_done=events.learned)
    learned = [(p, o) for p, o in zip(logs, outcomes, strict=True) if not isinstance(o, Failed)]
    scores, skipped = None, None
    if cross_scores and len(learned) >= 2:
        from sensact.errors import SensactError

        try:
            scores = score_fleet_on(
                engine,
                [Path(o.model) for _, o in learned],
                [p for p, _ in learned],
                on_progress=events.scoring,
                model_names=[g for g, o in zip(names, outcomes, strict=True) if not isinstance(o, Failed)],
            )
        except SensactError as exc:  # robots of other kinds: a model that does not fit another's log
            skipped = str(exc)
    return FleetRun(
        tuple(logs),
        tuple(names),
        tuple(outcomes),
        scores,
        skipped,
        engine.where,
        engine.workers,
        time.perf_counter() - t0,
    )
