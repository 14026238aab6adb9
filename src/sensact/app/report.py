"""``report.html`` beside a calibration's model: the page a person reads to decide whether to trust it.
EM's (`learn em`): convergence, each sensor's learned function over its readings, the path (over the truth
when the log has one), the residuals' histograms and autocorrelation, the learned action model against
the commands in SI, the sensor's mount, and every flag and warning of the fit. Chapter 3's and chapter
5's learners get their own figure, numbers and warnings (``simple_report``)."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from sensact.app.em import Calibration
from sensact.app.scores import Scores, Unscored
from sensact.records import JsonObject
from sensact.report.frames import MM, si, velocity_rep
from sensact.report.page import Section, report_path, write_report


def _num(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int | float):
        return f"{x + 0.0:.{digits}g}" if math.isfinite(x) else str(x)  # + 0.0: no "-0"
    return str(x)


def _flags(cal: Calibration, doc: JsonObject) -> tuple[str, ...]:
    res = cal.result
    flags = list(cal.diagnostics.warnings)
    if res.stop_reason != "converged":
        flags.append(f"EM stopped: {res.stop_reason} (not converged)")
    for key in ("range_function_turns", "range_function_bends"):
        for sign in doc.get(key) or []:
            flags.append(f"{key.replace('_', ' ')}: {sign}")
    if doc.get("em_unsettled"):
        flags.append(f"EM unsettled: {doc['em_unsettled']}")
    if isinstance(cal.scores, Unscored):
        flags.append(f"not scored against the log's truth: {cal.scores.reason}")
    if isinstance(cal.scores, Scores):
        missed = [k for k, ok in cal.scores.bars.items() if not ok]
        if missed:
            flags.append("bars missed against the truth: " + ", ".join(missed))
    return tuple(dict.fromkeys(flags))


def _action_table(cal: Calibration) -> tuple[tuple[str, ...], tuple[tuple[str, ...], ...]]:
    from sensact.app.export import action_model_si

    act = action_model_si(cal.model.action, cal.log.data.dt_s)
    if "velocities" not in act:
        return ("action model",), ((str(act.get("note", "")),),)
    features = list(dict.fromkeys(f for terms in act["velocities"].values() for f in terms))
    rows = tuple((v, *(_num(terms.get(f), 5) for f in features)) for v, terms in act["velocities"].items())
    return ("velocity (REP 103, SI)", *features), rows


def _mount_rows(cal: Calibration) -> tuple[tuple[str, ...], ...]:
    m = cal.model.sensor.mount.to_dict()
    rows = [("learned by EM", _num(m["forward_mm"] / 1000), _num(m["left_mm"] / 1000), _num(m["yaw_rad"]))]
    meta = cal.log.folder.meta if cal.log.folder is not None else {}
    tf = (meta.get("source") or {}).get("tf_static_mount") if isinstance(meta.get("source"), dict) else None
    if tf:
        rows.append(
            ("/tf_static (the bag's)", _num(tf["x_m"]), _num(tf["y_m"]), f"{_num(tf['yaw_rad_applied'])} (applied)")
        )
    ev = cal.scores.evaluation if isinstance(cal.scores, Scores) else {}
    fitted = (ev.get("sensor_mount") or {}).get("fitted_to_truth") if isinstance(ev.get("sensor_mount"), dict) else None
    if fitted:
        rows.append(
            (
                "fitted to the truth",
                _num(fitted.get("forward_mm", math.nan) / 1000),
                _num(fitted.get("left_mm", math.nan) / 1000),
                _num(fitted.get("yaw_rad")),
            )
        )
    return tuple(rows)


def si_parameter(name: str) -> tuple[str, float]:
    """An error bar's parameter (``learn/em/uses/error_bars.model_parameters``'s name, sensact's frame and mm) in
    REP 103 and SI, as the page's other tables, and the factor from its value to the shown one (a standard
    deviation's is taken without its sign)."""
    if m := re.fullmatch(r"action\.(\w+)\[(.*)\]", name):
        (v, kv), feats = velocity_rep(m[1]), [si(f) for f in m[2].split("*") if f != "1"]
        return f"action.{v}[{'*'.join(n for n, _ in feats) or 'constant'}]", kv / math.prod(k for _, k in feats)
    if m := re.fullmatch(r"(action\[\d+\]|Sigma_m\[\d+\])\.(\w+)", name):
        v, kv = velocity_rep(m[2])
        return f"{m[1]}.{v}", kv if m[1].startswith("action") else abs(kv)
    if m := re.fullmatch(r"f\.(\w+)\(([^ ]+) mm\)", name):
        channel, k = si(m[1])
        return f"f.{channel}({float(m[2]) * MM:g} m)", k
    if m := re.fullmatch(r"f\.(\w+)\.(bearing_term\d+)", name):  # d g(b) in the reading's unit, d in m
        channel, k = si(m[1])
        return f"f.{channel}.{m[2]}", k / MM
    head, _, tail = name.rpartition(".")
    shown, k = si(tail)
    return (f"{head}.{shown}" if head else shown), k


