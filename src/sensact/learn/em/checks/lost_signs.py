"""Signs, without ground truth, that EM lost the robot or that the action family does not fit it
(beyond the thesis).

From a poor start EM can settle in a basin where the smoothed path keeps far from the landmarks and
each channel's polynomial f bends to map the readings onto the wrong distances. A range sensor's f
rises (or falls) with distance; one that turns over within the distances it was fitted on is not a
sensor, it is f absorbing a wrong path. On MRCLAM Dataset 6 cut into quarters every fit that lost
its robot by metres had such an f, and none that found it (docs/em-real.md, "Short logs").
A channel that reads a length in the map's own unit gives a second sign: its f may be off by a scale,
but the scale does not change with distance, so an f whose slope does is bent by a wrong path.
A third sign needs no channel: EM at a model that fits its log moves little from it, so each iteration
after the best stays close to the best's likelihood; one that keeps falling far below it again and again
has not settled anywhere (``unsettled_fit``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.learn.em.config import EMConfig, SearchSettings
from sensact.learn.em.estep import Posteriors
from sensact.learn.em.result import (
    FunctionBends,
    FunctionTurns,
    LostSign,
    Unsettled,
    fall_per_sighting,
    smoothed_distances,
)
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

DISTANCE_PERCENTILES = (2.0, 98.0)  # the fitted distances, their few extremes left out
LENGTH_SUFFIX = "_mm"  # a reading in the map's unit, as sensact names one (io/timed_csv.py: range_m -> range_mm)
# learned sideways over forward Sigma_m sd above which a held sideways mean is suspect: 1.0-1.5 on MRCLAM's
# five robots and 1.1 on simulated ones; 3.2 on a simulated side-stepper held to no sideways mean
# (docs/em-real.md, "A robot that can side-step")
SIDEWAYS_NOISE_RATIO = 2.0


def _fitted_distances(
    model: EMModel, post: Posteriors, data: LandmarkLog, dist: np.ndarray | None = None
) -> list[tuple[Any, tuple[float, float]]]:
    """``fitted_distances`` on a planar log (the lost-fit signs); none on a track."""
    return fitted_distances(model, post, data, dist) if data.geometry.has_heading else []


def fitted_distances(
    model: EMModel, post: Posteriors, data: LandmarkLog, dist: np.ndarray | None = None
) -> list[tuple[Any, tuple[float, float]]]:
    """Each channel with the span (``DISTANCE_PERCENTILES``) of the distances, from the smoothed path, of
    the sightings it used within its window (``dist``: ``result.smoothed_distances``, when already taken);
    channels with fewer than two are left out."""
    if not data.n_observations:
        return []
    use = np.asarray(post.obs_used, dtype=bool)
    dist = smoothed_distances(model, post, data) if dist is None else dist
    readings = data.obs_readings[use][:, model.sensor.columns(data)]
    out = []
    for j, ch in enumerate(model.sensor.channels):
        d = dist[np.isfinite(readings[:, j])]
        d = d[(d >= ch.valid_min) & (d <= ch.valid_max)]  # f applies within the window only
        if d.size >= 2:
            lo, hi = np.percentile(d, DISTANCE_PERCENTILES)
            out.append((ch, (float(lo), float(hi))))
    return out


def _turns(fitted: list[tuple[Any, tuple[float, float]]]) -> list[LostSign]:
    turned: list[LostSign] = []
    for ch, (lo, hi) in fitted:
        turns = ch.function.turning_points(lo, hi)
        if turns.size:
            turned.append(FunctionTurns(ch.name, turns_at_mm=tuple(turns.tolist()), distances_mm=(lo, hi)))
    return turned


def _bends(fitted: list[tuple[Any, tuple[float, float]]], bend_ratio: float) -> list[LostSign]:
    bent: list[LostSign] = []
    for ch, (lo, hi) in fitted:
        if not ch.name.endswith(LENGTH_SUFFIX):
            continue
        least, greatest = ch.function.slope_range(lo, hi)
        if least * greatest <= 0:  # it turns or goes flat: not a bend
            continue
        if max(abs(least), abs(greatest)) > bend_ratio * min(abs(least), abs(greatest)):
            bent.append(FunctionBends(ch.name, slopes=(least, greatest), distances_mm=(lo, hi)))
    return bent


def range_function_turns(model: EMModel, post: Posteriors, data: LandmarkLog) -> list[LostSign]:
    """Each channel of a planar log whose learned f turns over inside the distances of the sightings it
    used (from the smoothed path): its name, the distances where it turns and the distances' span."""
    return _turns(_fitted_distances(model, post, data))


