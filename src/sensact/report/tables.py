"""Result tables with the thesis's numbers beside ours, as plain rows (rendered by Markdown or rich): the
thesis's experiments (chapters 3-5), the scorecard, and the cells they share with the real robots'
tables (``tables_real.py``) and the fleet's (``tables_fleet.py``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from sensact.evaluate.bars import checks_from_json, counts
from sensact.records import JsonObject

Table = tuple[str, list[str], list[list[str]]]  # title, headers, rows


def _pm(mean: float | None, std: float | None, digits: int = 1) -> str:
    if mean is None or mean != mean:
        return "-"
    return f"{mean:.{digits}f} ± {std:.{digits}f}" if std is not None and std == std else f"{mean:.{digits}f}"


def track1d_tables(res: JsonObject) -> list[Table]:
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


def sensor_span_cell(s: JsonObject) -> str:
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


def turtlebot_tables(res: JsonObject) -> list[Table]:
    """One table per training log: the first log's, then each of ``more_logs``."""
    return [_turtlebot_table(r) for r in (res, *res.get("more_logs", {}).values())]


def _turtlebot_table(res: JsonObject) -> Table:
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


def field2d_tables(res: JsonObject) -> list[Table]:
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


def em1d_tables(res: JsonObject) -> list[Table]:
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


def car_tables(res: JsonObject) -> list[Table]:
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


def scorecard_table(rows: list[JsonObject]) -> Table:
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


def bars_sentence(bars: dict[str, float]) -> str:
    """The real-data bars (``experiments.real.BARS``) in words."""
    return (
        f"an action RMS at most {bars['action_ratio_max']:g} times From-Truth's (translation at most "
        f"{bars['action_translation_max_mm_s']:g} mm/s), a sigma within a factor of {bars['sigma_factor']:g} of "
        "the truth's"
    )
