"""The landmark sensor model of eq. 4.19, with several reading channels.

The thesis has one reading, the beacon height ``f(dist) + N(0, sigma_1^2)``, and the bearing
``ang + N(0, sigma_2^2)``. A real robot may carry several range-like sensors: each is a
``ReadingChannel`` with its own polynomial ``f_i(dist)``, its own ``sigma_i``, a distance window outside
which its readings say nothing (an IR sensor's curve folds back below its minimum range), and a choice
of likelihood for outliers. Channel 0 of a one-channel sensor is the thesis's model exactly.

A camera that reads range from a landmark's apparent size is distorted away from the image centre: its
reading depends on where in the image the landmark is, not on the distance alone. ``bearing_terms``
``(a_1, .., a_m)`` model that as a relative error that grows with the measured bearing ``b``::

    reading = f(d) + d * (a_1 b + a_2 b^2 + .. + a_m b^m)

which is still linear in every parameter, so the M-step stays a weighted least squares. On MRCLAM it
takes the range residual about the truth from 60-185 mm down to 15-25 mm. The measured bearing is
used, not the predicted one: it is 10x more precise than the bearing changes that matter, and it keeps
the channels independent given the pose. No terms (the default) is the thesis's ``f(d)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from sensact.core.polyfit import vander
from sensact.errors import ModelFormatError
from sensact.models.polynomial import Polynomial1D
from sensact.records import JsonObject

ROBUST_KINDS = ("none", "student_t", "gate")


def check_robust(kind: str, param: float, what: str) -> None:
    if kind not in ROBUST_KINDS:
        raise ValueError(f"{what}: robust must be one of {ROBUST_KINDS}, not {kind!r}")
    if kind != "none" and not param > 0:
        raise ValueError(f"{what}: robust_param (Student-t degrees of freedom or gate in sigmas) must be > 0")


def student_t_params(channels: Sequence[Any], bearing_robust: str, bearing_robust_param: float) -> list[float]:
    """The degrees of freedom of each Student-t reading among ``channels`` (anything with ``robust`` and
    ``robust_param``: a sensor's channels or a config's), then the bearing's."""
    params = [c.robust_param for c in channels if c.robust == "student_t"]
    return params + ([bearing_robust_param] if bearing_robust == "student_t" else [])


def reading_features(
    dist: np.ndarray, bearing: np.ndarray, degree: int, n_terms: int, center: float, scale: float
) -> np.ndarray:
    """The columns a reading is linear in: ``u^0..u^degree`` of ``u = (d - center) / scale`` (f's), then
    ``d b^1..d b^n_terms`` (the bearing terms'). The M-step and From-Truth both regress on these."""
    d = np.asarray(dist, dtype=float)
    b = np.asarray(bearing, dtype=float)
    return np.column_stack([vander((d - center) / scale, degree)] + [d * b**k for k in range(1, n_terms + 1)])


