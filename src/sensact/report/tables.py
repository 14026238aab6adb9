"""Result tables with the thesis's numbers beside ours, as plain rows (rendered by Markdown or rich)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sensact.evaluate.bars import checks_from_json, counts

Table = tuple[str, list[str], list[list[str]]]  # title, headers, rows


def _pm(mean: float | None, std: float | None, digits: int = 1) -> str:
    if mean is None or mean != mean:
        return "-"
    return f"{mean:.{digits}f} ± {std:.{digits}f}" if std is not None and std == std else f"{mean:.{digits}f}"


def track1d_tables(res: dict[str, Any]) -> list[Table]:
    thesis = res["thesis"]["rows"]
    rows = []
    for name, ours in res["rows"].items():
        th = thesis.get(name, {})
        rows.append(
            [
                f"A0 = {name} ({ours['seconds']:.0f} s)",
                _pm(ours["sensor_rms_mm"], ours["sensor_rms_mm_std"]),
                _pm(th.get("sensor_rms_mm"), th.get("sensor_rms_mm_std")),
                _pm(ours["action_rms_mm_s"], ours["action_rms_mm_s_std"]),
                _pm(th.get("action_rms_mm_s"), th.get("action_rms_mm_s_std")),
                _pm(ours["consistency"], ours["consistency_std"], 3),
                _pm(th.get("consistency"), th.get("consistency_std"), 2),
                f"{ours['converged']}/{ours['trials']}",
                f"{th.get('converged', '-')}/{th.get('trials', '-')}",
            ]
        )
    t1: Table = (
        "Table 3.1 (simulated Aibo): scaled RMS errors, mean ± std over converged trials",
        [
            "starting model",
            "sensor mm",
            "thesis",
            "action mm/s",
            "thesis",
            "consistency",
            "thesis",
            "converged",
            "thesis",
        ],
        rows,
    )
    d, td = res["degree_selection"], res["thesis"]["degree_selection"]
    t2: Table = (
        "Degree selection (sec. 3.3.3)",
        ["", "ours", "thesis"],
        [
            ["chosen degree", _pm(d["degree_mean"], d["degree_std"], 2), _pm(td["degree_mean"], td["degree_std"], 2)],
            [
                "sensor RMS (mm)",
                _pm(d["sensor_rms_mm"], d["sensor_rms_mm_std"]),
                _pm(td["sensor_rms_mm"], td["sensor_rms_mm_std"]),
            ],
            ["trials", f"{d['trials']} × {d['seconds']:.0f} s", f"{td['trials']} × {td['seconds']:.0f} s"],
        ],
    )
    first = next(iter(res["rows"].values()))
    t3: Table = (
        "Reference errors on the measured grid",
        ["", "ours", "thesis"],
        [
            [
                "best cubic sensor (mm)",
                f"{first['sensor_best_rms_mm']:.1f}",
                f"{res['thesis']['best_cubic_sensor_rms_mm']:.1f}",
            ],
            [
                "best quartic action (mm/s)",
                f"{first['action_best_rms_mm_s']:.1f}",
                f"{res['thesis']['best_quartic_action_rms_mm_s']:.1f}",
            ],
            [
                "A0(c) = c action (mm/s)",
                f"{res['a0_linear_action_rms_mm_s']:.1f}",
                f"{res['thesis']['a0_linear_action_rms_mm_s']:.1f}",
            ],
        ],
    )
    return [t1, t2, t3]


# chapter 3 times each command held for 2 s or more (sec. 3.3.2); a gain needs one such command
NOT_TIMED = "not scored: no command held for 2 s"


def sensor_span_cell(s: dict[str, Any]) -> str:
    """A Turtlebot sensor's score (``evaluate.turtlebot_em.score_turtlebot_em``): its error in % of its span, and
    in how many bins f is so flat that the error exceeds the span."""
    pct = s["rms_pct_of_span"]
    if pct is None or not math.isfinite(pct):  # NaN in memory, null once read back
        return "not scored (readings in fewer than two 100-mm bins inside its window)"
    out = f"{pct:.2f} % of its {s['span_mm']:.0f} mm span"
    k = s.get("bins_beyond_span")
    if k:
        out += (
            f"; {s['rms_pct_of_span_within']:.2f} % without the {k} of its {s['bins']} bins off by more than the "
            "span, where f is nearly flat and the reading hardly tells the distance"
        )
    return out


def gain_cell(learned: float | None, true: float | None, error_pct: float | None, why: str = NOT_TIMED) -> str:
    """``learned (truth T, E % off)``, or ``learned (why)`` when the log could not score a gain."""
    if error_pct is None:
        return f"{learned:.4f} ({why})" if learned is not None and math.isfinite(learned) else why
    truth = f"truth {true:.4f}, " if true is not None else ""
    return f"{learned:.4f} ({truth}{error_pct:.2f} % off)"


def one_command_reason(share: float) -> str:
    return f"not scored: {100 * share:.0f} % of the steps at one command"


def turtlebot_tables(res: dict[str, Any]) -> list[Table]:
    """One table per training log: the first log's, then each of ``more_logs``."""
    return [_turtlebot_table(r) for r in (res, *res.get("more_logs", {}).values())]


