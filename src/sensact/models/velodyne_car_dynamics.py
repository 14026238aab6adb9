"""The car's action model (eqs. 2.30, 2.31; sec. 5.3): ``a = C5 + C6 g + C7 v + C8 v b`` and
``omega = C9 v + C10 v s``, and the prediction by eq. 5.5 from the actions alone."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sensact.errors import ModelFormatError
from sensact.records import JsonObject


@dataclass(frozen=True)
class CarDynamics:
    C5: float
    C6: float
    C7: float
    C8: float
    C9: float
    C10: float

    def as_array(self) -> np.ndarray:
        return np.array([self.C5, self.C6, self.C7, self.C8, self.C9, self.C10])

    def accel(self, v: np.ndarray, g: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self.C5 + self.C6 * g + self.C7 * v + self.C8 * v * b  # eq. 5.3

    def omega(self, v: np.ndarray, s: np.ndarray) -> np.ndarray:
        return self.C9 * v + self.C10 * v * s  # eq. 5.4

    def predict(self, actions: np.ndarray, v0: float, dt_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run the model on the actions (K, 3) = (g, b, s): ``(v, a, omega)`` per step, eq. 5.5 first."""
        K = len(actions)
        v = np.empty(K)
        a = np.empty(K)
        v[0] = v0
        for k in range(K):
            a[k] = self.accel(v[k], actions[k, 0], actions[k, 1])
            if k + 1 < K:
                v[k + 1] = v[k] + a[k] * dt_s
        return v, a, self.omega(v, actions[:, 2])

    def to_dict(self) -> JsonObject:
        return {"kind": "car_dynamics", **asdict(self)}

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> CarDynamics:
        try:
            if data.get("kind") != "car_dynamics":
                raise KeyError("kind")
            return cls(*(float(data[k]) for k in ("C5", "C6", "C7", "C8", "C9", "C10")))
        except (KeyError, TypeError, ValueError, AttributeError):
            raise ModelFormatError(
                "not a car dynamics model.",
                file=source,
                field="kind",
                fix="give a model written by `sensact learn car`.",
            ) from None


def fit_car_dynamics(v: np.ndarray, a: np.ndarray, omega: np.ndarray, actions: np.ndarray) -> CarDynamics:
    """Least squares on eq. 5.3 (C5..C8) and on eq. 5.4 (C9, C10), sec. 5.3."""
    g, b, s = actions[:, 0], actions[:, 1], actions[:, 2]
    Xa = np.column_stack([np.ones_like(v), g, v, v * b])
    ca, *_ = np.linalg.lstsq(Xa, a, rcond=None)
    Xw = np.column_stack([v, v * s])
    cw, *_ = np.linalg.lstsq(Xw, omega, rcond=None)
    return CarDynamics(*(float(x) for x in np.r_[ca, cw]))