@dataclass(frozen=True)
class ReadingChannel:
    name: str
    function: Polynomial1D  # f_i: distance -> reading
    sigma: float
    valid_min: float = -math.inf  # the reading is used only while the predicted distance is in this window
    valid_max: float = math.inf
    robust: str = "none"  # "none" (Gaussian, the thesis), "student_t" or "gate"
    robust_param: float = 0.0  # degrees of freedom, or the gate in innovation sigmas
    bearing_terms: tuple[float, ...] = ()  # a_1..a_m of the relative error d * sum_k a_k b^k

    def __post_init__(self) -> None:
        object.__setattr__(self, "bearing_terms", tuple(float(a) for a in self.bearing_terms))
        if not self.sigma > 0:
            raise ValueError(f"channel {self.name}: sigma must be > 0")
        if not self.valid_min < self.valid_max:
            raise ValueError(f"channel {self.name}: valid_min must be below valid_max")
        check_robust(self.robust, self.robust_param, f"channel {self.name}")

    def bearing_gain(self, bearing: np.ndarray) -> np.ndarray:
        """``sum_k a_k b^k`` for each measured bearing (0 without bearing terms)."""
        b = np.asarray(bearing, dtype=float)
        out = np.zeros_like(b)
        for a in reversed(self.bearing_terms):
            out = (out + a) * b
        return out

    def predict(self, dist: np.ndarray, bearing: np.ndarray | None = None) -> np.ndarray:
        """The mean reading at ``dist``, seen at the measured ``bearing`` when the channel has terms."""
        d = np.asarray(dist, dtype=float)
        if not self.bearing_terms:
            return self.function(d)
        if bearing is None:
            raise ValueError(f"channel {self.name} has bearing terms: give the measured bearings")
        return self.function(d) + d * self.bearing_gain(bearing)

    def with_solution(self, sol: np.ndarray, center: float, scale: float, n_terms: int) -> ReadingChannel:
        """The channel whose f (in ``(d - center) / scale``, same units) and, when ``n_terms``, bearing
        terms are the coefficients ``sol`` of ``reading_features``."""
        deg = len(sol) - 1 - n_terms
        f = self.function
        f = Polynomial1D(tuple(sol[: deg + 1]), center, scale, f.input_name, f.input_unit, f.output_unit)
        return replace(self, function=f, bearing_terms=tuple(sol[deg + 1 :]) if n_terms else self.bearing_terms)

    def to_dict(self) -> JsonObject:
        return {
            "name": self.name,
            "function": self.function.to_dict(),
            "sigma": self.sigma,
            "valid_min": self.valid_min if math.isfinite(self.valid_min) else None,
            "valid_max": self.valid_max if math.isfinite(self.valid_max) else None,
            "robust": self.robust,
            "robust_param": self.robust_param,
            "bearing_terms": list(self.bearing_terms),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> ReadingChannel:
        lo, hi = data.get("valid_min"), data.get("valid_max")
        return cls(
            str(data["name"]),
            Polynomial1D.from_dict(data["function"], source=source),
            float(data["sigma"]),
            -math.inf if lo is None else float(lo),
            math.inf if hi is None else float(hi),
            str(data.get("robust", "none")),
            float(data.get("robust_param", 0.0)),
            tuple(data.get("bearing_terms", ())),
        )


@dataclass(frozen=True)
class SensorMount:
    """Where a planar sensor sits on the robot: ``forward_mm`` and ``left_mm`` from the point the robot's
    pose tracks, and ``yaw_rad`` counterclockwise from the robot's forward axis. Readings are predicted
    from the sensor's pose (``core.pose_models.sensor_poses``); the zero mount is the thesis's eq. 4.19."""

    forward_mm: float = 0.0
    left_mm: float = 0.0
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("forward_mm", "left_mm", "yaw_rad"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ValueError(f"sensor mount {name} must be finite, not {value}")
            object.__setattr__(self, name, value)

    def as_array(self) -> np.ndarray:
        return np.array([self.forward_mm, self.left_mm, self.yaw_rad])

    @classmethod
    def from_array(cls, values: Sequence[float]) -> SensorMount:
        return cls(*(float(v) for v in values))

    def to_dict(self) -> dict[str, float]:
        return {"forward_mm": self.forward_mm, "left_mm": self.left_mm, "yaw_rad": self.yaw_rad}

    @classmethod
    def from_dict(cls, data: Any) -> SensorMount:
        if data is None:
            return cls()
        return cls(float(data["forward_mm"]), float(data["left_mm"]), float(data["yaw_rad"]))


MIN_SIGMA = 1e-9  # the M-step's floor on every sigma (learn/em/mstep.py)
MAX_SIGMA = 1e9  # limits.MAX_VALUE: beyond it in any unit


@dataclass(frozen=True)
class LandmarkSensor:
    channels: tuple[ReadingChannel, ...]
    sigma_bearing_rad: float | None = None  # None when the sensor reports no bearing (1-D)
    bearing_robust: str = "none"
    bearing_robust_param: float = 0.0
    # a sighting's Student-t readings share one weight, as one multivariate t (core/ekf_smoother.py): a
    # misread barcode spoils all of a sighting's readings at once, so a reading the others show to be
    # false does not count in full because it alone happens to fit
    joint_student_t: bool = False
    mount: SensorMount = SensorMount()  # where every channel's sensor sits on the robot (one physical sensor)

    def __post_init__(self) -> None:
        object.__setattr__(self, "channels", tuple(self.channels))
        if not self.channels:
            raise ValueError("a landmark sensor needs at least one reading channel")
        if self.sigma_bearing_rad is not None and not self.sigma_bearing_rad > 0:
            raise ValueError("sigma_bearing_rad must be > 0")
        check_robust(self.bearing_robust, self.bearing_robust_param, "bearing")
        if self.joint_student_t and len(set(self.student_t_params)) > 1:
            raise ValueError(
                "joint_student_t needs one degrees of freedom for every student_t reading, not "
                f"{sorted(set(self.student_t_params))}"
            )

    @property
    def reads_bearing(self) -> bool:
        """Whether the sensor reports each landmark's bearing (eq. 4.19's second component): a camera
        does, radio anchors and a 1-D ranger do not."""
        return self.sigma_bearing_rad is not None

    @property
    def student_t_params(self) -> list[float]:
        """The degrees of freedom of each Student-t reading, the channels' then the bearing's."""
        return student_t_params(self.channels, self.bearing_robust, self.bearing_robust_param)

    @classmethod
    def single(cls, height: Polynomial1D, sigma_height_px: float, sigma_bearing_rad: float | None = None):
        """The thesis's sensor (eq. 4.19): one beacon-height channel and, in 2-D, the bearing."""
        return cls((ReadingChannel("height_px", height, sigma_height_px),), sigma_bearing_rad)

    @property
    def height(self) -> Polynomial1D:
        """f of the first channel (the thesis's beacon height)."""
        return self.channels[0].function

    @property
    def sigma_height_px(self) -> float:
        return self.channels[0].sigma

    def with_fits(
        self, fits: Sequence[tuple[Polynomial1D, float, tuple[float, ...]]], sigma_bearing_rad: float | None
    ) -> LandmarkSensor:
        """The same channels with new functions, sigmas and bearing terms (the M-step's output)."""
        chans = tuple(
            replace(ch, function=f, sigma=s, bearing_terms=a) for ch, (f, s, a) in zip(self.channels, fits, strict=True)
        )
        return replace(self, channels=chans, sigma_bearing_rad=sigma_bearing_rad)

    @property
    def is_robust(self) -> bool:
        return self.bearing_robust != "none" or any(c.robust != "none" for c in self.channels)

    def gaussian(self) -> LandmarkSensor:
        """The same sensor with every reading Gaussian (the thesis's observation model)."""
        chans = tuple(replace(c, robust="none", robust_param=0.0) for c in self.channels)
        return replace(self, channels=chans, bearing_robust="none", bearing_robust_param=0.0, joint_student_t=False)

    def to_dict(self) -> JsonObject:
        return {
            "kind": "landmark_sensor",
            "channels": [c.to_dict() for c in self.channels],
            "sigma_bearing_rad": self.sigma_bearing_rad,
            "bearing_robust": self.bearing_robust,
            "bearing_robust_param": self.bearing_robust_param,
            "joint_student_t": self.joint_student_t,
            "mount": self.mount.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: JsonObject, *, source: str = "model") -> LandmarkSensor:
        if not isinstance(data, dict) or data.get("kind") != "landmark_sensor":
            raise ModelFormatError(
                "not a landmark sensor model.", file=source, field="kind", fix="give a model written by sensact."
            )
        try:
            sb = data.get("sigma_bearing_rad")
            sb = None if sb is None else float(sb)
            if "channels" not in data:  # written before channels existed: the thesis's one height channel
                return cls.single(
                    Polynomial1D.from_dict(data["height"], source=source), float(data["sigma_height_px"]), sb
                )
            sensor = cls(
                tuple(ReadingChannel.from_dict(c, source=source) for c in data["channels"]),
                sb,
                str(data.get("bearing_robust", "none")),
                float(data.get("bearing_robust_param", 0.0)),
                bool(data.get("joint_student_t", False)),
                SensorMount.from_dict(data.get("mount")),  # written before mounts existed: the robot's own point
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(
                f"bad landmark sensor ({exc}).",
                file=source,
                field="channels",
                fix="rewrite it with `sensact learn em`.",
            ) from None
        sigmas = [(f"channels[{i}].sigma", ch.sigma) for i, ch in enumerate(sensor.channels)]
        sigmas += [("sigma_bearing_rad", sb)] if sb is not None else []
        for field, sigma in sigmas:  # the M-step never learns one below its floor: a smaller one was written by hand
            if not (MIN_SIGMA <= sigma <= MAX_SIGMA):
                raise ModelFormatError(
                    f"a sigma of {sigma:g} is outside {MIN_SIGMA:g} to {MAX_SIGMA:g}: every reading would be "
                    "infinitely sure or say nothing.",
                    file=source,
                    field=field,
                    fix="rewrite it with `sensact learn em`.",
                )
        return sensor