def _turtlebot_table(res: dict[str, Any]) -> Table:
    rows = []
    for name, r in res["rows"].items():
        rows.append(
            [
                name,
                f"{100 * r['sensor_rms_m']:.1f} cm ({r['sensor_rms_pct']:.1f} %)",
                f"{100 * r['sensor_best_rms_m']:.1f} cm",
                f"{1000 * r['action_rms_m_s']:.1f} mm/s" if r["action_rms_m_s"] is not None else "-",
                f"{r['learned_gain']:.3f} / {r['true_gain']:.3f}" if r["gain_error_pct"] is not None else NOT_TIMED,
                _f(r["consistency"], 3) if r["consistency"] != math.inf else "-",  # inf: no timed command
                f"{r['n_gated']}/{r['n_observations']}",
            ]
        )
    return (
        f"Turtlebot {Path(res['file']).name}, Algorithm 1 (errors after the optimal scale)",
        ["sensor", "sensor RMS (% of span)", "best cubic", "action RMS", "gain learned / true", "consistency", "gated"],
        rows,
    )


def _f(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and x != x):
        return "-"
    return f"{x:.{digits}f}" if isinstance(x, float) else str(x)


def field2d_tables(res: dict[str, Any]) -> list[Table]:
    o, th = res["ours"], res["thesis"]
    w = o["worst"]
    rows = [
        ["v_x RMS (mm/s)", _f(th["vx_rms_mm_s"]), _f(o["vx_rms_mm_s"]), _f(w["vx_rms_mm_s"])],
        ["v_y RMS (mm/s)", _f(th["vy_rms_mm_s"]), _f(o["vy_rms_mm_s"]), _f(w["vy_rms_mm_s"])],
        ["v_θ RMS (rad/s)", _f(th["vtheta_rms_rad_s"], 3), _f(o["vtheta_rms_rad_s"], 3), _f(w["vtheta_rms_rad_s"], 3)],
        [
            "σ1 learned / true (px)",
            f"{th['sigma1_learned']} / {th['sigma1_true']}",
            f"{o['sigma1_learned']:.3f} / {o['sigma1_true']}",
            f"{w['sigma1_error_pct']:.1f} % off",
        ],
        [
            "σ2 learned / true (rad)",
            f"{th['sigma2_learned']} / {th['sigma2_true']}",
            f"{o['sigma2_learned']:.3f} / {o['sigma2_true']}",
            f"{w['sigma2_error_pct']:.1f} % off",
        ],
        ["EM iterations", str(th["iterations"]), _f(o["iterations"], 0), "-"],
        [
            "log-likelihood start → best",
            str(th["loglik_start"]),
            f"{o['loglik_start']:.0f} → {o['loglik_best']:.0f}",
            "-",
        ],
        ["learning time (s)", str(th["seconds"]), _f(o["seconds"], 1), "-"],
    ]
    tables = [
        (
            f"Field 2-D, simulation setting of sec. 4.4.2 (mean of {o['trials']} seeds; worst seed)",
            ["quantity", "thesis", "ours (mean)", "ours (worst)"],
            rows,
        )
    ]
    if "real_robot" in res:
        r, t = res["real_robot"]["ours"], res["real_robot"]["thesis"]
        tables.append(
            (
                "Field 2-D, real-robot setting of sec. 4.4.1 (30 Hz, 2 % false positives, pruning on)",
                ["quantity", "thesis (real Aibo)", "ours (simulated)"],
                [
                    ["v_θ RMS (rad/s)", _f(t["vtheta_rms_rad_s"], 3), _f(r["vtheta_rms_rad_s"], 3)],
                    ["v_x, v_y RMS (mm/s)", "not measured", f"{r['vx_rms_mm_s']:.1f}, {r['vy_rms_mm_s']:.1f}"],
                    [
                        "σ1 learned / true (px)",
                        f"{t['sigma1_learned']} / {t['sigma1_true']}",
                        f"{r['sigma1_learned']:.2f} / {r['sigma1_true']}",
                    ],
                    [
                        "σ2 learned / true (rad)",
                        f"{t['sigma2_learned']} / {t['sigma2_true']}",
                        f"{r['sigma2_learned']:.4f} / {r['sigma2_true']}",
                    ],
                    ["EM iterations", str(t["iterations"]), str(r["iterations"])],
                    ["observations (pruned)", str(t["n_observations"]), f"{r['n_observations']} ({r['n_pruned']})"],
                ],
            )
        )
    return tables