def range_function_bends(
    model: EMModel, post: Posteriors, data: LandmarkLog, bend_ratio: float = SearchSettings.lost_bend_ratio
) -> list[LostSign]:
    """Each channel of a planar log that reads a length in the map's unit (its name ends in ``_mm``)
    whose learned f's slope over the distances of the sightings it used (from the smoothed path) changes
    by more than ``bend_ratio`` times (``SearchSettings.lost_bend_ratio``) without turning over: its name, the
    least and greatest slope and the distances' span. A sensor off by a scale has one slope; one that turns is
    ``range_function_turns``'s."""
    return _bends(_fitted_distances(model, post, data), bend_ratio)


def unsettled_fit(
    loglik_history: np.ndarray, best_iteration: int, n_used: int, limit: float = SearchSettings.lost_fall_per_sighting
) -> list[LostSign]:
    """``[Unsettled(...)]`` when the iterations after the best fell on average more than
    ``limit`` log-units per sighting used below the best's likelihood
    (``fall_per_sighting``; the sign holds the best iteration, how many followed it, the mean fall and the
    fall per sighting); else ``[]``, also when no iteration followed the best."""
    per = fall_per_sighting(loglik_history, best_iteration, n_used)
    if per is None or per <= limit:
        return []
    after = int(np.size(loglik_history) - best_iteration - 1)
    return [
        Unsettled(best_iteration=int(best_iteration), iterations_after=after, mean_fall=per * n_used, per_sighting=per)
    ]


def lost_fit_signs(
    model: EMModel,
    post: Posteriors,
    data: LandmarkLog,
    loglik_history: np.ndarray | None = None,
    best_iteration: int = 0,
    config: EMConfig | None = None,
    *,
    dist: np.ndarray | None = None,
) -> list[LostSign]:
    """Every channel whose f turns over (``sign`` "turns") or bends ("bends") within its fitted
    distances, and with the fit's ``loglik_history`` on a planar log, ``unsettled_fit``'s sign (it names
    no channel): the signs, without ground truth, that EM lost the robot, by ``config``'s thresholds
    (``lost_bend_ratio``, ``lost_fall_per_sighting``; by default EMConfig's); ``dist``: the sightings'
    smoothed distances, when already taken."""
    cfg = config or EMConfig()
    fitted = _fitted_distances(model, post, data, dist)
    signs = _turns(fitted) + _bends(fitted, cfg.search.lost_bend_ratio)
    if loglik_history is not None and data.geometry.has_heading:
        used = int(np.count_nonzero(post.obs_used))
        signs += unsettled_fit(loglik_history, best_iteration, used, cfg.search.lost_fall_per_sighting)
    return signs


def describe_lost_fit(signs: list[LostSign], advice: bool = True) -> str:
    """One line for the user: which f turned over or bent where, what it likely means and (``advice``)
    what to try."""
    parts = [_describe_sign(t) for t in signs]
    why = []
    if any(isinstance(t, FunctionTurns) for t in signs):
        why.append("A range sensor's f does not turn")
    if any(isinstance(t, FunctionBends) for t in signs):
        why.append("A reading in the map's unit may be off by a scale, but not by one that changes with distance")
    if any(isinstance(t, Unsettled) for t in signs):
        why.append("EM at a model that fits the log moves little from it")
    line = "warning: " + "; ".join(parts) + ". " + "; ".join(why) + ": EM has probably lost the robot"
    if not advice:
        return line + "."
    return (
        line + " (a local optimum). Try a longer log, a smaller start_sigma for the channel (or more "
        "turn_restarts) in --config (docs/em-real.md, Short logs), or --start-from a model learned on a "
        "robot like it."
    )


def _describe_sign(t: LostSign) -> str:
    if isinstance(t, Unsettled):
        return (
            f"in the {t.iterations_after} iterations after its best one ({t.best_iteration}) EM's "
            f"log-likelihood stayed on average {t.mean_fall:.0f} below the best ({t.per_sighting:.2f} a sighting)"
        )
    if isinstance(t, FunctionTurns):
        shape = f"{t.channel}'s f turns over at {', '.join(f'{x:.0f}' for x in t.turns_at_mm)} mm"
    else:
        shape = f"{t.channel}'s f has slopes from {t.slopes[0]:.2f} to {t.slopes[1]:.2f} mm per mm"
    return shape + f", inside the {t.distances_mm[0]:.0f}-{t.distances_mm[1]:.0f} mm it was fitted on"


