"""Error bars from the likelihood itself (docs/uncertainty.md; beyond the thesis, which reports point estimates).

The learned parameters are one vector (``LearnedSpace``): the action model's free coefficients, each f
at its knots and its bearing terms, the sigmas and Sigma_m on the log scale, the mount's learned
components, and the nuisance EM also learns (the start's mean, a learned map's landmarks). The
log-likelihood is the forward pass's ``log P(O | C, lambda)`` (eq. 4.14), which costs a fraction of an
E-step, so its curvature can be taken by central differences:

* **action, f and mount**: Wald intervals from the observed information (the negative Hessian of the
  log-likelihood at the fit; Jamshidian & Jennrich 2000 take it by differences of the score, here by
  differences of the likelihood), carried to each named parameter by its derivative (the delta method);
* **sigma and Sigma_m**: profile-likelihood intervals on the log scale: the values of the standard
  deviation whose profile (the likelihood, the rest re-maximized) lies within ``chi^2_1(0.90) / 2`` of
  its maximum. Where the profile does not fall that far before a factor ``OPEN_FACTOR`` from the fit,
  the data give no bound on that side: the interval is open there (0 below, None above) and says so.

The start's mean is a nuisance parameter, not held: a sensor's yaw and the start's heading trade against
each other, and holding the start made the yaw's intervals four times too narrow on the coverage check.
The start's covariance sits at its floor (``prior_floor_sd``) and is held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from sensact.learn.em.space import LearnedSpace
from sensact.learn.em.uses.error_bars import Parameter, Uncertainty, Z, model_parameters
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

# chi^2_1's 90th percentile over 2: a profile within this of its maximum is inside the 90 % interval
PROFILE_DROP = Z * Z / 2  # chi^2_1(0.90) = z_0.95^2
STEP_LOGLIK = 0.02  # each central difference moves the log-likelihood by about this much
OPEN_FACTOR = 1000.0  # a profile still this flat a factor 1,000 from the fit: no bound on that side
PROFILE_NEWTON = 3  # Newton steps re-maximizing the rest at each point of a profile


def _steps(space: LearnedSpace, p: np.ndarray, l0: float) -> np.ndarray:
    """Per entry, a step that moves the log-likelihood by about ``STEP_LOGLIK`` (from the curvature)."""
    h = 1e-6 * np.maximum(1.0, np.abs(p))
    for _ in range(3):
        e = np.eye(p.size) * h
        curv = np.array([(space.loglik(p + e[i]) - 2 * l0 + space.loglik(p - e[i])) / h[i] ** 2 for i in range(p.size)])
        ok = np.isfinite(curv) & (curv < 0)
        h = np.where(ok, np.sqrt(2 * STEP_LOGLIK / np.abs(np.where(ok, curv, 1.0))), h * 100)
    return h


def observed_information(space: LearnedSpace, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(-H, steps, loglik)`` at ``p`` by central differences of the forward pass's likelihood, with each
    entry's step (its scale, for ``Curvature``)."""
    l0 = space.loglik(p)
    h = _steps(space, p, l0)
    n = p.size
    E = np.eye(n) * h
    up = np.array([space.loglik(p + E[i]) for i in range(n)])
    down = np.array([space.loglik(p - E[i]) for i in range(n)])
    H = np.diag((up - 2 * l0 + down) / h**2)
    for i in range(n):
        for j in range(i):
            v = (
                space.loglik(p + E[i] + E[j])
                - space.loglik(p + E[i] - E[j])
                - space.loglik(p - E[i] + E[j])
                + space.loglik(p - E[i] - E[j])
            ) / (4 * h[i] * h[j])
            H[i, j] = H[j, i] = v
    return -H, h, l0


@dataclass(frozen=True, eq=False)
class Curvature:
    """The observed information's inverse, taken on entries scaled by ``scale`` (so that millimetres and
    radians per millimetre compare): ``cov`` over the directions the likelihood bends down in, and those it
    does not (flat, or rising: the fit is not at a top there), along which nothing bounds a parameter."""

    cov: np.ndarray
    scale: np.ndarray
    unbounded: np.ndarray  # (n, k) orthonormal directions of the scaled entries

    @classmethod
    def of(cls, info: np.ndarray, scale: np.ndarray) -> Curvature:
        w, V = np.linalg.eigh(info * np.outer(scale, scale))
        flat = w <= 1e-8 * max(w.max(initial=0.0), 1e-300)
        inv = np.where(flat, 0.0, 1.0 / np.where(flat, 1.0, w))
        return cls((V * inv) @ V.T * np.outer(scale, scale), scale, V[:, flat])

    def sandwiched(self, meat: np.ndarray) -> Curvature:
        """``I^-1 B I^-1`` with ``B = meat`` (the scores' outer products), over the same bounded directions:
        the estimate's covariance where the model is only an approximation (Huber 1967, White 1982)."""
        return Curvature(self.cov @ meat @ self.cov, self.scale, self.unbounded)

    def variance(self, gradient: np.ndarray) -> float:
        """The variance of a function with ``gradient`` in the entries: infinite where a hundredth of its
        change or more lies along a direction the likelihood does not bound."""
        g = gradient * self.scale
        if self.unbounded.size and np.abs(g @ self.unbounded).max() > 1e-2 * np.linalg.norm(g):
            return math.inf
        return max(float(gradient @ self.cov @ gradient), 0.0)


