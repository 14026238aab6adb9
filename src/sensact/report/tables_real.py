"""The real robots' tables (docs/em-real.md): MRCLAM's robots against Vicon and the simulated differential drive
against its truth, each learned model beside From-Truth, with the cells the console's scores share."""

from __future__ import annotations

import math
from pathlib import Path

from sensact.records import JsonObject
from sensact.report.tables import Table, gain_cell, one_command_reason, sensor_span_cell
from sensact.report.tables_fleet import (
    FLEET_LIKELIHOOD_TITLE,
    FLEET_TITLE,
    fleet_likelihood_table,
    fleet_table,
)


def _drift_cell(n: JsonObject, when: str) -> str:
    learned = n.get(f"learned_heading_drift_{when}_rad")
    truth = f"{n[f'heading_drift_rms_{when}_rad']:.4f}"
    return truth if learned is None else f"{truth} / {learned:.4f}"


def _mount_cell(score: JsonObject) -> str:
    m, b = (score.get("sensor_mount") or {}).get("fitted_to_truth"), score["bearing"]
    if m is None or b is None:  # results written before the sensor's pose was fitted, or no bearings to fit it by
        return "-"
    return (
        f"{m['forward_mm']:.0f} / {-m['left_mm']:.0f} / {m['yaw_rad']:+.4f}; "
        f"{b['truth_origin_sigma_rad']:.4f} ({b['truth_origin_sigma_ratio']:.2f})"
    )


def shared_by_motion(n: JsonObject) -> str:
    """' (still 0%, straight 49%, turning 75%)': the truth's frame-shared bearing variance by the
    robot's motion, '-' where no frame could be split; empty for results written before it."""
    split = n.get("bearing_frame_shared_by_motion")
    if not split:
        return ""
    parts = [
        f"{name} {'-' if math.isnan(v['shared_fraction']) else format(v['shared_fraction'], '.0%')}"
        for name, v in split.items()
    ]
    return " (" + ", ".join(parts) + ")"


def translation_drift_cell(n: JsonObject) -> str:
    """'7.1 / 7.6; 16.5 / 15.7': the truth's sideways / forward miss per window, RMS mm, then the
    learned Sigma_m's; '-' for results written before they were measured."""
    truth, learned = n.get("translation_drift_rms_mm"), n.get("learned_translation_drift_mm")
    if truth is None or learned is None:
        return "-"
    return f"{truth[0]:.1f} / {truth[1]:.1f}; {learned[0]:.1f} / {learned[1]:.1f}"


def truth_heading_cell(n: JsonObject) -> str:
    """'0.0063 (51%)': the truth's own heading error on straight stretches, sd rad, and its share of the
    frame means' bearing residual variance; '-' where too few frames or for results written before it."""
    e = n.get("truth_heading_error") or {}
    var = e.get("variance_rad2")
    if var is None or var != var:  # NaN, null once written to JSON
        return "-"
    return f"{math.sqrt(max(var, 0.0)):.4f} ({e['share']:.0%})"


def _shared_cell(n: JsonObject) -> str:
    if "bearing_within_frame_sd_rad" not in n:
        return "-"
    return f"{n['bearing_within_frame_sd_rad']:.4f}; {n['bearing_frame_shared_fraction']:.0%}{shared_by_motion(n)}"


def _failed_bars(score: JsonObject) -> str:
    return ", ".join(k for k, v in score["bars"].items() if not v) or "all pass"


def _path_cell(score: JsonObject) -> str:
    p = score.get("path")
    return "-" if not p else f"{p['median_mm']:.0f} ({p['forward_median_mm']:+.0f})"


def _ridge_cell(em: JsonObject) -> str:
    # the moves only: the first search's likelihood is the held stage's, the others the freed one's
    return ", ".join(f"{r['shift_mm']:+.0f}" for r in em.get("ridge") or []) or "-"


def _delay_cell(action: JsonObject, em: JsonObject) -> str:
    cell = f"{action['learned_delay_s']:.3f} / {action['from_truth_delay_s']:.3f}"
    moves = [
        f"{s['delay_from']}->{s['delay_to']}" for s in em.get("delay_search") or [] if s["delay_to"] != s["delay_from"]
    ]
    return f"{cell} (searches moved it {', '.join(moves)} steps)" if moves else cell


