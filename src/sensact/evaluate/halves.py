"""How alike the models learned on a log's two halves are (``learn/em/uses/split_halves.py``): no ground truth, the
log against itself.

Each half's model is compared with the whole log's and with the other half's, on the whole log's own
ground: the velocities each predicts for the commands the whole log issued (RMS over its steps, as the
issue's action error is an RMS over the commands used), each channel's f over the distances its
sightings were seen at (from the whole fit's smoothed path), and the noise parameters as ratios.
"""

from __future__ import annotations

import numpy as np

from sensact.learn.em.checks.lost_signs import fitted_distances
from sensact.learn.em.estep import Posteriors
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject

GRID = 50  # distances at which two f are compared, spread evenly over a channel's span


def velocity_difference(a: EMModel, b: EMModel, data: LandmarkLog) -> dict[str, float]:
    """RMS over ``data``'s steps of the difference of the two models' mean velocities: on a plane the
    translation (its x and y together, mm/s) and the rotation (rad/s); on a track the velocity."""
    e = a.action.step_velocity(data) - b.action.step_velocity(data)
    if data.geometry.has_heading:
        return {
            "translation_mm_s": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))),
            "rotation_rad_s": float(np.sqrt(np.mean(e[:, 2] ** 2))),
        }
    return {"velocity_mm_s": float(np.sqrt(np.mean(e[:, 0] ** 2)))}


def f_difference(a: EMModel, b: EMModel, spans: dict[str, tuple[float, float]]) -> dict[str, float]:
    """Each channel's RMS difference of the two f (in the reading's unit, at no bearing) over its span."""
    out = {}
    for ca, cb in zip(a.sensor.channels, b.sensor.channels, strict=True):
        if ca.name in spans:
            d = np.linspace(*spans[ca.name], GRID)
            out[ca.name] = float(np.sqrt(np.mean((ca.function(d) - cb.function(d)) ** 2)))
    return out


def noise(model: EMModel) -> dict[str, float]:
    """The model's noise parameters by name: each channel's sigma, the bearing's, and Sigma_m's standard
    deviations per step (shared noise only; per action there is one row an action)."""
    out = {f"{c.name} sigma": float(c.sigma) for c in model.sensor.channels}
    if model.sensor.reads_bearing:
        out["bearing sigma"] = float(model.sensor.sigma_bearing_rad)
    if model.motion_sd is not None and len(model.motion_sd) == 1:
        names = [n.split("_")[0] for n in model.geometry.state_names]
        out.update({f"Sigma_m {n} sd": float(s) for n, s in zip(names, model.motion_sd[0], strict=True)})
    return out


def compare_halves(whole: EMModel, first: EMModel, second: EMModel, post: Posteriors, data: LandmarkLog) -> JsonObject:
    """The halves' models against each other and against ``whole`` (learned on ``data``, ``post`` its
    smoothed posteriors): velocity and f differences, and the noise parameters with the halves' ratio
    (the larger over the smaller, so 1 is alike)."""
    spans = {ch.name: span for ch, span in fitted_distances(whole, post, data)}
    # a channel that read nothing within its window kept its starting sigma: nothing to compare
    unread = {f"{c.name} sigma" for c in whole.sensor.channels if c.name not in spans}
    noises = [{k: v for k, v in noise(m).items() if k not in unread} for m in (whole, first, second)]
    ratios = {
        k: max(noises[1][k], noises[2][k]) / min(noises[1][k], noises[2][k])
        for k in noises[0]
        if min(noises[1][k], noises[2][k]) > 0
    }
    delays = [
        None if getattr(m.action, "delay_steps", None) is None else m.action.delay_steps * data.dt_s
        for m in (whole, first, second)
    ]
    return {
        "velocity": {
            "first_vs_whole": velocity_difference(first, whole, data),
            "second_vs_whole": velocity_difference(second, whole, data),
            "first_vs_second": velocity_difference(first, second, data),
        },
        "f": {
            "spans": {k: list(v) for k, v in spans.items()},
            "first_vs_whole": f_difference(first, whole, spans),
            "second_vs_whole": f_difference(second, whole, spans),
            "first_vs_second": f_difference(first, second, spans),
        },
        "noise": {"whole": noises[0], "first": noises[1], "second": noises[2], "halves_ratio": ratios},
        "delay_s": {"whole": delays[0], "first": delays[1], "second": delays[2]},
    }
