"""A fleet's models, each scored on every robot's log (beyond the thesis, whose robots had one log
each): does one robot's learned model serve another robot of its kind?

Each pair is ``score_against_truth`` of the model on the log, with From-Truth fitted on that log, and
the real-data bars (``real.bar_checks``). A pair is the robot's *own* when the model was learned on that
log. MRCLAM's five robots are one kind of robot: their action models carry over, their cameras' range
functions do not (docs/em-real-results.md, "One robot's model on another robot").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from sensact.evaluate.landmark_truth import score_against_truth
from sensact.experiments.real import BARS, bar_checks

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
        "bars": bar_checks(sc),
    }


def score_fleet(
    models: Mapping[str, Any],
    logs: Mapping[str, Any],
    own: Mapping[str, str] | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
) -> dict[str, Any]:
    """Every model of ``models`` ({name: EMModel}) on every log of ``logs`` ({name: anything with ``data``
    and ``truth_poses()``}: an ``MrclamLog`` or a log folder with groundtruth.csv). ``own`` maps a model's
    name to the log it was learned on. Cells are keyed ``cells[model][log]``."""
    own = dict(own or {})
    cells: dict[str, dict[str, Any]] = {name: {} for name in models}
    total, done = len(models) * len(logs), 0
    for log_name, log in logs.items():
        poses, valid = log.truth_poses()
        for model_name, model in models.items():
            cells[model_name][log_name] = fleet_cell(score_against_truth(model, log.data, poses, valid))
            done += 1
            if progress:
                progress("scoring models on logs", done, total)
    return {
        "bars": dict(BARS),
        "models": list(models),
        "logs": list(logs),
        "own": own,
        "cells": cells,
        "summary": fleet_summary(cells, own),
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
