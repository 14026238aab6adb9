"""Figures for the one-dimensional experiments, drawn like the thesis's Figures 3.7 to 3.9."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.evaluate.track1d import measured_models
from sensact.io.atomic import write_bytes
from sensact.records import JsonObject


def _save(fig: Any, path: Path) -> Path:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return write_bytes(path, buf.getvalue())


def figure_3_7(trial: Any, path: Path) -> Path:
    """w_a (curve) and w_s (+) over time in one run: the two location estimates coming into agreement."""
    h = trial.result.history
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ok = np.isfinite(h.w_s)
    ax.plot(h.times_s[ok][::3], h.w_s[ok][::3], "+", ms=3, color="tab:orange", label="$w_{s,t}$ = S(o)")
    ax.plot(h.times_s, h.w_a, "-", lw=1.2, color="tab:blue", label="$w_{a,t}$ (actions)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("location (learned units)")
    ax.set_title(
        f"Figure 3.7: location estimates over time (A0 = {trial.result.config.a0}, seed {trial.run.config.seed})"
    )
    ax.legend(loc="upper right")
    return _save(fig, path)


def figure_3_8(trial: Any, path: Path) -> Path:
    """Learned action and sensor models after the optimal scale, against the measured models."""
    m = measured_models(trial.run.truth)
    sc = trial.score
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    c = np.linspace(-300, 300, 301)
    a.plot(m.commands_mm_s, m.velocities_mm_s, "o", ms=4, label="measured")
    a.plot(c, sc.action_scale_k * trial.result.action(c), "-", label=f"learned × k (RMS {sc.action_rms:.1f} mm/s)")
    a.plot(c, c, ":", color="gray", label="A0(c) = c")
    a.set_xlabel("attempted velocity c (mm/s)")
    a.set_ylabel("velocity (mm/s)")
    a.set_title("a) action model")
    a.legend(fontsize=8)
    o = np.linspace(m.heights_px.min(), m.heights_px.max(), 200)
    b.plot(m.heights_px, m.distances_mm, "o", ms=4, label="measured")
    b.plot(
        o,
        sc.sensor_offset_a + sc.sensor_scale_b * trial.result.sensor(o),
        "-",
        label=f"a + b·S(o) (RMS {sc.sensor_rms:.1f} mm)",
    )
    b.set_xlabel("beacon height o (px)")
    b.set_ylabel("distance (mm)")
    b.set_title("b) sensor model")
    b.legend(fontsize=8)
    fig.suptitle("Figure 3.8: learned against measured models")
    return _save(fig, path)


def figure_3_9(
    curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], best: dict[str, float], path: Path
) -> Path:
    """Average scaled errors over time, with the best possible polynomial errors as horizontal lines."""
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.8))
    for row, (t, s_err, a_err) in curves.items():
        b.plot(t, s_err, label=f"A0 = {row}")
        a.plot(t, a_err, label=f"A0 = {row}")
    a.axhline(best["action"], color="k", ls="--", lw=1, label="best quartic")
    b.axhline(best["sensor"], color="k", ls="--", lw=1, label="best cubic")
    a.set_ylim(0, 100)
    b.set_ylim(0, 400)
    for ax, unit, name in ((a, "mm/s", "action"), (b, "mm", "sensor")):
        ax.set_xlabel("time (s)")
        ax.set_ylabel(f"RMS error ({unit})")
        ax.set_title(f"{name} model")
        ax.legend(fontsize=8)
    fig.suptitle("Figure 3.9: learning curves, mean over converged trials")
    return _save(fig, path)


def figure_degree(degree_trials: list[Any], path: Path) -> Path:
    """The automatically chosen sensor degree over time in each trial (sec. 3.3.3)."""
    fig, ax = plt.subplots(figsize=(8, 3.2))
    for i, d in enumerate(degree_trials):
        h = d.result.history
        ax.step(h.snapshot_t_s, h.snapshot_sensor_degree + 0.04 * (i - len(degree_trials) / 2), where="post", lw=1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("sensor polynomial degree")
    ax.set_title("Degree selection (sec. 3.3.3): one line per trial")
    return _save(fig, path)


def figure_real(runs: JsonObject, path: Path) -> Path:
    """Real robot: each sensor's learned model (after a + b·S) over the measured one, and the action."""
    n = len(runs)
    fig, axes = plt.subplots(1, n + 1, figsize=(4 * (n + 1), 3.6))
    for ax, (name, run) in zip(axes, runs.items(), strict=False):
        ms, sc = run.measured_sensor, run.score
        ax.plot(ms.observations, ms.positions, "o", ms=3, label="measured (median per 10 cm)")
        if ms.observations.size:
            o = np.linspace(ms.observations.min(), ms.observations.max(), 200)
            ax.plot(
                o,
                sc.sensor_offset_a + sc.sensor_scale_b * run.result.sensor(o),
                "-",
                label=f"learned (RMS {100 * sc.sensor_rms:.1f} cm)",
            )
        ax.set_xlabel(f"{name} ({run.log.observation_unit})")
        ax.set_ylabel("distance (m)")
        ax.legend(fontsize=7)
    ax = axes[-1]
    first = next(iter(runs.values()))
    ma = first.measured_action
    if ma.commands.size:
        c = np.linspace(ma.commands.min(), ma.commands.max(), 100)
        ax.plot(ma.commands, ma.velocities, "o", label="timed (ground truth)")
        for name, run in runs.items():
            ax.plot(c, run.score.action_scale_k * run.result.action(c), "-", lw=1, label=f"learned with {name}")
        ax.legend(fontsize=7)
    else:  # the optimal scale needs a timed command to scale the learned A onto
        ax.text(0.5, 0.5, "no command held for 2 s:\nnothing timed to scale against", ha="center", va="center")
        ax.set_axis_off()
    ax.set_xlabel("velocity_command (m/s)")
    ax.set_ylabel("velocity (m/s)")
    fig.suptitle("Turtlebot, Algorithm 1: learned models after the optimal scale")
    return _save(fig, path)
