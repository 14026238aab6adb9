"""Signs, without ground truth, that EM lost the robot or that the action family does not fit it
(beyond the thesis).

From a poor start EM can settle in a basin where the smoothed path keeps far from the landmarks and
each channel's polynomial f bends to map the readings onto the wrong distances. A range sensor's f
rises (or falls) with distance; one that turns over within the distances it was fitted on is not a
sensor, it is f absorbing a wrong path. On MRCLAM Dataset 6 cut into quarters every fit that lost
its robot by metres had such an f, and none that found it (docs/em-real-results.md, "Short logs").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sensact.core.pose_models import landmark_distance
from sensact.learn.em.estep import Posteriors, channel_columns
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

DISTANCE_PERCENTILES = (2.0, 98.0)  # the fitted distances, their few extremes left out
# learned sideways over forward Sigma_m sd above which a held sideways mean is suspect: 1.0-1.5 on MRCLAM's
# five robots and 1.1 on simulated ones; 3.2 on a simulated side-stepper held to no sideways mean
# (docs/em-real.md, "A robot that can side-step")
SIDEWAYS_NOISE_RATIO = 2.0


def range_function_turns(model: EMModel, post: Posteriors, data: LandmarkLog) -> list[dict[str, Any]]:
    """Each channel of a planar log whose learned f turns over inside the distances of the sightings it
    used (from the smoothed path): its name, the distances where it turns and the distances' span."""
    if data.geometry != "planar" or not data.n_observations:
        return []
    use = np.asarray(post.obs_used, dtype=bool)
    poses = post.mean_gamma[data.obs_step[use]]
    dist = landmark_distance(poses, data.landmarks_xy[data.obs_landmark[use]])
    turned = []
    readings = data.obs_readings[use][:, channel_columns(model.sensor, data)]
    for j, ch in enumerate(model.sensor.channels):
        d = dist[np.isfinite(readings[:, j])]
        d = d[(d >= ch.valid_min) & (d <= ch.valid_max)]  # f applies within the window only
        if d.size < 2:
            continue
        lo, hi = np.percentile(d, DISTANCE_PERCENTILES)
        turns = ch.function.turning_points(float(lo), float(hi))
        if turns.size:
            turned.append({"channel": ch.name, "turns_at_mm": turns.tolist(), "distances_mm": [float(lo), float(hi)]})
    return turned


def describe_turns(turned: list[dict[str, Any]], advice: bool = True) -> str:
    """One line for the user: which f turned over where, what it likely means and (``advice``) what to try."""
    parts = [
        f"{t['channel']}'s f turns over at {', '.join(f'{x:.0f}' for x in t['turns_at_mm'])} mm, inside the "
        f"{t['distances_mm'][0]:.0f}-{t['distances_mm'][1]:.0f} mm it was fitted on"
        for t in turned
    ]
    line = "warning: " + "; ".join(parts) + ". A range sensor's f does not turn: EM has probably lost the robot"
    if not advice:
        return line + "."
    return (
        line + " (a local optimum). Try a longer log, or a smaller start_sigma for the channel (or more "
        "turn_restarts) in --config (docs/em-real-results.md, Short logs)."
    )


def held_sideways_noise(model: EMModel, motion_noise: str) -> dict[str, float] | None:
    """The learned sideways and forward Sigma_m sds when the action model holds the sideways mean at 0
    (``action_zero_mean``) and the sideways one is over ``SIDEWAYS_NOISE_RATIO`` times the other: a robot
    that side-steps, whose side-steps the model cannot make, so the M-step reads them as motion noise.
    The action bars cannot show it, since From-Truth is fitted in the same family. None when Sigma_m was
    not learned (``motion_noise`` ``fixed``: its sds are the config's)."""
    held = "v_x_mm_s" in getattr(model.action, "zero_mean", ())
    if motion_noise == "fixed" or model.geometry != "planar" or model.motion_sd.shape[0] != 1 or not held:
        return None
    sideways, forward = (float(v) for v in model.motion_sd[0, :2])
    if sideways <= SIDEWAYS_NOISE_RATIO * forward:
        return None
    return {"sideways_mm": sideways, "forward_mm": forward, "ratio": sideways / forward}


def describe_held_sideways(held: dict[str, float]) -> str:
    return (
        f"note: the learned sideways motion noise is {held['ratio']:.1f} times the forward one "
        f"({held['sideways_mm']:.2f} against {held['forward_mm']:.2f} mm a step) while the action model holds "
        "the sideways velocity at 0 (action_zero_mean: [v_x_mm_s]). If the robot can side-step, its side-steps "
        "are read as noise, and the bars cannot tell (From-Truth is fitted in the same family): drop v_x_mm_s "
        'from action_zero_mean (docs/em-real.md, section 2, "A robot that can side-step").'
    )
