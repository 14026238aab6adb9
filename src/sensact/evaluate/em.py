"""Scoring chapter 4's learned models against the truth (secs. 4.4.2 and 4.4.3).

In 2-D the landmark map fixes the units, so velocities and sigmas compare directly. In 1-D nothing
does: the learned state is some ``x = k_s d + b`` of the true distance, and the learned velocities are
in the same unknown unit. As in sec. 3.3.2 the learned models are compared after the optimal scale:
the action table after ``k_a``, the sensor ``f`` after the map ``d -> k_s d + b`` that fits best. The
ratio ``k_a / k_s`` is 1 when the two learned models agree on their unit (sec. 4.4.3).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from sensact.evaluate.scaled import fit_scale
from sensact.models.em_model import EMModel
from sensact.models.polynomial import Polynomial1D


def component_rms(learned: np.ndarray, true: np.ndarray) -> np.ndarray:
    """RMS over actions of each velocity component (the thesis's v_x, v_y, v_theta errors)."""
    return np.sqrt(np.mean((np.asarray(learned) - np.asarray(true)) ** 2, axis=0))


def score_planar(
    model: EMModel,
    true_velocities: np.ndarray,
    true_height: Any,
    sigma_height_px: float,
    sigma_bearing_rad: float,
    distance_range_mm: tuple[float, float] = (1275.0, 4175.0),
) -> dict[str, float]:
    """The field2d numbers of sec. 4.4.2."""
    rms = component_rms(model.action.velocities, true_velocities)
    d = np.linspace(*distance_range_mm, 59)
    ranges = np.ptp(true_velocities, axis=0)
    sb = model.sensor.sigma_bearing_rad
    return {
        "vx_rms_mm_s": float(rms[0]),
        "vy_rms_mm_s": float(rms[1]),
        "vtheta_rms_rad_s": float(rms[2]),
        "vx_rms_pct": float(100 * rms[0] / ranges[0]),
        "vy_rms_pct": float(100 * rms[1] / ranges[1]),
        "vtheta_rms_pct": float(100 * rms[2] / ranges[2]),
        "velocity_ranges": [float(r) for r in ranges],
        "sensor_rms_px": float(np.sqrt(np.mean((model.sensor.height(d) - true_height(d)) ** 2))),
        "sigma1_learned": float(model.sensor.sigma_height_px),
        "sigma1_true": float(sigma_height_px),
        "sigma1_error_pct": float(100 * abs(model.sensor.sigma_height_px / sigma_height_px - 1)),
        "sigma2_learned": float(sb) if sb is not None else float("nan"),
        "sigma2_true": float(sigma_bearing_rad),
        "sigma2_error_pct": float(100 * abs(sb / sigma_bearing_rad - 1)) if sb is not None else float("nan"),
    }


@dataclass(frozen=True)
class DistanceMap:
    """``x = scale * d + offset``: how the learned state relates to the true distance."""

    scale: float
    offset: float
    rms_px: float


def fit_distance_map(f_learned: Polynomial1D, f_true: Any, distances: np.ndarray) -> DistanceMap:
    """``argmin_{k, b} RMS_d [f_learned(k d + b) - f_true(d)]``.

    Started from inverting the learned f on a dense grid (for each true height the nearest learned
    state), then refined by nonlinear least squares.
    """
    d = np.asarray(distances, dtype=float)
    h = np.asarray(f_true(d), dtype=float)
    xs = f_learned.center + f_learned.scale * np.linspace(-4, 4, 4001)
    fx = f_learned(xs)
    x_hit = xs[np.abs(fx[None, :] - h[:, None]).argmin(axis=1)]
    k0, b0 = np.polyfit(d, x_hit, 1)

    def resid(p: np.ndarray) -> np.ndarray:
        return f_learned(p[0] * d + p[1]) - h

    sol = least_squares(resid, np.array([k0, b0]), x_scale=np.array([abs(k0) or 1.0, f_learned.scale]))
    return DistanceMap(float(sol.x[0]), float(sol.x[1]), float(np.sqrt(np.mean(sol.fun**2))))


def score_track(
    model: EMModel, true_velocities: np.ndarray, true_height: Any, distances: np.ndarray
) -> dict[str, float]:
    """The em1d numbers of sec. 4.4.3: optimally scaled sensor and action errors and their ratio."""
    v = model.action.velocities[:, 0]
    tv = np.asarray(true_velocities, dtype=float)
    act = fit_scale(v, tv)  # tv ≈ k v, so the learned unit is 1/k of a mm
    dmap = fit_distance_map(model.sensor.height, true_height, distances)
    h_range = float(np.ptp(true_height(np.asarray(distances, dtype=float))))
    k_action = 1.0 / act.scale if act.scale else np.nan  # learned = k_action * true
    return {
        "sensor_rms_px": dmap.rms_px,
        "sensor_rms_pct": 100 * dmap.rms_px / h_range,
        "action_rms_mm_s": act.rms,
        # a robot whose true velocities are all one (it never moved) has no range to take a share of
        "action_rms_pct": 100 * act.rms / float(np.ptp(tv)) if np.ptp(tv) > 0 else float("nan"),
        "scale_ratio": float(k_action / dmap.scale),
        "action_scale": float(k_action),
        "sensor_scale": dmap.scale,
        "height_range_px": h_range,
        "velocity_range_mm_s": float(np.ptp(tv)),
    }
