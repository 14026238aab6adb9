"""Everything chapter 4's EM learns, ``lambda`` (sec. 4.1): action table, sensor model and the prior
``pi(w_0)`` over the first state."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from sensact.errors import ModelFormatError
from sensact.models.action_table import ActionTable
from sensact.models.landmark_sensor import LandmarkSensor

Geometry = Literal["planar", "track"]


@dataclass(frozen=True, eq=False)
class EMModel:
    geometry: Geometry  # "planar": w = (x, y, theta); "track": w = distance to the beacon
    action: ActionTable
    sensor: LandmarkSensor
    prior_mean: np.ndarray  # (n,)
    prior_cov: np.ndarray  # (n, n)

    def __post_init__(self) -> None:
        n = 3 if self.geometry == "planar" else 1
        m = np.asarray(self.prior_mean, dtype=float).reshape(n)
        P = np.asarray(self.prior_cov, dtype=float).reshape(n, n)
        object.__setattr__(self, "prior_mean", m)
        object.__setattr__(self, "prior_cov", P)
        if self.action.velocities.shape[1] != n:
            raise ValueError(f"a {self.geometry} model needs {n} velocity components per action")

    def replace(self, **changes: Any) -> EMModel:
        fields = {k: getattr(self, k) for k in ("geometry", "action", "sensor", "prior_mean", "prior_cov")}
        fields.update(changes)
        return EMModel(**fields)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "em_model",
            "geometry": self.geometry,
            "action": self.action.to_dict(),
            "sensor": self.sensor.to_dict(),
            "prior_mean": self.prior_mean.tolist(),
            "prior_cov": self.prior_cov.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "model") -> EMModel:
        if not isinstance(data, dict) or data.get("kind") != "em_model":
            raise ModelFormatError(
                "not an EM model.", file=source, field="kind", fix="give a model.json written by `sensact learn em`."
            )
        try:
            return cls(
                data["geometry"],
                ActionTable.from_dict(data["action"], source=source),
                LandmarkSensor.from_dict(data["sensor"], source=source),
                np.asarray(data["prior_mean"], dtype=float),
                np.asarray(data["prior_cov"], dtype=float),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad EM model ({exc}).", file=source, field="prior_mean", fix="rewrite it with `sensact learn em`."
            ) from None