def em1d_tables(res: dict[str, Any]) -> list[Table]:
    o, th = res["ours"], res["thesis"]
    main = [
        [
            "sensor RMS",
            f"{th['sensor_rms_px']} px ({th['sensor_rms_pct']} %)",
            f"{o['sensor_rms_px']:.2f} px ({o['sensor_rms_pct']:.2f} %)",
        ],
        [
            "action RMS",
            f"{th['action_rms_mm_s']} mm/s ({th['action_rms_pct']} %)",
            f"{o['action_rms_mm_s']:.1f} mm/s ({o['action_rms_pct']:.2f} %)",
        ],
        ["scale ratio k_a / k_s", str(th["scale_ratio"]), f"{o['scale_ratio']:.3f}"],
        ["EM iterations", str(th["iterations"]), str(o["iterations"])],
        ["learning time (s)", str(th["seconds"]), f"{o['seconds']:.1f}"],
    ]
    rows = []
    for key, label in (
        ("change_before_on_before", "model before, truth before"),
        ("change_after_on_after", "model after, truth after (relearned)"),
        ("change_before_on_after", "model before, truth after (stale)"),
        ("change_after_on_before", "model after, truth before"),
    ):
        a, t = o[key], th.get(key, {})
        rows.append(
            [
                label,
                f"{t.get('action_rms_mm_s', '-')} mm/s, ratio {t.get('scale_ratio', '-')}",
                f"{a['action_rms_mm_s']:.1f} mm/s ({a['action_rms_pct']:.2f} %), ratio {a['scale_ratio']:.2f}",
            ]
        )
    return [
        ("EM in one dimension, sec. 4.4.3 (errors after the optimal scale)", ["quantity", "thesis", "ours"], main),
        ("Learning a changing model: every model against every truth", ["pairing", "thesis", "ours"], rows),
    ]


