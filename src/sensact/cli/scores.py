"""What ``learn`` and ``evaluate`` print about a learned model: its parameters and its errors against
the ground truth a log carries (never used for learning); and what ``learn`` warns of in a log."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from sensact.cli.base import console, titled_table
from sensact.records import JsonObject

if TYPE_CHECKING:
    import numpy as np


def print_em_model(m: Any) -> None:
    from sensact.models.wheel_drive import as_differential_drive

    for ch in m.sensor.channels:
        console.print(f"  {ch.name}: " + ch.function.describe("f") + f", sigma = {ch.sigma:.4g}")
    sb = m.sensor.sigma_bearing_rad
    if sb:
        console.print(f"  bearing sigma_2 = {sb:.4g} rad")
    mount = m.sensor.mount
    if m.geometry.has_heading:
        console.print(
            f"  sensor mount: {mount.forward_mm:.1f} mm forward, {mount.left_mm:.1f} mm left, "
            f"yaw {mount.yaw_rad:+.4f} rad"
        )
    console.print("  Sigma_m (sd per step): " + "; ".join(", ".join(f"{x:.4g}" for x in row) for row in m.motion_sd))
    if m.turn_var is not None:
        console.print(f"  heading variance per step grows by {m.turn_var:.4g} rad^2 per rad/s of turning")
    a = m.action
    title, columns, rows = a.table()
    t = titled_table(title)
    for name in columns:
        t.add_column(name)
    for row in rows:
        t.add_row(*row)
    console.print(t)
    if m.geometry.state_is_range:
        console.print(describe_track_velocity(a), markup=False)
    drive = as_differential_drive(a)
    if drive is not None:
        console.print(describe_differential_drive(drive), markup=False)


def describe_track_velocity(a: Any) -> str:
    """A track's learned velocity in words. Sec. 4.4.3's state is the distance to the beacon, which a
    forward velocity shortens, so a robot whose commands take it away from what it ranges to learns a
    negative velocity; chapter 3's learner, whose location grows with its sensor, prints it positive."""
    head = "on a track v_mm_s is the speed toward the wall or beacon the readings range to (sec. 4.4.3)"
    a = a.linear()
    if a is not None and a.basis == "affine" and len(a.command_names) == 1:
        slope = float(a.coefficients[1, 0])
        way = "toward" if slope > 0 else "away from"
        return (
            f"{head}: this robot moves {way} it at {abs(slope):.4g} mm/s per unit of {a.command_names[0]}, "
            "in the learned distance's own scale"
        )
    return f"{head}: a negative v_mm_s takes the robot away from it"


def describe_differential_drive(drive: Any) -> str:
    """``models.wheel_drive.as_differential_drive`` in a sentence."""
    axle, ratio, unit = drive.axle_mm, drive.wheel_ratio, drive.unit
    # turn rate over forward speed, both per unit of the wheels' mean: the heading lost per metre driven straight
    per_metre = 1000.0 * drive.curvature_rad_per_unit / drive.forward_gain if drive.forward_gain else math.nan
    forward = (
        f"forward speed {drive.forward_gain:.4g} times the wheels' mean"
        if unit == "mm_s"
        else f"forward speed {drive.forward_gain:.4g} mm/s per {unit} of the wheels' mean"
        + (" (their mean radius, mm)" if unit == "rad_s" else "")
    )
    return (
        f"as a differential drive: {forward} ({drive.forward_bias_mm_s:+.3g} mm/s), "
        + (
            "a turn rate that does not follow the wheels' difference"
            if axle is None
            else f"turning as on an axle of {axle:.4g} mm"
        )
        + f" ({drive.turn_bias_rad_s:+.3g} rad/s), "
        + ("" if ratio is None else f"the right wheel {ratio:.4g} times the left, ")
        + f"driving straight turning {per_metre:+.3g} rad per metre"
    )


def print_simulated_score(s: JsonObject) -> None:
    """Learned against the model a simulated robot really used (`sensact simulate diffdrive`;
    ``evaluate.simulated_robot.score_against_simulated``)."""
    sd, sd_true = s["motion_sd_per_step"]
    mount = s["sensor_mount"]
    console.print(
        "vs the simulated model (learned / true): "
        f"forward gain {s['forward_gain'][0]:.3f} / {s['forward_gain'][1]:.3f}, "
        f"turn gain {s['turn_gain'][0]:.3f} / {s['turn_gain'][1]:.3f}, "
        + (f"sideways gain {s['sideways_gain'][0]:.3f} / {s['sideways_gain'][1]:.3f}, " if "sideways_gain" in s else "")
        + f"command delay {s['delay_steps'][0]} / {s['delay_steps'][1]} steps "
        f"({s['delay_with_lag_steps']:.1f} with the lag's time constant); "
        f"range sigma {s['range_sigma_mm'][0]:.1f} / {s['range_sigma_mm'][1]:.1f} mm"
        + (
            f", bearing sigma {s['bearing_sigma_rad'][0]:.4f} / {s['bearing_sigma_rad'][1]:.4f} rad"
            if "bearing_sigma_rad" in s
            else ""
        )
        + f"; Sigma_m per step sideways {sd[0]:.2f} / {sd_true[0]:.2f} mm, forward {sd[1]:.2f} / {sd_true[1]:.2f} mm, "
        f"heading {sd[2]:.4f} / {sd_true[2]:.4f} rad; sensor mount "
        + " / ".join(
            f"{m['forward_mm']:.0f} mm forward, {m['left_mm']:.0f} mm left, yaw {m['yaw_rad']:+.4f}" for m in mount
        )
    )