def _interval_si(interval: Any, open_ended: Any, k: float) -> str:
    """An interval in SI (``k`` may turn it over); an end the log gives no bound for is said so."""
    ends = [None if v is None else v * k for v in interval]
    opened = list(open_ended)
    if k < 0:
        ends, opened = ends[::-1], opened[::-1]
    text = [
        ("no bound" if v is None else _num(v, 5)) + (" (open)" if v is not None and o else "")
        for v, o in zip(ends, opened, strict=True)
    ]
    return f"{text[0]} to {text[1]}"


def _error_bars(u: Any) -> Section:
    """`--uncertainty`'s table: each parameter (REP 103, SI) with its standard error and interval."""
    rows = []
    for p in u.parameters:
        name, k = si_parameter(p.name)
        rows.append(
            (
                name,
                _num(p.value * k, 5),
                "held" if p.held else ("unbounded" if p.se is None else _num(p.se * abs(k), 3)),
                "-" if p.interval is None else _interval_si(p.interval, p.open_ended, k),
            )
        )
    rows = tuple(rows)
    where = (
        f"f is read at {', '.join(f'{d * MM:g}' for d in u.f_at_mm)} m, the 10th, 50th and 90th percentiles of the "
        "sightings' distances. A parameter the fit holds has none."
    )
    if u.method == "observed information":
        lead = (
            "From the likelihood itself: the action model's, f's and the mount's intervals from its curvature at the "
            "fit (the observed information), the noise's (sigma, Sigma_m) from their profiles on the log scale, "
            "open where the log gives no bound. " + where
        )
    else:
        failed = f"; {len(u.failed)} failed: {u.failed[0]}" if u.failed else ""
        lead = (
            f"A parametric bootstrap: {u.replicates} logs drawn from the learned model with this log's commands, "
            f"map and sighting times, each learned again from it ({u.used} learned{failed}). The standard error is "
            "the replicates' spread; the 90 % interval is centred on the value less the replicates' bias. " + where
        )
    return Section(
        "Error bars",
        paragraphs=(lead + " Values in REP 103 axes and SI units, as the exports give them.",),
        table=(("parameter", "value", "standard error", "90 % interval"), rows),
    )


def _learned_map(cal: Calibration, out: Path) -> Path:
    from sensact.evaluate.map_truth import rigid_alignment
    from sensact.report.figures_calibration import figure_landmark_map

    learned, data, post = cal.model.landmarks, cal.log.data, cal.result.posteriors
    survey = cal.log.folder.survey_xy if cal.log.folder is not None else None
    alignment = None if survey is None else rigid_alignment(learned.placed_xy(), survey)
    names = data.landmark_names or tuple(str(j) for j in range(len(learned.xy)))
    path = None if post is None else post.mean_gamma[:, :2]
    return figure_landmark_map(learned, names, path, survey, alignment, out, f"the landmark map of {cal.log.name}")