def _profile(space: Any, p: np.ndarray, C: np.ndarray, info: np.ndarray, scale: np.ndarray, j: int):
    """Log-scale interval of entry ``j`` from its profile: the rest moved with it along the covariance's
    column (the quadratic profile), then up to ``PROFILE_NEWTON`` Newton steps on the rest with the fit's
    information; ``(low, high)``, None for an end the profile does not reach."""
    rest = np.arange(p.size) != j
    solve = np.linalg.pinv(info[np.ix_(rest, rest)])
    direction = C[:, j] / C[j, j] if C[j, j] > 0 else np.eye(p.size)[j]

    def at(t: float) -> tuple[float, np.ndarray]:
        """The profile at ``t`` and the point that reaches it."""
        q = p + (t - p[j]) * direction
        best = space.loglik(q)
        for _ in range(PROFILE_NEWTON):  # Newton steps on the rest, with the fit's information
            if not math.isfinite(best):
                return best, q
            h = scale[rest]
            g = np.zeros(int(rest.sum()))
            for k, i in enumerate(np.flatnonzero(rest)):
                e = np.zeros(p.size)
                e[i] = h[k]
                g[k] = (space.loglik(q + e) - space.loglik(q - e)) / (2 * h[k])
            step = np.zeros(p.size)
            step[rest] = solve @ g
            moved = space.loglik(q + step) if np.all(np.isfinite(step)) else -math.inf
            if not moved > best:
                break
            q, best = q + step, moved
        return best, q

    sd = math.sqrt(C[j, j]) if C[j, j] > 0 else 1.0
    limit = math.log(OPEN_FACTOR)
    seen: dict[float, float] = {}

    def value(t: float) -> float:
        if t not in seen:
            seen[t] = at(t)[0]
        return seen[t]

    # the profile's top: EM's value need not be at it (EM stops by patience, and the rest moves here)
    grid = p[j] + np.clip(np.arange(-4, 5) * 0.5 * sd, -limit, limit)
    heights = [value(float(t)) for t in grid]
    k = int(np.argmax(heights))
    if 0 < k < len(grid) - 1:  # the parabola through the best and its neighbours: its vertex
        down, mid, up = heights[k - 1 : k + 2]
        bend = down - 2 * mid + up
        if bend < 0:
            value(float(grid[k] + 0.5 * (grid[k + 1] - grid[k]) * (down - up) / bend))
    ends: dict[float, float | None] = {}
    for _ in range(3):  # again if one side's search found a higher top
        top_t = max(seen, key=seen.__getitem__)
        top = seen[top_t]
        for sign in (-1.0, 1.0):
            ends[sign] = _crossing(value, top_t, sign, top - PROFILE_DROP, max(min(sd, limit), 1e-3), p[j], limit)
        if max(seen.values()) <= top:
            break
    return ends[-1.0], ends[1.0]


def _crossing(value, start: float, sign: float, level: float, width: float, centre: float, limit: float):
    """Where ``value`` falls below ``level`` going ``sign``-ward from ``start`` (steps doubling from
    ``width``, then bisection); None if it does not within ``limit`` of ``centre``."""
    inside, t = start, start
    while abs(t - centre) < limit:
        t = float(np.clip(t + sign * width, centre - limit, centre + limit))
        if value(t) < level:
            lo, hi = inside, t
            for _ in range(12):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if value(mid) >= level else (lo, mid)
            return 0.5 * (lo + hi)
        inside = t
        width *= 2
    return None


SANDWICH_BLOCK_S = 1.0  # the scores are summed over a second of sightings before their outer products


def sighting_scores(space: LearnedSpace, p: np.ndarray, h: np.ndarray) -> np.ndarray | None:
    """``(K, len(p))``: each sighting's share of the likelihood differentiated in each entry (central
    differences with the curvature's steps ``h``; 2 forward passes an entry); None where a pass fails."""
    out = np.zeros((space.data.n_observations, p.size))
    for i in range(p.size):
        e = np.zeros(p.size)
        e[i] = h[i]
        up, down = space.contributions(p + e), space.contributions(p - e)
        if up is None or down is None:
            return None
        out[:, i] = (up - down) / (2 * h[i])
    return out


