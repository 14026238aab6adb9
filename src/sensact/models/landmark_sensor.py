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
from typing import Any, ClassVar

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.ekf_smoother import GATE, GAUSSIAN, LANDMARK, STUDENT_T, STUDENT_T_JOINT, SensorInputs, Sightings
from sensact.core.geometry import Geometry
from sensact.core.polyfit import vander, weighted_lstsq
from sensact.core.pose_models import landmark_bearing, landmark_distance, sensor_distance, sensor_poses
from sensact.errors import ModelFormatError
from sensact.models.polynomial import Polynomial1D
from sensact.models.sensor_model import SightingLog
from sensact.records import JsonObject

ROBUST_KINDS = ("none", "student_t", "gate")
ROBUST_CODES = {"none": GAUSSIAN, "student_t": STUDENT_T, "gate": GATE}  # the compiled passes' codes


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


@dataclass(frozen=True, eq=False)
class SampledSightings:
    """The sightings an M-step reads (those the E-step used), with the robot's sampled poses at each."""

    poses: np.ndarray  # (S, R, n): the E-step's pose samples at the R sightings (eq. 4.25's expectation)
    landmark: np.ndarray  # (R,) which landmark each sighting saw
    readings: np.ndarray  # (R, C) each reading channel's input
    weights: np.ndarray  # (R, C + 1) each channel's E-step weight, then the bearing's; 0 = not used
    bearings: np.ndarray  # (R,) rad


MIN_SIGMA = 1e-9  # the M-step's floor on every sigma
MAX_SIGMA = 1e9  # limits.MAX_VALUE: beyond it in any unit