def write_em_report(cal: Calibration, model_path: Path, figures: Sequence[Path]) -> tuple[Path, list[Path]]:
    """The calibration's page beside ``model_path``, and the figures of its own it drew there (OUT_residuals,
    OUT_commands and, against a truth, OUT_path); ``figures`` are those already written (OUT.png and the
    figures against the truth)."""
    from sensact.report.figures_calibration import figure_actions, figure_path_over_truth, figure_residuals

    res, data, doc = cal.result, cal.log.data, cal.to_json()
    stem = model_path.with_suffix("")
    by_kind = {p.stem.removeprefix(stem.name).lstrip("_") or "fit": p for p in figures if p.suffix == ".png"}
    summary = res.summary()
    overview = (
        ("log", str(data.source)),
        ("preset", str(cal.settings.preset)),
        ("steps", f"{data.n_steps} of {_num(data.dt_s)} s ({_num(data.n_steps * data.dt_s, 5)} s)"),
        ("sightings", str(data.n_observations)),
        ("EM", f"{summary.get('iterations', '-')} iterations, {res.stop_reason}, best at {res.best_iteration}"),
        ("log-likelihood", _num(res.loglik_best, 8)),
        ("pruned by the gates", f"{100 * cal.diagnostics.pruned_fraction:.1f} %"),
        (
            "residuals' lag-1 autocorrelation",
            ", ".join(f"{si(k)[0]} {_num(v, 2)}" for k, v in cal.diagnostics.residual_lag1_autocorrelation.items()),
        ),
    )
    consistency = tuple(
        (name, f"{100 * r.coverage90:.1f} %", _num(r.nis_mean, 3), str(r.n))
        for name, r in cal.consistency.readings.items()
    )
    drawn: list[Path] = []
    sections = [
        Section("Summary", table=(("quantity", "value"), overview)),
        Section("Flags and warnings", flags=_flags(cal, doc), flag_list=True),
        Section(
            "Consistency: are the sigmas honest?",
            paragraphs=(
                "The filter's one-step-ahead innovations, each in the model's predictive law: an honest sigma "
                "holds 90 % of the readings in its 90 % interval, with a mean normalized innovation squared of 1. "
                "On this log the model was learned on; `sensact evaluate log` and `localize` give them on the next.",
            ),
            table=(("reading", "inside the 90 % interval", "NIS mean", "readings"), consistency),
        ),
    ]
    if res.posteriors is not None:
        sections.append(
            Section(
                "Convergence, the sensor functions and the path",
                paragraphs=("From the fit alone: no truth is used.",),
                figures=(
                    (by_kind["fit"], "log-likelihood per iteration; each channel's f over its readings; the path"),
                )
                if "fit" in by_kind
                else (),
            )
        )
        resid = figure_residuals(res, data, Path(f"{stem}_residuals.png"), "residuals about the smoothed path")
        acts = figure_actions(res, data, Path(f"{stem}_commands.png"), "the learned action model against the commands")
        drawn += [resid, acts]
        sections.append(
            Section(
                "Residuals",
                paragraphs=(
                    "Each reading's residual about the smoothed path over its learned sigma: a fit whose noise "
                    "model holds scatters as that model (N(0, 1), or a robust reading's Student-t), and "
                    "independent errors keep the autocorrelation in the band.",
                ),
                figures=((resid, "histograms and autocorrelation"),),
            )
        )
        sections.append(
            Section(
                "Action model",
                paragraphs=(f"Command delay {_num(getattr(cal.model.action, 'delay_steps', 0) * data.dt_s)} s.",),
                table=_action_table(cal),
                figures=((acts, "velocities over 1 s windows: the smoothed path's and A(c)'s"),),
            )
        )
    sections.append(Section("Sensor mount", table=(("", "x forward (m)", "y left (m)", "yaw (rad)"), _mount_rows(cal))))
    if cal.model.landmarks is not None:
        drawn.append(_learned_map(cal, Path(f"{stem}_map.png")))
        sections.append(
            Section(
                "Landmark map (learned)",
                paragraphs=(str(doc["map"]["frame"]),),
                figures=((drawn[-1], "the learned map with 2-sd ellipses, over the survey when the log has one"),),
            )
        )
    if cal.uncertainty is not None:
        sections.append(_error_bars(cal.uncertainty))
    if isinstance(cal.scores, Scores):
        ev = cal.scores.evaluation
        rows = tuple((k, "pass" if ok else "MISSED") for k, ok in cal.scores.bars.items())
        figs = []
        folder, posteriors = cal.in_truth_frame  # on a learned map: its survey, the path aligned to it
        truth = folder.truth_poses() if folder is not None else None
        if posteriors is not None and truth is not None:
            on_truth = replace(res, posteriors=posteriors)
            drawn.append(figure_path_over_truth(on_truth, folder.data, *truth, Path(f"{stem}_path.png"), "path"))
            figs.append((drawn[-1], "EM's path over the truth's"))
        figs += [
            (by_kind[k], k.replace("_", " "))
            for k in ("actions", "range", "heading_noise", "bearing", "against_range")
            if k in by_kind
        ]
        path_mm = (ev.get("path") or {}).get("median_mm") if isinstance(ev.get("path"), dict) else None
        sections.append(
            Section(
                f"Against {cal.scores.against} (never learned from)",
                paragraphs=(f"Path median off the truth: {_num(path_mm * MM)} m.",) if path_mm is not None else (),
                table=(("bar", "result"), rows) if rows else None,
                figures=tuple(figs),
            )
        )
    page = write_report(
        report_path(model_path),
        f"sensact calibration: {cal.log.name}",
        f"EM (ch. 4) on {data.source}; the model is {model_path.name}.",
        sections,
    )
    return page, drawn


def simple_report(
    model_path: Path,
    title: str,
    lead: str,
    numbers: JsonObject,
    warnings: Sequence[str],
    figures: Sequence[tuple[Path, str]],
) -> Path:
    """A learner's page with its numbers, its warnings and its figures (chapters 3 and 5)."""
    rows = tuple((k, _num(v)) for k, v in numbers.items())
    return write_report(
        report_path(model_path),
        title,
        lead,
        [
            Section("Summary", table=(("quantity", "value"), rows)),
            Section("Flags and warnings", flags=tuple(warnings), flag_list=True),
            Section("Figures", figures=tuple(figures)),
        ],
    )