def _mrclam_title(res: JsonObject) -> str:
    """'MRCLAM Dataset 6', or the names of the datasets the run found."""
    names = [Path(d).name.replace("MRCLAM_", "").replace("Dataset", "Dataset ") for d in res.get("mrclam_datasets", [])]
    return "MRCLAM " + (", ".join(names) if names else "Dataset 6")


def truth_score_headers(who: str, truth: str) -> list[str]:
    """The columns of ``_truth_score_row``; ``truth`` names the recorded poses (Vicon, or the simulated ones)."""
    return [
        who,
        "translation RMS mm/s",
        "rotation RMS rad/s",
        "command delay s, learned / From-Truth",
        "range residual RMS mm",
        "range sigma mm",
        "bearing sigma rad",
        f"path off {truth} mm, median (forward)",
        "ridge moves mm, forward (the first as the held stage ends)",
        "sightings pruned of all (of them when the robust readings took over)",
        "bars failed",
    ]


def _truth_score_row(name: str, score: JsonObject, em: JsonObject) -> list[str]:
    """One robot's ``score_against_truth``, learned / From-Truth (ratio), with the bars it failed."""
    a, rg, b = score["action"], score["range"], score["bearing"]
    la, fa = a["learned"], a["from_truth"]
    return [
        name,
        f"{la['translation_rms_mm_s']:.1f} / {fa['translation_rms_mm_s']:.1f} ({a['ratio_translation']:.2f})",
        f"{la['rotation_rms_rad_s']:.4f} / {fa['rotation_rms_rad_s']:.4f} ({a['ratio_rotation']:.2f})",
        _delay_cell(a, em),
        f"{rg['learned_residual_rms_mm']:.0f} / {rg['from_truth_residual_rms_mm']:.0f}",
        f"{rg['sigma_learned_mm']:.0f} / {rg['sigma_truth_mm']:.0f} ({rg['sigma_ratio']:.2f})",
        "-" if b is None else f"{b['sigma_learned_rad']:.4f} / {b['sigma_truth_rad']:.4f} ({b['sigma_ratio']:.2f})",
        _path_cell(score),
        _ridge_cell(em),
        f"{em['n_pruned']} of {em['n_observations']} ({em.get('n_pruned_when_freed', 0)})",
        _failed_bars(score),
    ]


def _sim_bearing_cell(s: JsonObject) -> str:
    """The learned bearing sigma / the simulated one (ratio); "-" for a range-only sensor."""
    if "bearing_sigma_rad" not in s:
        return "-"
    learned, true = s["bearing_sigma_rad"]
    return f"{learned:.4f} / {true:.4f} ({s['bearing_sigma_ratio']:.2f})"


def diffdrive_tables(res: JsonObject) -> list[Table]:
    """Simulated differential drives (or side-stepping robots): the MRCLAM table against their true poses,
    then the learned model against the one the simulator used."""
    seeds = res["seeds"]
    rows = [_truth_score_row(name, r["score"], r["em"]) for name, r in seeds.items()]
    sideways = any("sideways_gain" in r["simulated"] for r in seeds.values())  # a robot that side-steps
    sim_rows = []
    for name, r in seeds.items():
        s = r["simulated"]
        sd, sd_true = s["motion_sd_per_step"]
        side = s.get("sideways_gain")
        sim_rows.append(
            [
                name,
                f"{s['forward_gain'][0]:.3f} / {s['forward_gain'][1]:.3f}",
                f"{s['forward_bias_mm_s'][0]:.1f} / {s['forward_bias_mm_s'][1]:.1f}",
                f"{s['turn_gain'][0]:.3f} / {s['turn_gain'][1]:.3f}",
                *([f"{side[0]:.3f} / {side[1]:.3f}" if side else "-"] if sideways else []),
                f"{s['delay_steps'][0]} / {s['delay_steps'][1]} ({s['delay_with_lag_steps']:.1f})",
                f"{s['range_sigma_mm'][0]:.1f} / {s['range_sigma_mm'][1]:.1f} ({s['range_sigma_ratio']:.2f})",
                _sim_bearing_cell(s),
                ", ".join(f"{a:.3g} / {b:.3g}" for a, b in zip(sd, sd_true, strict=True)),
                f"{r['em']['iterations']} ({r['em']['seconds']:.1f} s)",
            ]
        )
    robots = "side-stepping robots" if res["config"]["simulator"].get("sidestep_mm_s", 0) > 0 else "differential drives"
    return [
        (
            f"Simulated {robots}, MRCLAM's EM settings: learned / From-Truth (ratio)",
            truth_score_headers("seed", "the true poses"),
            rows,
        ),
        (
            "The learned model / the simulated one (ratio)",
            [
                "seed",
                "forward gain",
                "forward bias mm/s",
                "turn gain",
                *(["sideways gain"] if sideways else []),
                "command delay steps (with the lag's time constant)",
                "range sigma mm",
                "bearing sigma rad",
                "Sigma_m sd per step: sideways mm, forward mm, heading rad",
                "EM iterations",
            ],
            sim_rows,
        ),
    ]


