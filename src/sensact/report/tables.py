"""Result tables with the thesis's numbers beside ours, as plain rows (rendered by Markdown or rich)."""

from __future__ import annotations

from typing import Any

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


def turtlebot_tables(res: dict[str, Any]) -> list[Table]:
    rows = []
    for name, r in res["rows"].items():
        rows.append(
            [
                name,
                f"{100 * r['sensor_rms_m']:.1f} cm ({r['sensor_rms_pct']:.1f} %)",
                f"{100 * r['sensor_best_rms_m']:.1f} cm",
                f"{1000 * r['action_rms_m_s']:.1f} mm/s",
                f"{r['learned_gain']:.3f} / {r['true_gain']:.3f}",
                f"{r['consistency']:.3f}",
                f"{r['n_gated']}/{r['n_observations']}",
            ]
        )
    return [
        (
            "Turtlebot training1.csv, Algorithm 1 (errors after the optimal scale)",
            [
                "sensor",
                "sensor RMS (% of span)",
                "best cubic",
                "action RMS",
                "gain learned / true",
                "consistency",
                "gated",
            ],
            rows,
        )
    ]


def to_markdown(tables: list[Table]) -> str:
    out = []
    for title, headers, rows in tables:
        out.append(f"### {title}\n")
        out.append("| " + " | ".join(headers) + " |")
        out.append("|" + "---|" * len(headers))
        out.extend("| " + " | ".join(r) + " |" for r in rows)
        out.append("")
    return "\n".join(out)