def car_tables(res: dict[str, Any]) -> list[Table]:
    th = res["thesis"]
    rows = [
        [
            "laser angles (RMS over 64)",
            f"{th['laser_angle_rms_deg']}° ({th['laser_angle_rms_pct']} %)",
            f"{res['laser_angle_rms_deg']:.3f}° ({res['laser_angle_rms_pct']:.2f} %)",
            "-",
        ],
    ]
    for key, unit, label in (
        ("accel_rms", "m/s²", "acceleration"),
        ("fwd_vel_rms", "m/s", "forward velocity"),
        ("ang_vel_rms", "rad/s", "angular velocity"),
    ):
        rows.append(
            [
                label,
                f"{th[key]} {unit} ({th[key + '_pct']} %), from truth {th[key + '_from_truth']}",
                f"{res[key]:.4g} {unit} ({res[key + '_pct']:.2f} %)",
                f"{res[key + '_from_truth']:.4g}",
            ]
        )
    rows.append(["iterations of Algorithm 3", str(th["iterations"]), str(res["iterations"]), "-"])
    stages = ", ".join(f"{k} {v:.1f} s" for k, v in res["seconds_by_stage"].items())
    rows.append(["time by stage", "angles 83 min (10.7 with the 23° bound), 34 min per iteration", stages, "-"])
    return [("Car and HDL-64E, sec. 5.4 and Table 5.1", ["quantity", "thesis", "ours", "ours from truth"], rows)]


VERDICT = {True: "cleared", False: "missed", None: "not scored"}


def scorecard_table(rows: list[dict[str, Any]]) -> Table:
    """An experiment's ``scorecard`` (``evaluate.bars.BarCheck`` dicts) as a table titled with its count."""
    checks = checks_from_json(rows)
    done, scored = counts(checks)
    return (
        f"Bars: {done} of {scored} cleared",
        ["quantity", "bar", "ours", "verdict"],
        [[c.quantity, c.bar, c.ours, VERDICT[c.cleared]] for c in checks],
    )


def to_markdown(tables: list[Table]) -> str:
    out = []
    for title, headers, rows in tables:
        out.append(f"### {title}\n")
        out.append("| " + " | ".join(headers) + " |")
        out.append("|" + "---|" * len(headers))
        out.extend("| " + " | ".join(r) + " |" for r in rows)
        out.append("")
    return "\n".join(out)


def _drift_cell(n: dict[str, Any], when: str) -> str:
    learned = n.get(f"learned_heading_drift_{when}_rad")
    truth = f"{n[f'heading_drift_rms_{when}_rad']:.4f}"
    return truth if learned is None else f"{truth} / {learned:.4f}"


def _mount_cell(score: dict[str, Any]) -> str:
    m, b = score.get("sensor_mount"), score["bearing"]
    if m is None or b is None:  # results written before the sensor's pose was fitted, or no bearings to fit it by
        return "-"
    return (
        f"{m['forward_mm']:.0f} / {m['lateral_mm']:.0f} / {m['yaw_rad']:+.4f}; "
        f"{b['truth_origin_sigma_rad']:.4f} ({b['truth_origin_sigma_ratio']:.2f})"
    )


def shared_by_motion(n: dict[str, Any]) -> str:
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


def translation_drift_cell(n: dict[str, Any]) -> str:
    """'7.1 / 7.6; 16.5 / 15.7': the truth's sideways / forward miss per window, RMS mm, then the
    learned Sigma_m's; '-' for results written before they were measured."""
    truth, learned = n.get("translation_drift_rms_mm"), n.get("learned_translation_drift_mm")
    if truth is None or learned is None:
        return "-"
    return f"{truth[0]:.1f} / {truth[1]:.1f}; {learned[0]:.1f} / {learned[1]:.1f}"


def truth_heading_cell(n: dict[str, Any]) -> str:
    """'0.0063 (51%)': the truth's own heading error on straight stretches, sd rad, and its share of the
    frame means' bearing residual variance; '-' where too few frames or for results written before it."""
    e = n.get("truth_heading_error") or {}
    var = e.get("variance_rad2")
    if var is None or var != var:  # NaN, null once written to JSON
        return "-"
    return f"{math.sqrt(max(var, 0.0)):.4f} ({e['share']:.0%})"


def _shared_cell(n: dict[str, Any]) -> str:
    if "bearing_within_frame_sd_rad" not in n:
        return "-"
    return f"{n['bearing_within_frame_sd_rad']:.4f}; {n['bearing_frame_shared_fraction']:.0%}{shared_by_motion(n)}"


