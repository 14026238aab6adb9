"""Comparing scale-free learned models with measured ones (sec. 3.3.2).

Chapter 3's models are learned in the robot's own unit, so a learned action model is compared after
the least-squares scale ``k`` and a learned sensor model after the least-squares map ``a + b S(o)``.
Consistent models share the unit: ``|k / b| = 1`` (the "consistency" figure ``| |k/b| - 1 |``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sensact.core.polyfit import best_fit_rms
from sensact.models.polynomial import Polynomial1D
from sensact.records import JsonObject


@dataclass(frozen=True)
class ScaleFit:
    scale: float  # k, or b for a sensor model
    offset: float  # 0 for an action model, a for a sensor model
    rms: float


def fit_scale(predicted: np.ndarray, measured: np.ndarray) -> ScaleFit:
    """``k = argmin sum (k p - m)^2`` and the RMS of ``k p - m``."""
    p = np.asarray(predicted, dtype=float)
    m = np.asarray(measured, dtype=float)
    den = float(p @ p)
    if not np.all(np.isfinite(p)) or den == 0.0:
        return ScaleFit(np.nan, 0.0, np.inf)
    k = float(p @ m) / den
    return ScaleFit(k, 0.0, float(np.sqrt(np.mean((k * p - m) ** 2))))


def fit_scale_offset(predicted: np.ndarray, measured: np.ndarray) -> ScaleFit:
    """``(a, b) = argmin sum (a + b p - m)^2`` (a linear regression) and its RMS."""
    p = np.asarray(predicted, dtype=float)
    m = np.asarray(measured, dtype=float)
    if not np.all(np.isfinite(p)) or np.ptp(p) == 0.0:
        return ScaleFit(np.nan, np.nan, np.inf)
    X = np.column_stack([np.ones_like(p), p])
    (a, b), *_ = np.linalg.lstsq(X, m, rcond=None)
    return ScaleFit(float(b), float(a), float(np.sqrt(np.mean((a + b * p - m) ** 2))))


def consistency(action_scale: float, sensor_scale: float) -> float:
    """``| |k / b| - 1 |``: 0 when the two models are learned in the same unit (sec. 3.3.2)."""
    if not (np.isfinite(action_scale) and np.isfinite(sensor_scale)) or sensor_scale == 0.0:
        return np.inf
    return abs(abs(action_scale / sensor_scale) - 1.0)


@dataclass(frozen=True)
class ModelPairScore:
    """How a learned (S, A) pair compares with measured models."""

    sensor_rms: float
    sensor_best_rms: float  # the best any polynomial of S's degree can do on the measured points
    sensor_scale_b: float
    sensor_offset_a: float
    action_rms: float
    action_best_rms: float  # ditto for A
    action_scale_k: float
    consistency: float

    def to_dict(self) -> JsonObject:
        return asdict(self)


def score_models(
    sensor: Polynomial1D,
    action: Polynomial1D,
    *,
    observations: np.ndarray,
    distances: np.ndarray,
    commands: np.ndarray,
    velocities: np.ndarray,
) -> ModelPairScore:
    """Score S on measured (observation, distance) pairs and A on measured (command, velocity) pairs."""
    s = fit_scale_offset(sensor(observations), distances)
    a = fit_scale(action(commands), velocities)
    return ModelPairScore(
        sensor_rms=s.rms,
        sensor_best_rms=best_fit_rms(observations, distances, sensor.degree),
        sensor_scale_b=s.scale,
        sensor_offset_a=s.offset,
        action_rms=a.rms,
        action_best_rms=best_fit_rms(commands, velocities, action.degree),
        action_scale_k=a.scale,
        consistency=consistency(a.scale, s.scale),
    )