def truth_heading_clause(n: JsonObject) -> str:
    """'; driving straight, the truth's own heading is off by ...': the truth's own heading error
    (``truth_heading_error``) for the truth's-noise line; empty where it could not be measured."""
    from sensact.report.tables_real import truth_heading_cell

    if truth_heading_cell(n) == "-":
        return ""
    e = n["truth_heading_error"]
    return (
        f"; driving straight, the truth's own heading is off by {math.sqrt(max(e['variance_rad2'], 0.0)):.4f} rad "
        f"(sd; {e['share']:.0%} of the frame means' variance), which the truth's residual counts and no learned "
        "sigma can"
    )


def truth_noise_line(sc: JsonObject, *, reads_bearing: bool) -> str:
    """What the truth says about the noise (``score["truth_noise"]``) beside Sigma_m, and for a sensor that
    reads bearings how its residuals share error across a frame and across frames."""
    from sensact.report.tables_real import shared_by_motion

    n = sc["truth_noise"]
    within = n["bearing_within_frame_sd_rad"]
    if within is None or within != within:  # NaN, null in JSON: no frame with two sightings
        frame_split = "no frame has two sightings, so no part shared by a frame can be split off"
    else:
        frame_split = (
            f"a frame's sightings share {n['bearing_frame_shared_fraction']:.0%} of their residual's variance"
            f"{shared_by_motion(n)}, and vary about their frame's mean by {within:.4f} rad"
        )
    return (
        f"truth's noise: heading drift per {sc['window_s']:.2g} s "
        f"{n['heading_drift_rms_at_rest_rad']:.4f} rad at rest (Sigma_m: "
        f"{n['learned_heading_drift_at_rest_rad']:.4f}), "
        f"{n['heading_drift_rms_turning_rad']:.4f} rad turning at {n['turning_rad_s']:.2f} rad/s (Sigma_m: "
        f"{n['learned_heading_drift_turning_rad']:.4f}); "
        f"position missed per {sc['window_s']:.2g} s, sideways / forward "
        f"{n['translation_drift_rms_mm'][0]:.1f} / {n['translation_drift_rms_mm'][1]:.1f} mm (Sigma_m: "
        f"{n['learned_translation_drift_mm'][0]:.1f} / {n['learned_translation_drift_mm'][1]:.1f})"
        + (
            f"; bearing residuals of frames 1-5 windows apart correlate at {n['bearing_frame_correlation']:.2f}; "
            + frame_split
            + truth_heading_clause(n)
            if reads_bearing
            else ""
        )
        + " (docs/em-real.md, Known limits)"
    )