@dataclass(frozen=True)
class LandmarkSensor:
    """Eq. 4.19's sensor (``models.sensor_model.SensorModel``): each reading channel ``f_i(d)`` of the
    distance from the sensor to the landmark it sees, then the landmark's bearing (a 1-D robot's and a
    range-only sensor's read none)."""

    kind: ClassVar[int] = LANDMARK
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

    # ------------------------------------------------------------ the sensor protocol (models/sensor_model.py)

    @property
    def noise_groups(self) -> tuple[str, ...]:
        return (*(c.name for c in self.channels), "bearing_rad")

    @property
    def sigmas(self) -> tuple[float, ...]:
        return (*(c.sigma for c in self.channels), self.sigma_bearing_rad if self.reads_bearing else np.nan)

    @property
    def parameters(self) -> np.ndarray:
        """Per channel f's coefficients, its bearing terms and sigma; then sigma_2 (if read), then the mount."""
        parts = [[*c.function.coef, *c.bearing_terms, c.sigma] for c in self.channels]
        parts.append([self.sigma_bearing_rad] if self.reads_bearing else [])
        parts.append(list(self.mount.as_array()))
        return np.array([v for p in parts for v in p], dtype=float)

    def with_parameters(self, values: np.ndarray) -> LandmarkSensor:
        x, at, chans = np.asarray(values, dtype=float).ravel(), 0, []
        for c in self.channels:
            k, m = c.function.degree + 1, len(c.bearing_terms)
            f = replace(c.function, coef=tuple(x[at : at + k]))
            chans.append(
                replace(c, function=f, bearing_terms=tuple(x[at + k : at + k + m]), sigma=float(x[at + k + m]))
            )
            at += k + m + 1
        sb = float(x[at]) if self.reads_bearing else None
        at += self.reads_bearing
        return replace(self, channels=tuple(chans), sigma_bearing_rad=sb, mount=SensorMount.from_array(x[at : at + 3]))

    def named_parameters(self, f_at: Sequence[float] = ()) -> dict[str, float]:
        """f by its coefficients (``f.NAME[i]``, in its normalized distance), or by its values at the distances
        ``f_at`` (``f.NAME(D mm)``); then its bearing terms, each sigma and the mount."""
        out: dict[str, float] = {}
        for ch in self.channels:
            if f_at:
                out.update({f"f.{ch.name}({d:g} mm)": float(ch.function(np.array([d]))[0]) for d in f_at})
            else:
                out.update({f"f.{ch.name}[{i}]": a for i, a in enumerate(ch.function.coef)})
            out.update({f"f.{ch.name}.bearing_term{k}": a for k, a in enumerate(ch.bearing_terms, start=1)})
            out[f"sigma.{ch.name}"] = ch.sigma
        if self.reads_bearing:
            out["sigma.bearing_rad"] = float(self.sigma_bearing_rad)
        return out | {f"mount.{k}": v for k, v in self.mount.to_dict().items()}

    def columns(self, data: SightingLog) -> list[int]:
        """The log's reading column of each of the sensor's channels, matched by name."""
        names = [c.name for c in self.channels]
        if len(names) == 1 and names[0] not in data.reading_names:
            return [0]  # a one-channel model reads the log's first reading, whatever it is called
        missing = [x for x in names if x not in data.reading_names]
        if missing:
            raise ValueError(f"the log {data.source} has no reading {missing[0]!r} (it has {list(data.reading_names)})")
        return [data.reading_names.index(x) for x in names]

    def readings_of(self, data: SightingLog) -> tuple[np.ndarray, np.ndarray]:
        """Each channel's readings ``(K, C)`` and bearing gain ``sum_k a_k b^k`` at the measured bearing.

        A channel with bearing terms cannot predict a reading whose bearing is missing: that reading counts
        as missing too.
        """
        readings = np.array(data.obs_readings[:, self.columns(data)], dtype=float)
        gain = np.zeros_like(readings)
        for c, ch in enumerate(self.channels):
            if not ch.bearing_terms:
                continue
            if not data.geometry.has_heading:
                raise ValueError(f"channel {ch.name} has bearing terms but the log {data.source} has no bearings")
            g = ch.bearing_gain(data.obs_bearing_rad)
            readings[~np.isfinite(g), c] = np.nan
            gain[:, c] = np.nan_to_num(g)
        return readings, gain

    def kernel_inputs(self, data: SightingLog) -> tuple[Sightings, SensorInputs]:
        """The log's sightings and this sensor as the compiled E-step reads them."""
        chans = self.channels
        C = len(chans)
        coefs = np.zeros((C, max(c.function.degree for c in chans) + 1))
        for i, ch in enumerate(chans):
            coefs[i, : ch.function.degree + 1] = ch.function.coef
        kinds = np.array([ROBUST_CODES[c.robust] for c in chans] + [ROBUST_CODES[self.bearing_robust]], dtype=np.int64)
        if self.joint_student_t:
            kinds[kinds == STUDENT_T] = STUDENT_T_JOINT
        sb = self.sigma_bearing_rad
        readings, gain = self.readings_of(data)
        # a sensor without sigma_2 (a range-only one) reads no bearing, whatever the log holds
        bearing = data.obs_bearing_rad if sb is not None else np.full(data.n_observations, np.nan)
        sight = Sightings(data.obs_ptr, data.obs_landmark, readings, gain, bearing)
        inputs = SensorInputs(
            LANDMARK,
            data.landmarks_xy if len(data.landmarks_xy) else np.zeros((1, 2)),
            coefs,
            np.array([c.function.center for c in chans], dtype=float),
            np.array([c.function.scale for c in chans], dtype=float),
            np.array([c.sigma**2 for c in chans], dtype=float),
            np.array([c.valid_min for c in chans], dtype=float),
            np.array([c.valid_max for c in chans], dtype=float),
            float((sb if sb is not None else 1.0) ** 2),
            self.mount.as_array(),
            kinds,
            np.array([c.robust_param for c in chans] + [self.bearing_robust_param], dtype=float),
        )
        return sight, inputs

    def predict(self, poses: np.ndarray, data: SightingLog, rows: np.ndarray) -> np.ndarray:
        """``(R, C + 1)``: each channel's mean reading, then the bearing (NaN where not read), of sightings
        ``rows`` from the sensor at its mount on the robot at ``poses`` (eq. 4.19)."""
        lm = data.landmarks_xy[data.obs_landmark[rows]]
        bearings = data.obs_bearing_rad[rows]
        at = sensor_poses(poses, self.mount.as_array()) if data.geometry.has_heading else poses
        dist = landmark_distance(at, lm, data.geometry.mode)
        out = np.full((len(rows), len(self.channels) + 1), np.nan)
        for j, ch in enumerate(self.channels):
            out[:, j] = ch.predict(dist, bearings if ch.bearing_terms else None)
        if self.reads_bearing and data.geometry.has_heading:
            out[:, -1] = landmark_bearing(at, lm)
        return out

    def update(
        self,
        seen: SampledSightings,
        landmarks_xy: np.ndarray,
        geometry: Geometry,
        *,
        fit_bearing_terms: bool = True,
        metric: int = -1,
    ) -> LandmarkSensor:
        """Eq. 4.25 (each f_i by regression on the sampled distances), eq. 4.27 (each sigma_i) and eq. 4.28
        (sigma_2), over the sightings the E-step used (``seen``), each reading with its E-step weight. Each f_i
        keeps its degree; without ``fit_bearing_terms`` the bearing terms are held. Channel ``metric`` (a
        map's scale from its readings) holds its slope at 1 in the middle of its distances."""
        poses, readings, weights, bearings = seen.poses, seen.readings, seen.weights, seen.bearings
        n_samples = len(poses)
        lm = landmarks_xy[seen.landmark]
        m_ = self.mount.as_array()
        dist = np.stack([sensor_distance(poses[s], lm, m_, geometry.mode) for s in range(n_samples)])  # (S, R)
        fits = []
        for c, ch in enumerate(self.channels):
            w = weights[:, c]
            use = w > 0
            deg, m = ch.function.degree, len(ch.bearing_terms) if fit_bearing_terms else 0
            if use.sum() <= deg + m + 1:
                fits.append((ch.function, ch.sigma, ch.bearing_terms))
                continue
            d = dist[:, use].ravel()
            y = np.tile(readings[use, c], n_samples)
            ww = np.tile(w[use], n_samples)
            b = np.tile(bearings[use], n_samples)
            held = 0.0 if m else d * ch.bearing_gain(b)  # held terms: f is fitted to what they leave
            center, scale = float(d.mean()), float(d.std()) or 1.0
            # eq. 4.25, with the bearing terms' columns d b^k beside f's (they enter linearly too)
            X = reading_features(d, b, deg, m, center, scale)
            if c == metric and deg >= 1:  # the map's scale: f = d + offset (and the bearing terms)
                rest = np.r_[[0], deg + 1 : X.shape[1]].astype(int)
                sol = np.zeros(X.shape[1])
                sol[1] = scale
                if rest.size:
                    sol[rest] = weighted_lstsq(X[:, rest], y - held - X[:, :2] @ sol[:2], ww)
            else:
                sol = weighted_lstsq(X, y - held, ww)
            fitted = ch.with_solution(sol, center, scale, m)
            sigma = float(np.sqrt(np.sum(ww * (fitted.predict(d, b) - y) ** 2) / d.size))  # eq. 4.27
            fits.append((fitted.function, max(sigma, MIN_SIGMA), fitted.bearing_terms))
        sigma_b = self.sigma_bearing_rad
        wb = weights[:, -1]
        if geometry.has_heading and sigma_b is not None and (wb > 0).any():  # eq. 4.28
            b = wb > 0
            ob = bearings[b]
            err = np.concatenate(
                [wrap_angle(landmark_bearing(sensor_poses(poses[s][b], m_), lm[b]) - ob) for s in range(n_samples)]
            )
            sigma_b = max(float(np.sqrt(np.sum(np.tile(wb[b], n_samples) * err**2) / err.size)), MIN_SIGMA)
        return self.with_fits(fits, sigma_b)

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
