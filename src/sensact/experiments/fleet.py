"""A fleet's models, each scored on every robot's log (beyond the thesis, whose robots had one log
each): does one robot's learned model serve another robot of its kind?

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
against issue 5's Turtlebot bars).

A pair is the robot's *own* when the model was learned on that log; it has a small edge there, having
been fitted to those very sightings. MRCLAM's five robots are one kind of robot: their action models
carry over, their cameras' range functions do not (docs/em-real.md, "One robot's model on another
robot").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.errors import ConfigError
from sensact.evaluate.bars import BARS, bar_checks
from sensact.evaluate.landmark_truth import score_against_truth
from sensact.evaluate.turtlebot_em import range_column_problem, score_turtlebot_em
from sensact.experiments.turtlebot_em import GAIN_BAR_PCT, SENSOR_BAR_PCT, best_sensor
from sensact.experiments.turtlebot_em import scorecard as turtlebot_scorecard
from sensact.learn.em.config import EMConfig
from sensact.learn.em.localize import Localized, localize

# the bars' own keys for the action model and for the sensor
ACTION_BARS = ("action_translation_ratio", "action_rotation_ratio", "action_translation_abs")


def fleet_cell(sc: dict[str, Any]) -> dict[str, Any]:
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
    models: Mapping[str, Any],
    logs: Mapping[str, Any],
    own: Mapping[str, str] | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
    configs: Mapping[str, EMConfig] | None = None,
) -> dict[str, Any]:
    """Every model of ``models`` ({name: EMModel}) on every log of ``logs`` ({name: anything with ``data``
    and ``truth_poses()``}: an ``MrclamLog``, a log folder or a ``RangeLog``). ``own`` maps a model's name
    to the log it was learned on. Against the truth (``cells``, ``summary``) when every log has recorded
    poses; by the likelihood (``likelihood``) when ``configs`` gives each model the settings ``localize``
    places the robot with (``localize.learned_config``), and then, on the Turtlebot CSVs whose range is
    there at every step, against the range (``range``). Cells are keyed ``cells[model][log]``."""
    own = dict(own or {})
    truths = {name: recorded_truth(log) for name, log in logs.items()}
    out: dict[str, Any] = {"bars": dict(BARS), "models": list(models), "logs": list(logs), "own": own}
    if all(t is not None for t in truths.values()):
        cells: dict[str, dict[str, Any]] = {name: {} for name in models}
        doubts: dict[str, str] = {}  # a log's recorded heading that points off the way it moves
        total, done = len(models) * len(logs), 0
        for log_name, log in logs.items():
            poses, valid = truths[log_name]
            for model_name, model in models.items():
                sc = score_against_truth(model, log.data, poses, valid)
                cells[model_name][log_name] = fleet_cell(sc)
                if "truth_heading_doubt" in sc:
                    doubts[log_name] = sc["truth_heading_doubt"]
                done += 1
                if progress:
                    progress("scoring models against the truth", done, total)
        out.update(cells=cells, summary=fleet_summary(cells, own))
        if doubts:
            out["truth_heading_doubts"] = doubts
    else:
        out["no_truth"] = [name for name, t in truths.items() if t is None]
    if configs is not None:
        out.update(score_likelihoods(models, logs, configs, own, progress))
    return out


def place(model: Any, data: Any, config: EMConfig) -> Localized | str:
    """One model placed on one log by the E-step alone, or why the filter failed from every start."""
    try:
        return localize(model, data, config)
    except ConfigError as exc:
        return exc.problem


def likelihood_cell(loc: Localized | str) -> dict[str, Any]:
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


def score_likelihoods(
    models: Mapping[str, Any],
    logs: Mapping[str, Any],
    configs: Mapping[str, EMConfig],
    own: Mapping[str, str],
    progress: Callable[[str, int, int | None], None] | None = None,
) -> dict[str, Any]:
    """``{"likelihood": ...}``: each model placed on each log (``likelihood_cell``), and each one's fall per
    sighting below the log's most likely model (``below_best``: 0 for that model); and ``"range"``, each
    placed model scored on each ``RangeLog`` whose range is there at every step (``range_grid``)."""
    cells: dict[str, dict[str, Any]] = {name: {} for name in models}
    ranged = {g: log for g, log in logs.items() if isinstance(log, RangeLog)}
    range_cells: dict[str, dict[str, Any]] = {name: {} for name in models}
    total, done = len(models) * len(logs), 0
    for log_name, log in logs.items():
        for model_name, model in models.items():
            data, range_mm = log.reads[model_name] if log_name in ranged else (log.data, None)
            loc = place(model, data, configs[model_name])
            cells[model_name][log_name] = likelihood_cell(loc)
            if log_name in ranged and log.range_problem is None:
                range_cells[model_name][log_name] = range_cell(loc, data, range_mm)
            done += 1
            if progress:
                progress("placing each model on each log", done, total)
        scored = [cells[m][log_name]["per_sighting"] for m in models if cells[m][log_name]["per_sighting"] is not None]
        best = max(scored) if scored else None
        for model_name in models:
            c = cells[model_name][log_name]
            c["below_best"] = None if c["per_sighting"] is None else best - c["per_sighting"]
    out: dict[str, Any] = {"likelihood": {"cells": cells, "summary": likelihood_summary(cells, list(logs), own)}}
    if ranged:
        out["range"] = range_grid(range_cells, ranged, own)
    return out


def range_cell(loc: Localized | str, data: Any, range_mm: np.ndarray) -> dict[str, Any]:
    """A placed model scored against a Turtlebot CSV's range as `evaluate log` scores it
    (``score_turtlebot_em``): the action gain's error (None on a log that holds one command) and each
    sensor's error in % of its span, with issue 5's two Turtlebot bars (``gain`` None where not scored)."""
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


def range_grid(
    cells: dict[str, dict[str, Any]], ranged: Mapping[str, RangeLog], own: Mapping[str, str]
) -> dict[str, Any]:
    """The pairs scored against the range, the logs they are on (``logs``), the Turtlebot CSVs that could not
    score (``no_range``, with why), and over the robots' own pairs and the others how many clear each bar."""
    scored = [g for g, log in ranged.items() if log.range_problem is None]
    no_range = {g: log.range_problem for g, log in ranged.items() if log.range_problem is not None}
    groups: dict[str, list[dict[str, Any]]] = {"own": [], "other": []}
    for m, row in cells.items():
        for g, c in row.items():
            groups["own" if own.get(m) == g else "other"].append(c)

    def describe(cs: list[dict[str, Any]]) -> dict[str, Any]:
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


def likelihood_summary(cells: dict[str, dict[str, Any]], logs: list[str], own: Mapping[str, str]) -> dict[str, Any]:
    """Per log, the most likely model, and the most likely of the others (a log's own model left out, or
    the runner-up where no model is its own) with its fall; and on how many logs the own model wins."""
    owner = {g: m for m, g in own.items() if m in cells}
    per_log: dict[str, Any] = {}
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


def fleet_summary(cells: dict[str, dict[str, Any]], own: Mapping[str, str]) -> dict[str, Any]:
    """Over the pairs that are a robot's own and those that are not (every pair is "other" when ``own`` is
    empty): how many clear the action bars and the sigma bars, the worst action ratios, and the range
    residual's span."""
    groups: dict[str, list[dict[str, Any]]] = {"own": [], "other": []}
    for model_name, row in cells.items():
        for log_name, c in row.items():
            groups["own" if own.get(model_name) == log_name else "other"].append(c)

    def describe(cs: list[dict[str, Any]]) -> dict[str, Any]:
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