def sandwich_meat(scores: np.ndarray, data: LandmarkLog) -> np.ndarray:
    """``B = sum_b s_b s_b'`` over blocks of ``SANDWICH_BLOCK_S`` of sightings (``s_b`` their summed
    scores): the scores' spread as the log shows it, blocked so that neighbouring sightings that err
    together (a path the linearization bends alike) count as one."""
    per_block = max(1, round(SANDWICH_BLOCK_S / data.dt_s))
    block = np.asarray(data.obs_step) // per_block
    _, which = np.unique(block, return_inverse=True)
    summed = np.zeros((which.max(initial=-1) + 1, scores.shape[1]))
    np.add.at(summed, which, scores)
    return summed.T @ summed


def information_intervals(
    model: EMModel, data: LandmarkLog, f_at: tuple[float, ...], mount_free: tuple[bool, bool, bool] | None
) -> Uncertainty:
    """Every learned parameter's 90 % interval from the likelihood's curvature (action, f, mount) or its
    profile (sigma, Sigma_m), at ``model``."""
    return likelihood_intervals(model, data, f_at, mount_free)[0]


def likelihood_intervals(
    model: EMModel,
    data: LandmarkLog,
    f_at: tuple[float, ...],
    mount_free: tuple[bool, bool, bool] | None,
    sandwich: bool = False,
) -> tuple[Uncertainty, Uncertainty | None]:
    """``information_intervals``, and with ``sandwich`` the same with the action, f and mount intervals from
    the sandwich covariance (``Curvature.sandwiched``: the curvature around the sightings' scores'
    spread) instead; the profiles (sigma, Sigma_m) are the likelihood's either way."""
    space = LearnedSpace.about(model, data, mount_free)
    p = space.p0
    info, scale, _ = observed_information(space, p)
    curve = Curvature.of(info, scale)
    sandwiched = None
    if sandwich:
        scores = sighting_scores(space, p, scale)
        sandwiched = None if scores is None else curve.sandwiched(sandwich_meat(scores, data))
    named = {name: value for name, (_, value) in model_parameters(model, f_at).items()}
    families = {name: fam for name, (fam, _) in model_parameters(model, f_at).items()}
    names = list(named)
    J = np.zeros((len(names), p.size))
    for i in range(p.size):  # each named parameter's derivative in each entry (no likelihood needed)
        h = 1e-6 * max(1.0, abs(p[i]))
        e = np.zeros(p.size)
        e[i] = h
        up = model_parameters(space.model(p + e), f_at)
        down = model_parameters(space.model(p - e), f_at)
        J[:, i] = [(up[n][1] - down[n][1]) / (2 * h) for n in names]
    profiled = _profiled_entries(space, names, model)
    params: dict[str, list[Parameter]] = {"information": [], "sandwich": []}
    for k, name in enumerate(names):
        value, family = named[name], families[name]
        if not np.any(J[k]):  # held by the fit
            held = Parameter(name, family, value, None, None, None)
            params["information"].append(held)
            params["sandwich"].append(held)
            continue
        if name in profiled:
            lo, hi = _profile(space, p, curve.cov, info, scale, profiled[name])
            interval: tuple[float | None, float | None] = (
                0.0 if lo is None else math.exp(lo),
                None if hi is None else math.exp(hi),
            )
            se = math.sqrt(curve.variance(J[k]))
            opened = (lo is None, hi is None)
            one = Parameter(name, family, value, se if math.isfinite(se) else None, interval, None, opened)
            params["information"].append(one)
            params["sandwich"].append(one)
            continue
        for method, c in (("information", curve), ("sandwich", sandwiched)):
            if c is None:
                continue
            se = math.sqrt(c.variance(J[k]))
            if math.isfinite(se):
                params[method].append(Parameter(name, family, value, se, (value - Z * se, value + Z * se), None))
            else:
                params[method].append(Parameter(name, family, value, None, (None, None), None, (True, True)))
    plain = Uncertainty(0, 0, 0, f_at, tuple(params["information"]), method="observed information")
    if sandwiched is None:
        return plain, None
    return plain, Uncertainty(0, 0, 0, f_at, tuple(params["sandwich"]), method="sandwich")


def _profiled_entries(space: LearnedSpace, names: list[str], model: EMModel) -> dict[str, int]:
    """The named standard deviations and the entry of ``p`` each is the logarithm of."""
    where: dict[str, int] = {}
    idx = {label: [i for i, lab in enumerate(space.labels) if lab == label] for label in set(space.labels)}
    for ch in model.sensor.channels:
        where[f"sigma.{ch.name}"] = idx[f"log sigma.{ch.name}"][0]
    if "log sigma.bearing_rad" in idx:
        where["sigma.bearing_rad"] = idx["log sigma.bearing_rad"][0]
    velocity = model.action.velocity_names
    for k, i in enumerate(idx.get("log Sigma_m", [])):
        g, a = divmod(k, len(velocity))
        where[f"Sigma_m[{g}].{velocity[a]}"] = i
    if "log turn_var" in idx:
        where["Sigma_m.turn_var"] = idx["log turn_var"][0]
    return {n: i for n, i in where.items() if n in names}
