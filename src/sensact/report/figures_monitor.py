"""The change monitor's figure: each stream's CUSUM over the log against its threshold, with the change
and any episodes marked (`sensact monitor --out`, `sensact reproduce monitor`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.report.figures1d import _save


def figure_monitor(result: Any, path: Path, title: str, true_change_s: float | None = None) -> Path:
    """One panel per stream: CUSUM / threshold over time (1 is the alarm line)."""
    streams = result.streams
    fig, axes = plt.subplots(len(streams), 1, figsize=(9, 1.9 * len(streams) + 0.6), sharex=True, squeeze=False)
    width = result.config.bin_s
    for ax, s in zip(axes[:, 0], streams, strict=True):
        t = (np.arange(s.statistic.size) + 1) * width
        ax.plot(t, s.statistic / s.threshold, lw=1, color="C0" if s.model == "action" else "C2")
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        for e in s.episodes:
            ax.axvspan(e.change_s, e.alarm_s, color="0.8", lw=0)
        if s.change is not None:
            ax.axvline(s.change.alarm_s, color="C3", lw=1.2, label=f"change flagged at {s.change.alarm_s:.0f} s")
            ax.axvline(s.change.change_s, color="C3", lw=0.8, ls=":", label=f"began at {s.change.change_s:.0f} s")
        if true_change_s is not None:
            ax.axvline(true_change_s, color="k", lw=0.8, ls="-.", label=f"true change, {true_change_s:.0f} s")
        ax.set_ylabel("CUSUM / h", fontsize=8)
        ax.set_title(f"{s.name} (long-run sd {s.scale:.2f}, h {s.threshold:.1f})", fontsize=9)
        if s.change is not None or true_change_s is not None:
            ax.legend(fontsize=7, loc="upper left")
    axes[-1, 0].set_xlabel("time in the log (s); grey: episodes that did not persist")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return _save(fig, path)
