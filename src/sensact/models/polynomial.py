"""A one-dimensional polynomial model: the chapter-3 sensor model ``S(o)`` and action model ``A(c)``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensact.core.polyfit import affine_basis_matrix, polyval
from sensact.errors import ModelFormatError
from sensact.records import JsonObject


@dataclass(frozen=True)
class Polynomial1D:
    """``p(x) = sum_i coef[i] * u**i`` with ``u = (x - center) / scale``.

    The normalized variable keeps the fit well conditioned; ``power_coefficients()`` gives the same
    polynomial in plain powers of ``x`` for people and other tools.
    """

    coef: tuple[float, ...]
    center: float = 0.0
    scale: float = 1.0
    input_name: str = "x"
    input_unit: str = ""
    output_unit: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "coef", tuple(float(c) for c in self.coef))
        if len(self.coef) == 0:
            raise ValueError("a polynomial needs at least one coefficient")
        if not self.scale > 0:
            raise ValueError("scale must be > 0")

    @property
    def degree(self) -> int:
        return len(self.coef) - 1

    def __call__(self, x: np.ndarray | float) -> np.ndarray:
        return polyval(np.asarray(self.coef), (np.asarray(x, dtype=float) - self.center) / self.scale)

    def power_coefficients(self) -> np.ndarray:
        """Ascending coefficients of the same polynomial in powers of ``x`` itself."""
        M = affine_basis_matrix(self.degree, 1.0 / self.scale, -self.center / self.scale)
        return M.T @ np.asarray(self.coef)

    def is_finite(self) -> bool:
        return bool(np.all(np.isfinite(self.coef)))

    def slope(self, x: np.ndarray | float) -> np.ndarray:
        """``dp/dx`` at ``x``."""
        der = np.polynomial.polynomial.polyder(np.asarray(self.coef))
        return polyval(der, (np.asarray(x, dtype=float) - self.center) / self.scale) / self.scale

    def slope_range(self, lo: float, hi: float) -> tuple[float, float]:
        """The least and the greatest ``dp/dx`` over ``[lo, hi]``: at an end, or where the slope itself turns."""
        curvature = np.polynomial.polynomial.polyder(np.asarray(self.coef), 2)
        x = [lo, hi]
        if curvature.size and np.any(curvature):
            roots = np.polynomial.polynomial.polyroots(np.trim_zeros(curvature, "b"))
            real = roots.real[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))]
            x += [float(v) for v in self.center + self.scale * real if lo < v < hi]
        slopes = self.slope(np.array(x))
        return float(slopes.min()), float(slopes.max())

    def turning_points(self, lo: float, hi: float) -> np.ndarray:
        """The ``x`` strictly inside ``(lo, hi)`` where ``p`` turns (its slope changes sign), ascending."""
        slope = np.polynomial.polynomial.polyder(np.asarray(self.coef))
        if slope.size < 2 or not np.any(slope[1:]):
            return np.empty(0)
        roots = np.polynomial.polynomial.polyroots(np.trim_zeros(slope, "b"))
        u = np.sort(roots.real[np.abs(roots.imag) <= 1e-9 * np.maximum(1.0, np.abs(roots.real))])
        x = self.center + self.scale * u
        inside = (x > lo) & (x < hi)
        x, u = x[inside], u[inside]
        # a double root touches zero without a turn: the slope's sign either side tells
        eps = 1e-6 * np.maximum(1.0, np.abs(u))
        left = np.polynomial.polynomial.polyval(u - eps, slope)
        right = np.polynomial.polynomial.polyval(u + eps, slope)
        return x[np.sign(left) * np.sign(right) < 0]

    def describe(self, name: str = "p", digits: int = 6) -> str:
        """``p(x) = a0 + a1 x + ...`` in plain powers."""
        terms = []
        for i, c in enumerate(self.power_coefficients()):
            v = f"{c:.{digits}g}"
            terms.append(v if i == 0 else f"{v}·{self.input_name}" + (f"^{i}" if i > 1 else ""))
        return f"{name}({self.input_name}) = " + " + ".join(terms).replace("+ -", "- ")

    def to_dict(self) -> JsonObject:
        return {
            "kind": "polynomial1d",
            "coef": list(self.coef),
            "center": self.center,
            "scale": self.scale,
            "input_name": self.input_name,
            "input_unit": self.input_unit,
            "output_unit": self.output_unit,
            "power_coefficients": self.power_coefficients().tolist(),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> Polynomial1D:
        if not isinstance(data, dict) or data.get("kind") != "polynomial1d":
            raise ModelFormatError(
                "not a polynomial1d model.",
                file=source,
                field="kind",
                fix="give a JSON object written by sensact with kind 'polynomial1d'.",
            )
        try:
            return cls(
                coef=tuple(float(c) for c in data["coef"]),
                center=float(data.get("center", 0.0)),
                scale=float(data.get("scale", 1.0)),
                input_name=str(data.get("input_name", "x")),
                input_unit=str(data.get("input_unit", "")),
                output_unit=str(data.get("output_unit", "")),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad polynomial ({exc}).",
                file=source,
                field="coef",
                fix="coef must be a non-empty list of numbers and scale > 0.",
            ) from None