def _failed_bars(score: dict[str, Any]) -> str:
    return ", ".join(k for k, v in score["bars"].items() if not v) or "all pass"


def _path_cell(score: dict[str, Any]) -> str:
    p = score.get("path")
    return "-" if not p else f"{p['median_mm']:.0f} ({p['forward_median_mm']:+.0f})"


def _ridge_cell(em: dict[str, Any]) -> str:
    # the moves only: the first search's likelihood is the held stage's, the others the freed one's
    return ", ".join(f"{r['shift_mm']:+.0f}" for r in em.get("ridge") or []) or "-"


def _delay_cell(action: dict[str, Any], em: dict[str, Any]) -> str:
    cell = f"{action['learned_delay_s']:.3f} / {action['from_truth_delay_s']:.3f}"
    moves = [
        f"{s['delay_from']}->{s['delay_to']}" for s in em.get("delay_search") or [] if s["delay_to"] != s["delay_from"]
    ]
    return f"{cell} (searches moved it {', '.join(moves)} steps)" if moves else cell


def _mrclam_title(res: dict[str, Any]) -> str:
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


def _truth_score_row(name: str, score: dict[str, Any], em: dict[str, Any]) -> list[str]:
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


def _sim_bearing_cell(s: dict[str, Any]) -> str:
    """The learned bearing sigma / the simulated one (ratio); "-" for a range-only sensor."""
    if "bearing_sigma_rad" not in s:
        return "-"
    learned, true = s["bearing_sigma_rad"]
    return f"{learned:.4f} / {true:.4f} ({s['bearing_sigma_ratio']:.2f})"


def diffdrive_tables(res: dict[str, Any]) -> list[Table]:
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


FLEET_TITLE = "translation / rotation RMS over From-Truth's, range residual about the truth, bearing sigma ratio"
FLEET_BARS = {  # a fleet cell's part and the bars it answers to (experiments.real.robot_checks)
    "translation": ("action_translation_ratio", "action_translation_abs"),
    "rotation": ("action_rotation_ratio",),
    "bearing": ("bearing_sigma",),
}


def fleet_table(
    fleet: dict[str, Any],
    title: str = FLEET_TITLE,
    miss: Callable[[str], str] = lambda s: f"{s} (miss)",
    own: Callable[[str], str] = lambda s: f"**{s}**",
) -> Table:
    """``experiments.fleet.score_fleet``'s pairs, a row per model and a column per log, and From-Truth's
    range residual per log; ``miss`` marks a number that misses its bar, ``own`` a robot's own pair (the
    console passes colour, Markdown the defaults)."""

    def cell(m: str, g: str) -> str:
        c = fleet["cells"][m][g]

        def shown(text: str, part: str) -> str:
            return text if all(c["bars"][b] for b in FLEET_BARS[part]) else miss(text)

        tr, rot = (f"{c[k]:.2f}" for k in ("translation_ratio", "rotation_ratio"))
        b = c["bearing_sigma_ratio"]
        text = f"{shown(tr, 'translation')} / {shown(rot, 'rotation')}, {c['range_residual_rms_mm']:.0f} mm, " + (
            "no bearing" if b is None else shown(f"{b:.2f}", "bearing")
        )
        return own(text) if fleet["own"].get(m) == g else text

    first = fleet["models"][0]
    rows = [[m, *(cell(m, g) for g in fleet["logs"])] for m in fleet["models"]]
    rows.append(
        ["From-Truth", *(f"{fleet['cells'][first][g]['range_from_truth_rms_mm']:.0f} mm" for g in fleet["logs"])]
    )
    return title, ["model \\ log", *fleet["logs"]], rows


def bars_sentence(bars: dict[str, float]) -> str:
    """The real-data bars (``experiments.real.BARS``) in words."""
    return (
        f"an action RMS at most {bars['action_ratio_max']:g} times From-Truth's (translation at most "
        f"{bars['action_translation_max_mm_s']:g} mm/s), a sigma within a factor of {bars['sigma_factor']:g} of "
        "the truth's"
    )