def restart_runs_cell(runs: list[JsonObject]) -> str:
    """Each run of ``fit.restart_while_lost``: its channels' start sigmas and its likelihood."""
    return "; ".join(
        ", ".join(f"{name} {s:.4g}" for name, s in r["start_sigma"].items())
        + f": {r['loglik']:.1f}"
        + (f" ({_lost_signs(r['f_turns'])})" if r["f_turns"] else "")
        for r in runs
    )


def _lost_signs(signs: list[JsonObject]) -> str:
    """``f turned``, ``f bent``, ``f turned and bent``, ``EM unsettled`` or one of the first three and it,
    for a run's ``checks/lost_signs.lost_fit_signs``."""
    kinds = {t["sign"] for t in signs}
    f = [word for sign, word in (("turns", "turned"), ("bends", "bent")) if sign in kinds]
    return "; ".join(([f"f {' and '.join(f)}"] if f else []) + (["EM unsettled"] if "unsettled" in kinds else []))


def kept_run_cell(runs: list[JsonObject]) -> str:
    """Which run ``fit.restart_while_lost`` kept."""
    k = next(i for i, r in enumerate(runs) if r["kept"])
    return "the first run" if k == 0 else f"restart {k}"


def real_tables(res: JsonObject) -> list[Table]:
    """MRCLAM robots (learned against From-Truth) and the Turtlebot (EM beside chapter 3)."""
    tables: list[Table] = []
    title = _mrclam_title(res)
    mrclam = res.get("mrclam", {})
    rows = [_truth_score_row(name, r["score"], r["em"]) for name, r in mrclam.items()]
    if rows:
        tables.append((f"{title}: learned / From-Truth (ratio)", truth_score_headers("robot", "Vicon"), rows))
    restarts = [(name, r, r["truth_restart"]) for name, r in mrclam.items() if "truth_restart" in r]
    if restarts:
        tables.append(_truth_restart_table(title, restarts))
    noise = [(name, r["score"].get("truth_noise")) for name, r in mrclam.items()]
    if any(n for _, n in noise):
        tables.append(_truth_noise_table(title, [(name, n, mrclam[name]["score"]) for name, n in noise if n]))
    for dataset, fleet in res.get("fleet", {}).items():
        tables.append(fleet_table(fleet, f"{dataset}, each robot's model on every robot's log: {FLEET_TITLE}"))
        if "likelihood" in fleet:  # absent from results written before the likelihood was measured
            tables.append(fleet_likelihood_table(fleet, f"{dataset}: {FLEET_LIKELIHOOD_TITLE}"))
    turtlebots = [res["turtlebot"], *res.get("turtlebot_more_logs", {}).values()] if res.get("turtlebot") else []
    tables += [_turtlebot_table(tb) for tb in turtlebots]  # the training1.csv, then any other training log
    restarted = [(name, r["em"]["restarts"]) for name, r in mrclam.items() if r["em"].get("restarts")]
    if restarted:
        tables.append(
            (
                f"{title}: EM started again because the fit looked lost (learn/em/checks/lost_signs.py)",
                ["robot", "start sigma: log-likelihood on the sightings all runs kept", "kept"],
                [[name, restart_runs_cell(runs), kept_run_cell(runs)] for name, runs in restarted],
            )
        )
    skipped = [line.partition(": ") for line in res.get("skipped", [])]
    if skipped:
        tables.append(("Not run", ["what", "why"], [[what, why] for what, _, why in skipped]))
    return tables