def print_truth_score(sc: JsonObject) -> None:
    import numpy as np

    from sensact.evaluate.bars import BARS, bar_checks
    from sensact.report.tables import bars_sentence

    a, r, b = sc["action"], sc["range"], sc["bearing"]
    bars = bar_checks(sc)

    def mark(*keys: str) -> str:
        return "pass" if all(bars[k] for k in keys) else "[bold red]miss[/]"

    t = titled_table(f"against ground truth ({sc['windows_scored']} windows of {sc['window_s']:.2g} s)")
    for col in ("quantity", "learned", "From-Truth", "ratio", "bar"):
        t.add_column(col)
    la, fa = a["learned"], a["from_truth"]
    t.add_row(
        "translation RMS (mm/s)",
        f"{la['translation_rms_mm_s']:.1f}",
        f"{fa['translation_rms_mm_s']:.1f}",
        f"{a['ratio_translation']:.2f}",
        mark("action_translation_ratio", "action_translation_abs"),
    )
    if a["ratio_rotation"] is not None:  # None: a truth without heading
        t.add_row(
            "rotation RMS (rad/s)",
            f"{la['rotation_rms_rad_s']:.4f}",
            f"{fa['rotation_rms_rad_s']:.4f}",
            f"{a['ratio_rotation']:.2f}",
            mark("action_rotation_ratio"),
        )
    t.add_row("command delay (s)", f"{a['learned_delay_s']:.3f}", f"{a['from_truth_delay_s']:.3f}", "", "")
    t.add_row(
        "range residual RMS (mm)",
        f"{r['learned_residual_rms_mm']:.1f}",
        f"{r['from_truth_residual_rms_mm']:.1f}",
        f"f gap {r['learned_vs_from_truth_rms_mm']:.1f} mm",
        mark("range_function"),
    )
    t.add_row(
        "range sigma (mm)",
        f"{r['sigma_learned_mm']:.1f}",
        f"{r['sigma_truth_mm']:.1f}",
        f"{r['sigma_ratio']:.2f}",
        mark("range_sigma"),
    )
    if b is not None:  # None: a sensor that reads ranges alone
        t.add_row(
            "bearing sigma (rad)",
            f"{b['sigma_learned_rad']:.4f}",
            f"{b['sigma_truth_rad']:.4f}",
            f"{b['sigma_ratio']:.2f} ({b.get('sigma_ratio_truth_heading_removed', np.nan):.2f} without the "
            "truth's heading error)",
            mark("bearing_sigma"),
        )
    console.print(t)
    console.print(f"bar: {bars_sentence(BARS)} (docs/em-real.md)")
    if sc.get("truth_noise"):
        console.print(truth_noise_line(sc, reads_bearing=b is not None))
    m = (sc.get("sensor_mount") or {}).get("fitted_to_truth")
    learned = (sc.get("sensor_mount") or {}).get("learned")
    if learned:
        console.print(
            f"sensor mount learned (from EM's point): {learned['forward_mm']:.0f} mm forward, "
            f"{learned['left_mm']:.0f} mm left, yaw {learned['yaw_rad']:+.4f} rad"
        )
    if m:
        console.print(
            f"sensor pose fitted to the truth (from the truth's point): {m['forward_mm']:.0f} mm forward, "
            f"{m['left_mm']:.0f} mm left, yaw {m['yaw_rad']:+.4f} rad (counterclockwise); "
            f"at the truth's origin instead the bearing residual is {b['truth_origin_sigma_rad']:.4f} rad RMS "
            f"(mean {b['truth_origin_mean_rad']:+.4f}; learned sigma / it {b['truth_origin_sigma_ratio']:.2f})"
        )
    if sc.get("no_heading"):
        console.print(f"[yellow]note:[/] {sc['no_heading']}", highlight=False)
    if sc.get("truth_heading_doubt"):
        console.print(f"[yellow]warning:[/] {sc['truth_heading_doubt']}", highlight=False)
    if "bars" in sc:
        console.print("bars: " + ", ".join(f"{k} {'pass' if v else 'FAIL'}" for k, v in sc["bars"].items()))


def print_scores(scores: Any, log: Any) -> None:
    """A fit's scores against its log's truth (``app.scores``), or why it has none."""
    from sensact.app.scores import RECORDED_POSES, SIMULATED_MODEL, Unscored

    if scores is None:
        if log.no_truth is not None:  # a kind that would be scored, and whose log carries nothing to score with
            console.print(log.no_truth, highlight=False)
        return
    if isinstance(scores, Unscored):
        console.print(scores.reason, highlight=False)
        return
    sc = scores.evaluation
    if scores.against == RECORDED_POSES:
        print_truth_score(sc)
        if "path" in sc:
            p, o = sc["path"], sc["path"]["fitted_offset"] or {"forward_mm": math.nan, "left_mm": math.nan}
            console.print(
                f"smoothed path off the recorded poses: median {p['median_mm']:.0f} mm after the truth's point is "
                f"placed {o['forward_mm']:+.0f} mm forward and {o['left_mm']:+.0f} mm left of EM's (median "
                f"{p['median_raw_mm']:.0f} mm before; metres off means EM lost the robot)"
            )
        if sc.get("map"):
            m = sc["map"]
            console.print(
                f"learned map against the survey: {m['rms_mm']:.0f} mm RMS after the best rigid alignment (no scale); "
                f"{m['landmarks_placed']} of {m['landmarks_total']} landmarks placed"
                + (
                    f", {m['seen_enough_not_placed']} seen 20 times or more not placed"
                    if m["seen_enough_not_placed"]
                    else ""
                )
                + "; the path above is scored in the survey's frame"
            )
        if "simulated" in sc:
            print_simulated_score(sc["simulated"])
    elif scores.against == SIMULATED_MODEL and "vx_rms_mm_s" in sc:
        console.print(
            f"vs truth: v_x {sc['vx_rms_mm_s']:.1f} mm/s, v_y {sc['vy_rms_mm_s']:.1f} mm/s, "
            f"v_theta {sc['vtheta_rms_rad_s']:.3f} rad/s RMS; sigma_1 {sc['sigma1_error_pct']:.1f} % off, "
            f"sigma_2 {sc['sigma2_error_pct']:.1f} % off; f {sc['sensor_rms_px']:.2f} px RMS"
        )
    elif scores.against == SIMULATED_MODEL:
        console.print(
            f"vs truth (optimal scale): sensor {sc['sensor_rms_px']:.2f} px ({sc['sensor_rms_pct']:.2f} %), "
            f"action {sc['action_rms_mm_s']:.1f} mm/s ({sc['action_rms_pct']:.2f} %), "
            f"scale ratio {sc['scale_ratio']:.3f}"
        )
    else:
        print_range_score(sc, scores.against)


