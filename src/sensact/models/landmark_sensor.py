"""The landmark sensor model of eq. 4.19: beacon height ``f(dist) + N(0, sigma_1^2)`` and bearing
``ang + N(0, sigma_2^2)``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sensact.errors import ModelFormatError
from sensact.models.polynomial import Polynomial1D


@dataclass(frozen=True)
class LandmarkSensor:
    height: Polynomial1D  # f: distance -> beacon height in px
    sigma_height_px: float
    sigma_bearing_rad: float | None = None  # None when the sensor reports no bearing (1-D)

    def __post_init__(self) -> None:
        if not self.sigma_height_px > 0:
            raise ValueError("sigma_height_px must be > 0")
        if self.sigma_bearing_rad is not None and not self.sigma_bearing_rad > 0:
            raise ValueError("sigma_bearing_rad must be > 0")

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "landmark_sensor",
            "height": self.height.to_dict(),
            "sigma_height_px": self.sigma_height_px,
            "sigma_bearing_rad": self.sigma_bearing_rad,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "model") -> LandmarkSensor:
        if not isinstance(data, dict) or data.get("kind") != "landmark_sensor":
            raise ModelFormatError(
                "not a landmark sensor model.", file=source, field="kind", fix="give a model written by sensact."
            )
        try:
            sb = data.get("sigma_bearing_rad")
            return cls(
                Polynomial1D.from_dict(data["height"], source=source),
                float(data["sigma_height_px"]),
                None if sb is None else float(sb),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad landmark sensor ({exc}).", file=source, field="sigma_height_px", fix="sigmas must be > 0."
            ) from None