def fleet_lines(fleet: dict[str, Any]) -> list[str]:
    """What the fleet table says over the robots' own pairs and over the others."""
    lines = [
        f"bars: {bars_sentence(fleet['bars'])}; the range residual has no bar (From-Truth's, the last row, is its "
        "floor)"
    ]
    for group, s in fleet["summary"].items():
        if not s["pairs"]:
            continue
        lo, hi = s["range_residual_rms_mm"]
        who = "a robot's own model" if group == "own" else "another robot's model" if fleet["own"] else "every pair"
        lines.append(
            f"{who} ({s['pairs']} pairs): {s['clear_action_bars']} clear the action bars "
            f"(worst translation {s['translation_ratio_max']:.2f}, rotation {s['rotation_ratio_max']:.2f}), "
            f"{s['clear_range_sigma_bar']} the range sigma bar, {s['clear_bearing_sigma_bar']} the bearing sigma "
            "bar"
            + (
                f" (of the {s['bearing_pairs']} pairs whose model reads bearings)"
                if s.get("bearing_pairs", s["pairs"]) < s["pairs"]
                else ""
            )
            + f"; range residual {lo:.0f}-{hi:.0f} mm"
        )
    return lines


FLEET_LIKELIHOOD_TITLE = (
    "log-likelihood a sighting, each model placed on each log by the E-step alone (no ground truth); in brackets, "
    "how far below the log's most likely model"
)


def fleet_likelihood_table(
    fleet: dict[str, Any], title: str = FLEET_LIKELIHOOD_TITLE, own: Callable[[str], str] = lambda s: f"**{s}**"
) -> Table:
    """``experiments.fleet.score_likelihoods``' pairs, a row per model and a column per log, and the
    sightings each log's likelihood is over; ``own`` marks a robot's own pair."""
    lk = fleet["likelihood"]

    def cell(m: str, g: str) -> str:
        c = lk["cells"][m][g]
        if c["per_sighting"] is None:
            text = "the filter failed"
        else:
            below = c["below_best"]
            text = f"{c['per_sighting']:.3f} ({'most likely' if below == 0 else f'{below:.3f} below'})"
            if not c["filter_ok"]:
                text += ", the filter lost positive definiteness"
        return own(text) if fleet["own"].get(m) == g else text

    def used(g: str) -> str:
        n = sorted(
            {lk["cells"][m][g]["n_used"] for m in fleet["models"] if lk["cells"][m][g]["per_sighting"] is not None}
        )
        return "-" if not n else str(n[0]) if len(n) == 1 else f"{n[0]}-{n[-1]}"

    rows = [[m, *(cell(m, g) for g in fleet["logs"])] for m in fleet["models"]]
    rows.append(["sightings used", *(used(g) for g in fleet["logs"])])
    return title, ["model \\ log", *fleet["logs"]], rows


def fleet_likelihood_lines(fleet: dict[str, Any]) -> list[str]:
    """What the likelihood table says: whether each log's own model is its most likely, and how close the
    best of the others comes on each log."""
    lk = fleet["likelihood"]
    s = lk["summary"]
    lines = []
    if s["logs_with_own"]:
        lines.append(
            f"by the likelihood (no ground truth): on {s['own_most_likely']} of {s['logs_with_own']} logs the "
            "robot's own model is the most likely (it has a small edge there, having been fitted to those sightings)"
        )
    owner = {g: m for m, g in fleet["own"].items()}
    found = [(g, p) for g, p in s["per_log"].items() if p["closest_other"] is not None]

    def closest_cell(g: str, p: dict[str, Any], first: bool) -> str:
        own_below = lk["cells"][owner[g]][g]["below_best"] if g in owner else None
        if p["closest_other_below"] == 0 and own_below:  # another model explains the run better than its own
            return f"{p['closest_other']} on {g} (the most likely: {owner[g]}, its own, {own_below:.3f} below)"
        return f"{p['closest_other']} on {g} ({p['closest_other_below']:.3f}{' a sighting below' if first else ''})"

    closest = [closest_cell(g, p, i == 0) for i, (g, p) in enumerate(found)]  # the unit said once, on the first
    if closest:
        lines.append(
            ("the closest other model on each log: " if fleet["own"] else "the runner-up on each log: ")
            + ", ".join(closest)
        )
    failed = [
        f"{m} on {g}: {c['failed']}"
        for m, row in lk["cells"].items()
        for g, c in row.items()
        if c["per_sighting"] is None
    ]
    return lines + [f"not placed: {f}" for f in failed]


