"""One figure for any Algorithm 1 run, drawn from the run alone (no ground truth): what
`sensact learn bootstrap --out` writes beside the models, as `learn em --out` does for EM.

Panels: the two location estimates over time (Figure 3.7's: Algorithm 1 learns from their agreement);
S(o) over the pairs (o_t, w_a,t) as the run regressed on them (sec. 3.2.1); A(c) over the commands the
log used, beside the slope of w_s over a second at each step. Eq. 3.2 fits A to w_s's path rather than
to slopes, so the slopes are a picture of what S's estimates say of the velocity, not A's targets."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensact.report.figures1d import _save


def _velocity_of_w_s(times: np.ndarray, w_s: np.ndarray, window_s: float = 1.0) -> np.ndarray:
    """The slope of w_s over the observations within ``window_s`` of each step (NaN where too few): what
    S's estimates say of the velocity (eq. 3.2 fits A to w_s's path, not to these slopes)."""
    out = np.full(times.size, np.nan)
    ok = np.flatnonzero(np.isfinite(w_s))
    if ok.size < 3:
        return out
    t, w = times[ok], w_s[ok]
    lo = np.searchsorted(t, times - window_s / 2)
    hi = np.searchsorted(t, times + window_s / 2)
    # running sums give each window's least-squares slope without a Python loop
    c = [np.concatenate(([0.0], np.cumsum(x))) for x in (np.ones_like(t), t, w, t * t, t * w)]
    n, st, sw, stt, stw = (x[hi] - x[lo] for x in c)
    det = n * stt - st * st
    good = (n >= 3) & (det > 1e-12 * np.maximum(n * stt, 1e-300))
    out[good] = (n[good] * stw[good] - st[good] * sw[good]) / det[good]
    return out


def figure_bootstrap_fit(res: Any, data: Any, path: Path, title: str) -> Path:
    """The run's own evidence: w_a and w_s coming into agreement, S over its training pairs, A over its."""
    h = res.history
    assert h is not None, "the run's history is needed (the batch path records it)"
    used = np.isfinite(h.w_s)
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(16, 4.2))
    a.plot(h.times_s[used], h.w_s[used], "+", ms=3, color="tab:orange", label="$w_s$ = S(o)")
    a.plot(h.times_s, h.w_a, "-", lw=1, color="tab:blue", label="$w_a$ (actions)")
    if res.diverged_at_s is not None:
        a.axvline(res.diverged_at_s, color="C3", ls="--", lw=1, label="diverged")
    a.set(xlabel="time (s)", ylabel="location (learned units)", title="location estimates (Figure 3.7)")
    a.legend(fontsize=7)

    o = np.asarray(data.observations, dtype=float)
    b.scatter(o[used], h.w_a[used], s=3, alpha=0.3, color="C0", label="($o_t$, $w_{a,t}$) as the run saw them")
    seen = o[used] if used.any() else o[np.isfinite(o)]  # not the gated outliers' far readings
    if seen.size:
        x = np.linspace(seen.min(), seen.max(), 200)
        b.plot(x, res.sensor(x), color="C3", lw=2, label=f"learned S (degree {res.sensor_degree})")
    if res.n_gated:
        b.plot([], [], " ", label=f"{res.n_gated} observations gated as outliers")
    b.set(
        xlabel=f"{data.observation_name} ({data.observation_unit})",
        ylabel="location (learned units)",
        title="sensor model S(o)",
    )
    b.legend(fontsize=7, markerscale=3)

    cmd = np.asarray(data.commands, dtype=float)
    vel = _velocity_of_w_s(h.times_s, h.w_s)
    keep = np.isfinite(vel) & np.isfinite(cmd)
    c.scatter(cmd[keep], vel[keep], s=3, alpha=0.2, color="C0", label="slope of $w_s$ over 1 s")
    x = np.linspace(np.nanmin(cmd), np.nanmax(cmd), 200)
    c.plot(x, res.action(x), color="C3", lw=2, label="learned A")
    if keep.any():
        r = vel[keep]
        pad = 0.15 * (np.percentile(r, 99) - np.percentile(r, 1))
        c.set_ylim(np.percentile(r, 1) - pad, np.percentile(r, 99) + pad)
    c.set(
        xlabel=f"command ({data.command_unit})",
        ylabel="velocity (learned units / s)",
        title="action model A(c)",
    )
    c.legend(fontsize=7, markerscale=3)
    for ax in (a, b, c):
        ax.grid(alpha=0.3)
    fig.suptitle(f"{title}: status {res.status}")
    fig.tight_layout()
    return _save(fig, path)
