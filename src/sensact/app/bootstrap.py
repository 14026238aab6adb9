"""``sensact learn bootstrap`` (chapter 3's Algorithm 1) scored against its log's truth, when it has any
(never used for learning): a simulated track's true models, or a real 1-D robot's recorded position."""

from __future__ import annotations

from typing import Any

from sensact.records import JsonObject


def score_bootstrap(data: Any, res: Any, cfg: Any) -> tuple[JsonObject, str] | None:
    """Scaled errors against ``data``'s truth (a ``TrackLog``) and the line that says them; None without truth."""
    if "truth" in data.meta:
        from sensact.evaluate.track1d import score_track_models
        from sensact.sim.track1d import TrackTruth

        sc = score_track_models(res.sensor, res.action, TrackTruth.from_dict(data.meta["truth"]))
        line = (
            f"vs truth (measured grid of sec. 3.3.2): sensor RMS {sc.sensor_rms:.1f} mm "
            f"(best cubic {sc.sensor_best_rms:.1f}), action RMS {sc.action_rms:.1f} mm/s "
            f"(best quartic {sc.action_best_rms:.1f}), consistency {sc.consistency:.3f}"
        )
        return sc.to_dict(), line
    if data.true_position is None:
        return None
    from sensact.evaluate.real_track import evaluate_real
    from sensact.report.tables import NOT_TIMED

    run = evaluate_real(data, res, cfg)
    sc = run.score
    pct = 100.0 * sc.sensor_rms / run.sensor_span
    sensor = (
        f"vs ground truth: sensor RMS {sc.sensor_rms:.4g} {data.position_unit} (best {sc.sensor_best_rms:.4g}; "
        f"{pct:.2f} % of the {run.sensor_span:.4g} {data.position_unit} it is scored over)"
    )
    timed = run.measured_action.commands.size
    out = {**sc.to_dict(), "sensor_rms_pct": pct, "learned_gain": run.learned_gain, "true_gain": run.true_gain}
    if timed < 2:  # A's own optimal scale fits one timed command exactly: no action error to show
        out |= {"action_rms": None, "action_best_rms": None}
    if timed == 0:
        return out, f"{sensor}; action and gain {NOT_TIMED}"
    action = f"action RMS {sc.action_rms:.4g} {data.position_unit}/s" if timed >= 2 else "action RMS not scored"
    return out, (
        f"{sensor}, {action}, gain {run.learned_gain:.4f} (truth {run.true_gain:.4f}), consistency {sc.consistency:.3f}"
    )