FLEET_RANGE_TITLE = (
    "each model placed on each Turtlebot CSV and scored against its range column (optimal scale and offset, "
    "sec. 4.4.3): the action gain's error; the best sensor's, in % of its span"
)


def fleet_range_table(
    fleet: dict[str, Any],
    title: str = FLEET_RANGE_TITLE,
    miss: Callable[[str], str] = lambda s: f"{s} (miss)",
    own: Callable[[str], str] = lambda s: f"**{s}**",
) -> Table:
    """``experiments.fleet.range_grid``'s pairs, a row per model and a column per CSV with its range; ``miss``
    marks a number past its bar, ``own`` a robot's own pair."""
    rng = fleet["range"]

    def cell(m: str, g: str) -> str:
        c = rng["cells"][m][g]
        if "failed" in c:
            return "the filter failed"
        if c["gain_error_pct"] is None:
            gain = f"gain {one_command_reason(c['one_command_share'])}"
        else:
            gain = f"gain {c['gain_error_pct']:.2f} % off"
            gain = gain if c["bars"]["gain"] else miss(gain)
        if c["best_sensor"] is None:
            sensor = "no sensor scored"
        else:
            sensor = f"{c['best_sensor']} {c['best_sensor_pct']:.2f} %"
            sensor = sensor if c["bars"]["sensor"] else miss(sensor)
        text = f"{gain}, {sensor}"
        return own(text) if fleet["own"].get(m) == g else text

    rows = [[m, *(cell(m, g) for g in rng["logs"])] for m in fleet["models"]]
    return title, ["model \\ log", *rng["logs"]], rows


def fleet_range_lines(fleet: dict[str, Any]) -> list[str]:
    """What the range table says over the robots' own pairs and over the others, and which Turtlebot CSVs
    could not be scored against their range."""
    rng = fleet.get("range")
    if not rng:
        return []
    lines = []
    if rng["logs"]:
        b = rng["bars"]
        lines.append(
            f"bars: the action gain within {b['gain_pct_max']:g} % of the range's, the best sensor within "
            f"{b['sensor_pct_max']:g} % of its span"
        )
    for group, s in rng["summary"].items():
        if not s["pairs"]:
            continue
        who = "a robot's own model" if group == "own" else "another robot's model" if fleet["own"] else "every pair"
        gains = (
            f"{s['clear_gain_bar']} of the {s['gain_scored']} with a scored gain clear the gain bar (worst "
            f"{s['gain_error_pct_max']:.2f} % off)"
            if s["gain_scored"]
            else "no gain scored"
        )
        lines.append(f"{who} ({s['pairs']} pairs): {gains}, {s['clear_sensor_bar']} the sensor bar")
    if rng["no_range"]:
        lines.append("not scored against the range: " + ", ".join(f"{g} ({why})" for g, why in rng["no_range"].items()))
    return lines


def restart_runs_cell(runs: list[dict[str, Any]]) -> str:
    """Each run of ``fit.restart_while_lost``: its channels' start sigmas and its likelihood."""
    return "; ".join(
        ", ".join(f"{name} {s:.4g}" for name, s in r["start_sigma"].items())
        + f": {r['loglik']:.1f}"
        + (f" ({_lost_signs(r['f_turns'])})" if r["f_turns"] else "")
        for r in runs
    )


