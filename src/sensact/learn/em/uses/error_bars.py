"""Error bars on every learned parameter by a parametric bootstrap (docs/uncertainty.md; beyond the thesis, which
reports point estimates).

``B`` logs are drawn from the learned model (``uses/draw_log.simulate_from_model``: the log's own commands,
map and sighting times), and each is learned again as the log was: from the same start (the thesis's
poor guess, or the learned model `--start-from` placed), with the same settings. The spread of the ``B``
estimates is each parameter's standard error; the 90 % interval is the basic bootstrap's in its normal
form, ``(2 theta_hat - mean*) +- z_0.95 SE``, which takes out the bias the replicates show.

Each replicate runs the whole procedure, not EM on from the learned model: EM creeps along flat
directions of the likelihood (Sigma_m's above all) and stops by patience before it gets far, so
replicates started at the learned model stay near it and gave standard errors several times too small
(Sigma_m's intervals held the truth 2 times in 9 on the coverage check); from the same start as the
fit, each stops where the procedure stops, and their spread and bias are the procedure's.

Parameters, by family: ``action`` (the action model's coefficients, or a table's velocities), ``f`` (each
channel's reading function at the distances the log's sightings span, and its bearing terms),
``sigma`` (each reading's noise and the bearing's), ``Sigma_m`` (the motion noise's standard deviations
per step, and ``turn_var``) and ``mount`` (the sensor's forward, left and yaw). A parameter the fit holds
(a column the action model keeps at zero, a mount component the log cannot pin) is the same in every
replicate: it is marked ``held``, with no error bar.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.learn.em.config import EMConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.records import JsonObject

LEVEL = 0.90
Z = 1.6448536269514722  # the standard normal's 95th percentile: a two-sided 90 % interval
FAMILIES = ("action", "f", "sigma", "Sigma_m", "mount")
F_QUANTILES = (0.1, 0.5, 0.9)  # where f is read: the 10th, 50th and 90th percentile of the sightings' distances


def f_distances(model: EMModel, data: LandmarkLog, path: np.ndarray) -> np.ndarray:
    """The distances f is read at (``F_QUANTILES`` of the sensor-to-landmark distances of the log's
    sightings, on the smoothed ``path``), rounded to whole millimetres so that they name themselves."""
    at = path[data.obs_step]
    d = data.geometry.sensor_distance(at, data.landmarks_xy[data.obs_landmark], model.sensor.mount.as_array())
    return np.round(np.quantile(d, F_QUANTILES))


def model_parameters(model: EMModel, f_at: Sequence[float]) -> dict[str, tuple[str, float]]:
    """Every learned parameter of ``model`` by name: ``{name: (family, value)}``."""
    out: dict[str, tuple[str, float]] = {}
    a = model.action
    out.update({name: ("action", value) for name, value in a.named_parameters().items()})
    sensor = model.sensor.named_parameters(f_at)  # f's, the sigmas', then the mount's: each its family's prefix
    out.update({name: (name.split(".")[0], value) for name, value in sensor.items() if not name.startswith("mount.")})
    names = a.velocity_names
    for g, row in enumerate(model.motion_sd):
        for j, sd in enumerate(row):
            out[f"Sigma_m[{g}].{names[j]}"] = ("Sigma_m", float(sd))
    if model.turn_var is not None:
        out["Sigma_m.turn_var"] = ("Sigma_m", model.turn_var)
    if model.geometry.has_heading:  # a track's sensor has no pose of its own
        out.update({name: ("mount", value) for name, value in sensor.items() if name.startswith("mount.")})
    return out


def replicate(
    model: EMModel,
    data: LandmarkLog,
    config: EMConfig,
    seed: int,
    f_at: tuple[float, ...],
    start: EMModel | None = None,
    *,
    progress: Any = None,
) -> dict[str, float]:
    """One bootstrap replicate: a log drawn from ``model`` (``seed``), learned again from ``start`` (None:
    the thesis's poor guess) under ``config``, as the log was; its parameters by name (``model_parameters``)."""
    from sensact.learn.em.fit import fit_em
    from sensact.learn.em.uses.draw_log import simulate_from_model

    drawn, _ = simulate_from_model(model, data, seed)

    def on_iteration(it: int, ll: float, best: float, since: int) -> None:
        if progress is not None:
            progress(f"replicate {seed}: EM iteration {it}, log-likelihood {ll:.1f}", it + 1, None)

    res = fit_em(drawn, start, config, on_iteration=on_iteration)
    if res.stop_reason == "diverged":
        raise ValueError(f"EM diverged on replicate {seed}")
    return {name: value for name, (_, value) in model_parameters(res.model, f_at).items()}


@dataclass(frozen=True)
class Parameter:
    """One learned parameter with its error bar (no interval where the fit held it). An interval's end is
    None where the data give no bound on that side; ``open_ended`` says which side (a standard
    deviation's open lower end is 0)."""

    name: str
    family: str
    value: float
    se: float | None  # None: held, or nothing in the data bounds it
    interval: tuple[float | None, float | None] | None
    bias: float | None  # the replicates' mean less the value (None: not a bootstrap's)
    open_ended: tuple[bool, bool] = (False, False)

    @property
    def held(self) -> bool:
        return self.interval is None

    def covers(self, truth: float) -> bool | None:
        """Whether the interval holds ``truth`` (None for a held parameter); an open end holds all beyond."""
        if self.interval is None:
            return None
        lo, hi = self.interval
        return bool((lo is None or lo <= truth) and (hi is None or truth <= hi))

    def to_dict(self) -> JsonObject:
        return {
            "family": self.family,
            "value": self.value,
            "se": self.se,
            "interval": None if self.interval is None else list(self.interval),
            "open_ended": list(self.open_ended),
            "bias": self.bias,
            "held": self.held,
        }


@dataclass(frozen=True)
class Uncertainty:
    """The bootstrap's error bars: ``replicates`` asked, ``used`` learned (a replicate EM failed on is
    left out, its line in ``failed``), the base ``seed`` (replicate b draws with ``seed + b``)."""

    replicates: int
    used: int
    seed: int
    f_at_mm: tuple[float, ...]
    parameters: tuple[Parameter, ...]
    failed: tuple[str, ...] = ()
    method: str = "parametric bootstrap"  # or "observed information" (uses/information.py)

    def by_name(self) -> dict[str, Parameter]:
        return {p.name: p for p in self.parameters}

    def to_dict(self) -> JsonObject:
        """The model JSON's ``uncertainty`` (its key names are fixed: checks read them)."""
        return {
            "method": self.method,
            "level": LEVEL,
            "replicates": self.replicates,
            "used": self.used,
            "seed": self.seed,
            "f_at_mm": list(self.f_at_mm),
            "parameters": {p.name: p.to_dict() for p in self.parameters},
            "failed": list(self.failed),
        }


def summarize(
    model: EMModel,
    draws: Sequence[Mapping[str, float] | str],
    f_at: Sequence[float],
    seed: int,
) -> Uncertainty:
    """Each parameter's standard error and 90 % interval from the replicates ``draws`` (a string is a
    replicate that failed, as one line)."""
    used = [d for d in draws if not isinstance(d, str)]
    failed = tuple(d for d in draws if isinstance(d, str))
    params = []
    for name, (family, value) in model_parameters(model, f_at).items():
        values = np.array([d[name] for d in used if name in d], dtype=float)
        if values.size < 2 or np.ptp(values) == 0.0:  # held by the fit (or too few replicates to tell)
            params.append(Parameter(name, family, value, None, None, None))
            continue
        se = float(np.std(values, ddof=1))
        bias = float(np.mean(values) - value)
        center = value - bias
        params.append(Parameter(name, family, value, se, (center - Z * se, center + Z * se), bias))
    return Uncertainty(len(draws), len(used), seed, tuple(float(d) for d in f_at), tuple(params), failed)


def coverage(fits: Sequence[tuple[Uncertainty, Mapping[str, float]]]) -> dict[str, JsonObject]:
    """Per family, over fits each with the true parameters: how many intervals hold the truth, of how many
    (held parameters left out), and the share."""
    out: dict[str, JsonObject] = {}
    for family in FAMILIES:
        held = total = 0
        for unc, truth in fits:
            for p in unc.parameters:
                if p.family != family or p.name not in truth:
                    continue
                hit = p.covers(truth[p.name])
                if hit is None:
                    continue
                total += 1
                held += hit
        out[family] = {"covered": held, "intervals": total, "share": held / total if total else math.nan}
    return out
