"""SQUAREM (Varadhan & Roland 2008, scheme S3) for EM's map ``lambda -> M(E(lambda))``.

EM converges linearly, and slowly along the ridge where the path and the action model trade against
each other (docs/em-real.md). From ``lambda_0`` and two EM steps ``lambda_1``, ``lambda_2``, with
``r = lambda_1 - lambda_0`` and ``v = lambda_2 - 2 lambda_1 + lambda_0``, S3 steps to
``lambda_0 + 2 a r + a^2 v`` with ``a = |r| / |v|``, clipped to ``[1, step_max]``: ``a = 1`` is
``lambda_2`` itself, plain EM's two steps. The step is taken on coordinates where every model is valid
(``Coordinates``): the sigmas and Sigma_m on the log scale, the prior's covariance by its log-Cholesky
factor, each f by its values at fixed distances (so that a refit's new centre and scale do not move
it). The loop (``loop.squarem_loop``) adds the likelihood safeguard and the step-length bound.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as dc_replace

import numpy as np

from sensact.learn.em.mstep import into_robot_frame
from sensact.models.action_model import CommandLog
from sensact.models.em_model import EMModel
from sensact.models.polynomial import Polynomial1D

# R's SQUAREM: the bound starts at 1, grows x4 whenever a step reaches it, shrinks x4 when one is refused
STEP_MAX_START = 1.0
STEP_FACTOR = 4.0
STEP_MAX_LIMIT = 4.0**6  # a step of ~4,000 EM steps at most
# the safeguard (SQUAREM's objfn.inc): a step may lose this much log-likelihood against lambda_0
LOGLIK_SLACK = 1.0
# patience on a deterministic map: the best must rise this much over ``patience`` E-steps to go on
MIN_GAIN = 0.1


def _knots(f: Polynomial1D) -> np.ndarray:
    """Chebyshev points of f's own normalized variable, one per coefficient (in the log's units)."""
    k = f.degree + 1
    return f.center + f.scale * np.cos(np.pi * (np.arange(k) + 0.5) / k)


ACTION_STEPS = 256  # the log's steps whose velocities stand for the action model


@dataclass(frozen=True, eq=False)
class Coordinates:
    """``lambda`` as a vector on unconstrained coordinates, about ``template``: its f's knots, its delay,
    and whatever a vector does not hold (names, windows, the robust laws, the map's held positions).

    So that S3's step length does not depend on how the model is written, the action model is its
    velocities at ``ACTION_STEPS`` of the log's steps (wheel speeds or v and omega, the same numbers),
    and the prior's covariance is taken in the robot's frame at the template's heading (a map turned with
    its log, the same numbers)."""

    template: EMModel
    # (K n + q, p): the sampled steps' velocities per unit of each action parameter, then the q directions of
    # the parameters that no sampled velocity shows
    velocity_map: np.ndarray

    moving: np.ndarray  # (p,) bool: the action parameters the cycle moved; the rest stay exactly as they are

    @classmethod
    def about(cls, template: EMModel, data: CommandLog, moving: np.ndarray) -> Coordinates:
        a = template.action
        shape = np.shape(a.parameters)
        steps = np.unique(np.linspace(0, data.n_steps - 1, min(ACTION_STEPS, data.n_steps)).astype(int))
        zero = a.with_parameters(np.zeros(shape)).step_velocity(data)[steps]
        cols = []
        for j in np.flatnonzero(moving):
            unit = np.zeros(int(np.prod(shape)))
            unit[j] = 1.0
            cols.append((a.with_parameters(unit.reshape(shape)).step_velocity(data)[steps] - zero).ravel())
        J = np.stack(cols, axis=1).reshape(-1, len(cols)) / np.sqrt(len(steps))
        # parameters no sampled step shows (a table's rare action): their own values, beside the velocities
        _, sv, vt = np.linalg.svd(J, full_matrices=J.shape[0] < J.shape[1])  # vt whole either way; U not needed
        rank = int(np.sum(sv > sv.max(initial=0.0) * 1e-10))
        return cls(template, np.vstack([J, vt[rank:]]), np.asarray(moving, dtype=bool))

    def _turn(self, cov: np.ndarray, back: bool = False) -> np.ndarray:
        if cov.shape[0] != 3:
            return cov
        h = self.template.prior_mean[2]
        return into_robot_frame(cov[None], np.cos(h)[None], (-1.0 if back else 1.0) * np.sin(h)[None])[0]

    def _free_landmarks(self) -> np.ndarray | None:
        lm = self.template.landmarks
        return None if lm is None else lm.learned & np.isfinite(lm.xy).all(axis=1)

    def blocks(self, model: EMModel) -> list[tuple[str, np.ndarray]]:
        """``vector``'s parts in order, each named: ``action``, ``f.<channel>`` (f at its knots),
        ``bearing_terms.<channel>``, ``log sigma.<channel>``, ``log sigma.bearing_rad``, ``mount``,
        ``log Sigma_m``, ``log turn_var``, ``prior.mean``, ``prior.log_diag``, ``prior.low`` and ``landmarks``."""
        parts = [("action", self.velocity_map @ np.asarray(model.action.parameters, dtype=float).ravel()[self.moving])]
        for ch, t in zip(model.sensor.channels, self.template.sensor.channels, strict=True):
            parts += [
                (f"f.{ch.name}", ch.function(_knots(t.function))),
                (f"bearing_terms.{ch.name}", np.asarray(ch.bearing_terms, dtype=float)),
                (f"log sigma.{ch.name}", np.log([ch.sigma])),
            ]
        if model.sensor.reads_bearing:
            parts.append(("log sigma.bearing_rad", np.log([model.sensor.sigma_bearing_rad])))
        parts.append(("mount", model.sensor.mount.as_array()))
        parts.append(("log Sigma_m", np.log(model.motion_sd).ravel()))
        if model.turn_var is not None:
            parts.append(("log turn_var", np.log([model.turn_var])))
        L = np.linalg.cholesky(self._turn(model.prior_cov))
        low = np.tril_indices(L.shape[0], -1)
        parts += [("prior.mean", model.prior_mean), ("prior.log_diag", np.log(np.diag(L))), ("prior.low", L[low])]
        free = self._free_landmarks()
        if free is not None and model.landmarks is not None:
            parts.append(("landmarks", model.landmarks.xy[free].ravel()))
        return [(name, np.asarray(p, dtype=float).ravel()) for name, p in parts]

    def vector(self, model: EMModel) -> np.ndarray:
        return np.concatenate([p for _, p in self.blocks(model)])

    def model(self, x: np.ndarray) -> EMModel:
        """The model at ``x``; ValueError where ``x`` is no valid model (a sigma beyond its bound)."""
        t, at = self.template, 0

        def take(n: int) -> np.ndarray:
            nonlocal at
            at += n
            return x[at - n : at]

        shape = np.shape(t.action.parameters)
        beta = np.asarray(t.action.parameters, dtype=float).ravel().copy()
        beta[self.moving] = np.linalg.lstsq(self.velocity_map, take(self.velocity_map.shape[0]), rcond=None)[0]
        action = t.action.with_parameters(beta.reshape(shape))
        channels = []
        for ch in t.sensor.channels:
            f = ch.function
            u = (_knots(f) - f.center) / f.scale
            coef = np.linalg.solve(np.vander(u, f.degree + 1, increasing=True), take(f.degree + 1))
            terms = tuple(float(a) for a in take(len(ch.bearing_terms)))
            sigma = float(np.exp(take(1)[0]))
            channels.append(dc_replace(ch, function=dc_replace(f, coef=tuple(coef)), bearing_terms=terms, sigma=sigma))
        sigma_b = t.sensor.sigma_bearing_rad
        if sigma_b is not None:
            sigma_b = float(np.exp(take(1)[0]))
        mount = type(t.sensor.mount).from_array(take(3))
        sensor = dc_replace(t.sensor, channels=tuple(channels), sigma_bearing_rad=sigma_b, mount=mount)
        motion_sd = np.exp(take(t.motion_sd.size)).reshape(t.motion_sd.shape)
        turn_var = None if t.turn_var is None else float(np.exp(take(1)[0]))
        n = t.prior_mean.size
        mean = take(n).copy()
        L = np.diag(np.exp(take(n)))
        L[np.tril_indices(n, -1)] = take(n * (n - 1) // 2)
        landmarks = t.landmarks
        free = self._free_landmarks()
        if free is not None and landmarks is not None:
            xy = landmarks.xy.copy()
            xy[free] = take(2 * int(free.sum())).reshape(-1, 2)
            landmarks = dc_replace(landmarks, xy=xy)
        if not np.all(np.isfinite(x)):
            raise ValueError("the step left the finite numbers")
        return t.replace(
            action=action,
            sensor=sensor,
            prior_mean=mean,
            prior_cov=self._turn(L @ L.T, back=True),
            motion_sd=motion_sd,
            turn_var=turn_var,
            landmarks=landmarks,
        )


def step_length(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, step_max: float) -> float:
    """S3's ``a = |r| / |v|`` on the coordinates, clipped to ``[1, step_max]`` (1 where v is 0)."""
    r, v = x1 - x0, x2 - 2.0 * x1 + x0
    nv = float(np.linalg.norm(v))
    if not nv > 0:
        return 1.0
    return float(np.clip(np.linalg.norm(r) / nv, 1.0, step_max))


def extrapolate(x0: np.ndarray, x1: np.ndarray, x2: np.ndarray, a: float) -> np.ndarray:
    """S3's step ``lambda_0 + 2 a r + a^2 v``."""
    r, v = x1 - x0, x2 - 2.0 * x1 + x0
    return x0 + 2.0 * a * r + a * a * v


@dataclass(frozen=True, eq=False)
class S3Path:
    """One cycle's ``lambda_0``, ``lambda_1``, ``lambda_2`` on ``coords``: S3's steps along them."""

    coords: Coordinates
    x: tuple[np.ndarray, np.ndarray, np.ndarray]

    @classmethod
    def through(cls, coords: Coordinates, models: tuple[EMModel, EMModel, EMModel]) -> S3Path:
        x0, x1, x2 = (coords.vector(m) for m in models)
        return cls(coords, (x0, x1, x2))

    def length(self, step_max: float) -> float:
        return step_length(*self.x, step_max)

    def model_at(self, a: float) -> EMModel | None:
        """The model S3's step of length ``a`` reaches (None where it is no valid model)."""
        try:
            return self.coords.model(extrapolate(*self.x, a))
        except (ValueError, np.linalg.LinAlgError):
            return None