def held_sideways_noise(model: EMModel, motion_noise: str) -> dict[str, float] | None:
    """The learned sideways and forward Sigma_m sds when the action model holds the sideways mean at 0
    (``action_zero_mean``) and the sideways one is over ``SIDEWAYS_NOISE_RATIO`` times the other: a robot
    that side-steps, whose side-steps the model cannot make, so the M-step reads them as motion noise.
    The action bars cannot show it, since From-Truth is fitted in the same family. None when Sigma_m was
    not learned (``motion_noise`` ``fixed``: its sds are the config's)."""
    held = "v_x_mm_s" in getattr(model.action, "zero_mean", ())
    if motion_noise == "fixed" or not model.geometry.has_heading or model.motion_sd.shape[0] != 1 or not held:
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


# beyond this lag-1 autocorrelation (either sign) of a channel's smoothed residuals, its errors are not
# independent from one reading to the next as eq. 4.19 assumes. Above it EM reads the shared part as motion
# and the sigma it learns is a lower bound (a real 1-D robot's laser at 0.97 learned a sigma 10x
# too small); below minus it the path follows the readings, each error undone by the next (a real robot's
# bearings at -0.38 raised no warning at 0.5).
AUTOCORRELATION_WARN = 0.3
# above this share of the sightings pruned by the gates, the gate is doing more than dropping outliers
PRUNED_WARN = 0.2


def residual_autocorrelation(model: EMModel, post: Posteriors, data: LandmarkLog) -> dict[str, float | None]:
    """The lag-1 autocorrelation of each channel's residuals about the smoothed path (the reading minus
    its prediction from the sensor at the smoothed mean pose, times the square root of the reading's
    E-step weight, so that a robust channel's outliers count as little as they did in the fit), over the
    readings the E-step used, in time order; the bearing's under ``"bearing"``. None where fewer than 10
    readings were used."""
    rows = np.flatnonzero(post.obs_used)
    out: dict[str, float | None] = {}
    if rows.size == 0:
        return out
    predicted = model.sensor.predict(post.mean_gamma[data.obs_step[rows]], data, rows)
    readings = model.sensor.readings_of(data)[0][rows]
    bearings = data.obs_bearing_rad[rows]
    for j, ch in enumerate(model.sensor.channels):
        w = post.weights[rows, j]
        use = w > 0
        out[ch.name] = _lag1(np.sqrt(w[use]) * (readings[use, j] - predicted[use, j]))
    if model.sensor.reads_bearing and data.geometry.has_heading:
        w = post.weights[rows, -1]
        use = w > 0
        out["bearing"] = _lag1(np.sqrt(w[use]) * wrap_angle(bearings[use] - predicted[use, -1]))
    return out


def _lag1(e: np.ndarray) -> float | None:
    e = np.asarray(e, dtype=float)
    e = e[np.isfinite(e)]
    if e.size < 10:
        return None
    e = e - e.mean()
    den = float(np.dot(e, e))
    return float(np.dot(e[:-1], e[1:]) / den) if den > 0 else None


def describe_correlated(autocorrelation: dict[str, float | None]) -> list[str]:
    """A warning for each channel whose residuals' lag-1 autocorrelation is beyond +-``AUTOCORRELATION_WARN``."""
    out = []
    for name, r in autocorrelation.items():
        if r is not None and r > AUTOCORRELATION_WARN:
            out.append(
                f"{name}'s residuals about the smoothed path have a lag-1 autocorrelation of {r:.2f} (above "
                f"{AUTOCORRELATION_WARN}): reading errors persist from one reading to the next, in this channel or "
                "in another whose error the path follows as motion; eq. 4.19 takes them as independent, so the "
                "learned sigmas are lower bounds on the sensors' noise"
            )
        elif r is not None and r < -AUTOCORRELATION_WARN:
            out.append(
                f"{name}'s residuals about the smoothed path have a lag-1 autocorrelation of {r:.2f} (below "
                f"-{AUTOCORRELATION_WARN}): each error is undone by the next, so the path follows these readings "
                "(too little motion noise, or a wrong mount or delay) or the sensor's errors alternate; either "
                "way its learned sigma is not the sensor's noise"
            )
    return out


def describe_pruned(fraction: float, setting: str = "prune_rad_per_step") -> str | None:
    """A warning when the gates dropped more than ``PRUNED_WARN`` of the sightings."""
    if fraction <= PRUNED_WARN:
        return None
    return (
        f"{100 * fraction:.0f} % of the sightings were pruned as outliers (above {100 * PRUNED_WARN:.0f} %): the "
        f"first iteration's bearing gate is dropping more than outliers; a start far off, or a sensor mount that "
        f"turns the bearings, does this. Loosen it with --set {setting}=... (0 turns it off)"
    )