def range_column_scoreable(truth_mm: Any, absent: str | None) -> bool:
    """Whether the range column can score a fit (``evaluate.turtlebot_em.range_column_problem``); says why
    not: ``absent`` when there is no column (None: say nothing), and how many steps are empty otherwise."""
    from sensact.evaluate.turtlebot_em import NO_RANGE_COLUMN, range_column_problem

    problem = range_column_problem(truth_mm)
    if problem == NO_RANGE_COLUMN:
        if absent:
            console.print(absent)
    elif problem:
        console.print(f"{problem}: not scored.")
    return problem is None


def print_range_score(sc: JsonObject, against: str) -> None:
    """A 1-D fit's scaled gain and sensor errors against a recorded distance (``against`` names it)."""
    from sensact.report.tables import gain_cell, one_command_reason, sensor_span_cell

    gain = gain_cell(
        sc["gain_learned"], sc["gain_true"], sc["gain_error_pct"], one_command_reason(sc["one_command_share"])
    )
    console.print(f"vs {against} (optimal scale and offset): action gain {gain}; command delay {sc['delay_s']:.2f} s")
    for name, s in sc["sensors"].items():
        console.print(f"  {name}: {sensor_span_cell(s)}")


def halves_rows(cmp: JsonObject, fits: list[Any], data: Any) -> list[list[str]]:
    """The rows of `learn em --halves`'s table (``evaluate/halves.compare_halves``) on the whole log
    ``data``: each half's difference from the whole log's model and the halves' from each other."""

    def velocity(d: dict[str, float]) -> str:
        if "translation_mm_s" in d:
            return f"{d['translation_mm_s']:.2f} mm/s, {d['rotation_rad_s']:.4f} rad/s"
        return f"{d['velocity_mm_s']:.2f} mm/s"

    v, f, n, delay = cmp["velocity"], cmp["f"], cmp["noise"], cmp["delay_s"]
    rows = [
        ["steps (sightings)"]
        + [f"{b - a} ({h.data.n_observations})" for h in fits for a, b in [h.steps]]
        + [f"{data.n_steps} ({data.n_observations})", ""],
        ["EM iterations, the most likely at"]
        + [f"{h.result.iterations}, {h.result.best_iteration} ({h.result.seconds:.1f} s)" for h in fits]
        + ["", ""],
        [
            "velocities against the whole's, RMS over its commands",
            velocity(v["first_vs_whole"]),
            velocity(v["second_vs_whole"]),
            "",
            velocity(v["first_vs_second"]),
        ],
    ]
    for name, (lo, hi) in f["spans"].items():
        rows.append(
            [f"{name} f against the whole's, RMS over {lo:.0f}-{hi:.0f} mm"]
            + [f"{f[k][name]:.4g}" for k in ("first_vs_whole", "second_vs_whole")]
            + ["", f"{f['first_vs_second'][name]:.4g}"]
        )
    for key, value in n["whole"].items():
        ratio = n["halves_ratio"].get(key)
        rows.append(
            [
                key,
                f"{n['first'][key]:.4g}",
                f"{n['second'][key]:.4g}",
                f"{value:.4g}",
                f"x {ratio:.2f}" if ratio is not None else "-",
            ]
        )
    if delay["whole"] is not None:
        rows.append(
            ["command delay, s"]
            + [f"{delay[k]:.3f}" for k in ("first", "second", "whole")]
            + [f"{abs(delay['first'] - delay['second']):.3f}"]
        )
    return rows


def warn_if_one_command(commands: np.ndarray, source: str, name: str, unit: str = "") -> None:
    """Say so when a 1-D log spends nearly all its steps at one command (``evaluate.measured.one_command_doubt``)."""
    from sensact.evaluate.measured import one_command_doubt

    doubt = one_command_doubt(commands, source, name, unit)
    if doubt is not None:
        console.print(f"[yellow]warning:[/] {doubt}", highlight=False)