def _lost_signs(signs: list[dict[str, Any]]) -> str:
    """``f turned``, ``f bent``, ``f turned and bent``, ``EM unsettled`` or one of the first three and it,
    for a run's ``checks.lost_fit_signs``."""
    kinds = {t["sign"] for t in signs}
    f = [word for sign, word in (("turns", "turned"), ("bends", "bent")) if sign in kinds]
    return "; ".join(([f"f {' and '.join(f)}"] if f else []) + (["EM unsettled"] if "unsettled" in kinds else []))


def kept_run_cell(runs: list[dict[str, Any]]) -> str:
    """Which run ``fit.restart_while_lost`` kept."""
    k = next(i for i, r in enumerate(runs) if r["kept"])
    return "the first run" if k == 0 else f"restart {k}"


def real_tables(res: dict[str, Any]) -> list[Table]:
    """MRCLAM robots (learned against From-Truth) and the Turtlebot (EM beside chapter 3)."""
    tables: list[Table] = []
    title = _mrclam_title(res)
    rows = [_truth_score_row(name, r["score"], r["em"]) for name, r in res.get("mrclam", {}).items()]
    if rows:
        tables.append((f"{title}: learned / From-Truth (ratio)", truth_score_headers("robot", "Vicon"), rows))
    restarts = [(name, r, r["truth_restart"]) for name, r in res.get("mrclam", {}).items() if "truth_restart" in r]
    if restarts:
        tables.append(
            (
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
        )
    noise = [(name, r["score"].get("truth_noise")) for name, r in res.get("mrclam", {}).items()]
    if any(n for _, n in noise):
        tables.append(
            (
                f"{title}: what the truth says about the noise (see docs/em-real-results.md, Known limits)",
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
                        _mount_cell(res["mrclam"][name]["score"]),
                    ]
                    for name, n in noise
                    if n
                ],
            )
        )
    for dataset, fleet in res.get("fleet", {}).items():
        tables.append(fleet_table(fleet, f"{dataset}, each robot's model on every robot's log: {FLEET_TITLE}"))
        if "likelihood" in fleet:  # absent from results written before the likelihood was measured
            tables.append(fleet_likelihood_table(fleet, f"{dataset}: {FLEET_LIKELIHOOD_TITLE}"))
    turtlebots = [res["turtlebot"], *res.get("turtlebot_more_logs", {}).values()] if res.get("turtlebot") else []
    for tb in turtlebots:  # the training1.csv, then any other training log, a table each
        sc, ch3 = tb["score"], tb.get("chapter3_sonar1", {})
        share = sc.get("one_command_share", 0.0)  # absent from results written before it was measured
        trows = [
            [
                "action gain (after the optimal scale)",
                gain_cell(sc["gain_learned"], sc["gain_true"], sc["gain_error_pct"], one_command_reason(share)),
                gain_cell(ch3["learned_gain"], None, ch3["gain_error_pct"]) if ch3 else "-",
            ],
            ["learned command delay", f"{sc['delay_s']:.3f} s", "-"],
        ]
        for name, s in sc["sensors"].items():
            c3 = f"{ch3['sensor_rms_pct']:.2f} %" if name == "sonar1" and ch3 else "-"
            trows.append([f"{name} error, % of its span", sensor_span_cell(s), c3])
        tables.append(
            (
                f"Turtlebot {Path(tb['file']).name}: EM in 1-D against the chapter-3 learner",
                ["quantity", "EM", "chapter 3"],
                trows,
            )
        )
    restarted = [(name, r["em"]["restarts"]) for name, r in res.get("mrclam", {}).items() if r["em"].get("restarts")]
    if restarted:
        tables.append(
            (
                f"{title}: EM started again because the fit looked lost (learn/em/checks.py)",
                ["robot", "start sigma: log-likelihood on the sightings all runs kept", "kept"],
                [[name, restart_runs_cell(runs), kept_run_cell(runs)] for name, runs in restarted],
            )
        )
    skipped = [line.partition(": ") for line in res.get("skipped", [])]
    if skipped:
        tables.append(("Not run", ["what", "why"], [[what, why] for what, _, why in skipped]))
    return tables