def _truth_restart_table(title: str, restarts: list[tuple[str, JsonObject, JsonObject]]) -> Table:
    """Each robot from the poor start beside EM run again from the truth's range function and start pose."""
    return (
        f"{title}: poor start / EM again from the truth's range function and start pose "
        "(a higher likelihood after the restart means the poor start stopped in a local optimum)",
        [
            "robot",
            "log-likelihood",
            "path off Vicon mm, median (forward)",
            "range f to From-Truth's, RMS mm",
            "bearing sigma ratio",
            "bars failed after the restart",
        ],
        [
            [
                name,
                f"{t['loglik_poor_start']:.1f} / {t['loglik_best']:.1f}"
                + ("" if t["sightings_used"] == t["sightings_used_poor_start"] else " (other sightings)"),
                f"{_path_cell(r['score'])} / {_path_cell(t['score'])}",
                f"{r['score']['range']['learned_vs_from_truth_rms_mm']:.0f} / "
                f"{t['score']['range']['learned_vs_from_truth_rms_mm']:.0f}",
                f"{r['score']['bearing']['sigma_ratio']:.2f} / {t['score']['bearing']['sigma_ratio']:.2f}",
                _failed_bars(t["score"]),
            ]
            for name, r, t in restarts
        ],
    )


def _truth_noise_table(title: str, noise: list[tuple[str, JsonObject, JsonObject]]) -> Table:
    """What the truth says about each robot's noise: (robot, its truth_noise, its score)."""
    return (
        f"{title}: what the truth says about the noise (see docs/em-real.md, Known limits)",
        [
            "robot",
            "heading drift per 1 s at rest rad, truth / Sigma_m",
            "while turning (90th percentile), truth / Sigma_m",
            "turn rate rad/s",
            "sideways / forward miss per 1 s mm, truth; Sigma_m",
            "bearing residual correlation, frames 1-5 s apart",
            "bearing residual about its frame's mean, sd rad; frame-shared variance (by motion)",
            "the truth's own heading error driving straight, sd rad (share of the frame means' variance)",
            "sensor on the robot, forward mm / right mm / yaw rad; "
            "bearing residual at the truth's origin rad (learned sigma / it)",
        ],
        [
            [
                name,
                _drift_cell(n, "at_rest"),
                _drift_cell(n, "turning"),
                f"{n['turning_rad_s']:.3f}",
                translation_drift_cell(n),
                f"{n['bearing_frame_correlation']:.2f}",
                _shared_cell(n),
                truth_heading_cell(n),
                _mount_cell(score),
            ]
            for name, n, score in noise
        ],
    )


def _turtlebot_table(tb: JsonObject) -> Table:
    """One Turtlebot training log: EM in 1-D beside chapter 3's learner on sonar1."""
    sc, ch3 = tb["score"], tb.get("chapter3_sonar1", {})
    share = sc.get("one_command_share", 0.0)  # absent from results written before it was measured
    rows = [
        [
            "action gain (after the optimal scale)",
            gain_cell(sc["gain_learned"], sc["gain_true"], sc["gain_error_pct"], one_command_reason(share)),
            gain_cell(ch3["learned_gain"], None, ch3["gain_error_pct"]) if ch3 else "-",
        ],
        ["learned command delay", f"{sc['delay_s']:.3f} s", "-"],
    ]
    for name, s in sc["sensors"].items():
        c3 = f"{ch3['sensor_rms_pct']:.2f} %" if name == "sonar1" and ch3 else "-"
        rows.append([f"{name} error, % of its span", sensor_span_cell(s), c3])
    return (
        f"Turtlebot {Path(tb['file']).name}: EM in 1-D against the chapter-3 learner",
        ["quantity", "EM", "chapter 3"],
        rows,
    )
