"""Everything chapter 4's EM learns, ``lambda`` (sec. 4.1): action model, sensor model, the prior
``pi(w_0)`` over the first state and the motion noise ``Sigma_m``.

The thesis holds ``Sigma_m`` fixed; here it is part of the model so that it can be learned (the future
work of sec. 4.4.1). ``motion_sd`` has one row (shared) or one row per action (per-action noise), each
the robot-frame standard deviations per time step. ``turn_var`` lets a shared Sigma_m's heading
variance grow with the turn rate: wheels slip in turns, and MRCLAM's Vicon shows a heading that drifts
4-9 times more while turning than at rest.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.core.geometry import PLANAR, TRACK, Geometry, geometry_named
from sensact.errors import ModelFormatError
from sensact.models.action_model import ActionModel
from sensact.models.action_table import ActionTable
from sensact.models.landmark_map import LandmarkMap
from sensact.models.landmark_sensor import MAX_SIGMA, LandmarkSensor
from sensact.models.linear_action import LinearActionModel
from sensact.records import JsonObject

# the robot-frame velocities a planar model moves by (sideways, forward, turn; theta = 0 faces +y) and a track's
PLANAR_VELOCITY_NAMES = PLANAR.velocity_names
TRACK_VELOCITY_NAMES = TRACK.velocity_names


# the action models a model.json may hold, by the "kind" each writes
ACTION_KINDS: dict[str, type[ActionModel]] = {"linear_action_model": LinearActionModel, "action_table": ActionTable}


def action_from_dict(data: JsonObject, *, source: str) -> ActionModel:
    kind = data.get("kind") if isinstance(data, dict) else None
    return ACTION_KINDS.get(kind, ActionTable).from_dict(data, source=source)


@dataclass(frozen=True, eq=False)
class EMModel:
    geometry: Geometry  # "planar": w = (x, y, theta); "track": w = distance to the beacon
    action: ActionModel
    sensor: LandmarkSensor
    prior_mean: np.ndarray  # (n,)
    prior_cov: np.ndarray  # (n, n)
    motion_sd: np.ndarray | None = None  # (1, n) shared or (A, n) per action; None = the thesis's
    # heading variance per step added per rad/s of the model's own turn rate |A(c_t)_theta|, on top of
    # motion_sd's (planar, shared Sigma_m); None = Sigma_m does not depend on turning (the thesis)
    turn_var: float | None = None
    # the landmarks' positions EM learns with the models (docs/map.md); None = the log's surveyed map
    landmarks: LandmarkMap | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "geometry", geometry_named(self.geometry))
        n = self.geometry.n
        m = np.asarray(self.prior_mean, dtype=float).reshape(n)
        P = np.asarray(self.prior_cov, dtype=float).reshape(n, n)
        object.__setattr__(self, "prior_mean", m)
        object.__setattr__(self, "prior_cov", P)
        if len(self.action.velocity_names) != n:
            raise ValueError(f"a {self.geometry} model needs {n} velocity components per action")
        sd = self.geometry.thesis_motion_sd if self.motion_sd is None else self.motion_sd
        sd = np.atleast_2d(np.asarray(sd, dtype=float))
        if sd.shape[1] != n or not np.all((sd > 0) & (sd <= MAX_SIGMA)):  # NaN fails both
            raise ValueError(f"motion_sd needs rows of {n} positive standard deviations, each at most {MAX_SIGMA:g}")
        if sd.shape[0] not in (1, self.action.noise_groups):
            raise ValueError("motion_sd needs one row (shared) or one row per action of the table")
        object.__setattr__(self, "motion_sd", sd)
        if self.turn_var is not None:
            if not self.geometry.has_heading or sd.shape[0] != 1:
                raise ValueError("turn_var needs a planar model with one shared motion_sd row")
            if not (np.isfinite(self.turn_var) and self.turn_var >= 0):
                raise ValueError("turn_var must be >= 0")
            object.__setattr__(self, "turn_var", float(self.turn_var))

    @property
    def per_action_noise(self) -> bool:
        return self.motion_sd.shape[0] > 1

    def replace(self, **changes: Any) -> EMModel:
        names = ("geometry", "action", "sensor", "prior_mean", "prior_cov", "motion_sd", "turn_var", "landmarks")
        fields = {k: getattr(self, k) for k in names}
        fields.update(changes)
        return EMModel(**fields)

    def to_dict(self) -> JsonObject:
        return {
            "kind": "em_model",
            "geometry": self.geometry.name,
            "action": self.action.to_dict(),
            "sensor": self.sensor.to_dict(),
            "prior_mean": self.prior_mean.tolist(),
            "prior_cov": self.prior_cov.tolist(),
            "motion_sd": self.motion_sd.tolist(),
            "turn_var": self.turn_var,
            **({} if self.landmarks is None else {"landmarks": self.landmarks.to_arrays()}),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> EMModel:
        if not isinstance(data, dict) or data.get("kind") != "em_model":
            raise ModelFormatError(
                "not an EM model.", file=source, field="kind", fix="give a model.json written by `sensact learn em`."
            )
        try:
            prior_mean = np.asarray(data["prior_mean"], dtype=float)
            prior_cov = np.asarray(data["prior_cov"], dtype=float)
            if not (np.all(np.isfinite(prior_mean)) and prior_cov.ndim == 2 and _positive_definite(prior_cov)):
                raise ValueError("prior_mean must be finite and prior_cov a symmetric positive-definite matrix")
            return cls(
                data["geometry"],
                action_from_dict(data["action"], source=source),
                LandmarkSensor.from_dict(data["sensor"], source=source),
                prior_mean,
                prior_cov,
                None if data.get("motion_sd") is None else np.asarray(data["motion_sd"], dtype=float),
                None if data.get("turn_var") is None else float(data["turn_var"]),
                None if data.get("landmarks") is None else LandmarkMap.from_arrays(data["landmarks"]),
            )
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise ModelFormatError(
                f"bad EM model ({exc}).", file=source, field="prior_mean", fix="rewrite it with `sensact learn em`."
            ) from None


def _positive_definite(P: np.ndarray) -> bool:
    if not (np.all(np.isfinite(P)) and np.allclose(P, P.T)):
        return False
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return True
