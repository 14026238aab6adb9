"""The E-step (sec. 4.2): the posterior over poses given every action and observation.

``e_step(model, data)`` runs the compiled forward EKF and two-filter smoother of
``sensact.core.ekf_smoother`` and returns ``Posteriors``: alpha, gamma, the displacement moments under
xi, each reading's weight, and ``log P(O | C, lambda)`` (eq. 4.14). ``log_likelihood(model, data)`` is
that likelihood from the forward pass alone, for the searches that only compare models.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field

import numpy as np

from sensact.core.ekf_smoother import OK, STUDENT_T_JOINT, StepInputs, passes_for
from sensact.learn.em.actions import step_motion_var
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel
from sensact.reprs import compact_repr


@dataclass
class PassCount:
    """How many passes over the log a fit ran: E-steps (forward and backward), and the searches' forward
    passes alone (``log_likelihood``), across the threads of a start race."""

    e_steps: int = 0
    forward_only: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, smoothed: bool) -> None:
        with self._lock:
            if smoothed:
                self.e_steps += 1
            else:
                self.forward_only += 1


_COUNT: ContextVar[PassCount | None] = ContextVar("sensact_e_steps", default=None)


@contextmanager
def counting_passes() -> Iterator[PassCount]:
    """Counts every E-step and likelihood run inside (threads started with the context copied included)."""
    count = PassCount()
    token = _COUNT.set(count)
    try:
        yield count
    finally:
        _COUNT.reset(token)


def _counted(smoothed: bool) -> None:
    count = _COUNT.get()
    if count is not None:
        count.add(smoothed)


@dataclass(frozen=True, eq=False)
class Posteriors:
    __repr__ = compact_repr  # a line, never the arrays
    loglik: float  # log P(O | C, lambda), eq. 4.14
    ok: bool  # False if a covariance stopped being positive definite
    mean_alpha: np.ndarray  # (T, n) filtered means
    cov_alpha: np.ndarray  # (T, n, n)
    mean_gamma: np.ndarray  # (T, n) smoothed means, eq. 4.9
    cov_gamma: np.ndarray  # (T, n, n) eq. 4.10
    disp_mean: np.ndarray  # (T-1, n) D(mu_xi,t), eq. 4.18
    disp_cov: np.ndarray  # (T-1, n, n) covariance of the linearized D under xi_t
    obs_used: np.ndarray  # (K,) bool; False for pruned observations
    n_used: int
    weights: np.ndarray  # (K, C+1) each reading channel's weight, then the bearing's; 0 = not used


def e_step(
    model: EMModel,
    data: LandmarkLog,
    motion_var: np.ndarray | None = None,
    *,
    obs_use: np.ndarray | None = None,
    prune_rad_per_step: float = 0.0,
) -> Posteriors:
    """Alpha, gamma and xi for ``model`` on ``data``. ``obs_use`` masks observations (a copy is pruned).

    ``motion_var`` overrides the model's Sigma_m with one shared diagonal.
    """
    _counted(True)
    T = data.n_steps
    n = model.prior_mean.size
    use = np.ones(data.n_observations, dtype=np.bool_) if obs_use is None else np.array(obs_use, dtype=np.bool_)
    mu_g = np.empty((T, n))
    P_g = np.empty((T, n, n))
    d_mu = np.full((T - 1, n), np.nan)
    d_P = np.full((T - 1, n, n), np.nan)
    status, loglik, n_used, mu_a, P_a, weights = _run_passes(
        model, data, motion_var, use, prune_rad_per_step, (mu_g, P_g, d_mu, d_P)
    )
    ok = status == OK and np.isfinite(loglik)
    return Posteriors(float(loglik), bool(ok), mu_a, P_a, mu_g, P_g, d_mu, d_P, use, int(n_used), weights)


def log_likelihood(model: EMModel, data: LandmarkLog, *, obs_use: np.ndarray | None = None) -> float:
    """``log P(O | C, lambda)`` (eq. 4.14) from the forward pass alone, -inf if the filter fails: the same
    number, bit for bit, as ``e_step(...).loglik``, in a quarter of the time. For searches that compare
    models by their likelihood and smooth only the one they keep."""
    _counted(False)
    use = np.ones(data.n_observations, dtype=np.bool_) if obs_use is None else np.array(obs_use, dtype=np.bool_)
    status, loglik, *_ = _run_passes(model, data, None, use, 0.0, None)
    return float(loglik) if status == OK and np.isfinite(loglik) else -np.inf


def sighting_logliks(model: EMModel, data: LandmarkLog, *, obs_use: np.ndarray | None = None) -> np.ndarray | None:
    """Each sighting's share of ``log_likelihood`` (its readings' predictive densities, eq. 4.14's terms;
    0 where unused), from one forward pass; they sum to it. None if the filter fails."""
    _counted(False)
    use = np.ones(data.n_observations, dtype=np.bool_) if obs_use is None else np.array(obs_use, dtype=np.bool_)
    out = np.zeros(data.n_observations)
    status, loglik, *_ = _run_passes(model, data, None, use, 0.0, None, None, out)
    return out if status == OK and np.isfinite(loglik) else None


@dataclass(frozen=True, eq=False)
class Innovations:
    """The forward pass's standardized innovations: under a correct linear-Gaussian model, independent
    N(0, 1) in the order the filter met them."""

    __repr__ = compact_repr  # a line, never the arrays

    ok: bool
    z: np.ndarray  # (K, C+1) each reading channel's, then the bearing's; NaN where not evaluated
    # (K, C+1, n) each z's derivative in a gain 1 + g_a on velocity component a (the kernel's innov_sens)
    sensitivity: np.ndarray


def innovations(model: EMModel, data: LandmarkLog) -> Innovations:
    """Every reading's standardized innovation under ``model`` (sec. 2.4's EKF, as the E-step runs it)."""
    n = model.prior_mean.size
    C = len(model.sensor.channels)
    z = np.full((data.n_observations, C + 1), np.nan)
    sens = np.zeros((data.n_observations, C + 1, n))
    use = np.ones(data.n_observations, dtype=np.bool_)
    status, loglik, *_ = _run_passes(model, data, None, use, 0.0, None, (z, sens))
    return Innovations(status == OK and bool(np.isfinite(loglik)), z, sens)


def _run_passes(
    model: EMModel,
    data: LandmarkLog,
    motion_var: np.ndarray | None,
    use: np.ndarray,
    prune_rad_per_step: float,
    smoothed: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None,
    record: tuple[np.ndarray, np.ndarray] | None = None,
    obs_loglik: np.ndarray | None = None,
) -> tuple[int, float, int, np.ndarray, np.ndarray, np.ndarray]:
    """The compiled passes on ``model`` and ``data``: ``(status, loglik, n_used, mu_a, P_a, weights)``.
    ``smoothed`` is ``(mu_g, P_g, d_mu, d_P)`` to fill, or None for the forward pass only; ``record`` is
    ``(innov, innov_sens)`` to fill with the standardized innovations and their sensitivities;
    ``obs_loglik`` (zeros) each sighting's share of the likelihood."""
    if model.geometry != data.geometry:
        raise ValueError(f"a {model.geometry} model cannot run on a {data.geometry} log")
    T = data.n_steps
    n = model.prior_mean.size
    velocity = model.action.step_velocity(data)
    if motion_var is None:
        var_steps = step_motion_var(model, data, velocity)
    else:
        var_steps = np.repeat(np.asarray(motion_var, dtype=float).reshape(1, n), T, axis=0)
    mu_a = np.empty((T, n))
    P_a = np.empty((T, n, n))
    steps = StepInputs(data.mode, float(data.dt_s), np.ascontiguousarray(velocity), np.ascontiguousarray(var_steps))
    sight, inputs = model.sensor.kernel_inputs(data)
    weights = np.zeros((data.n_observations, sight.readings.shape[1] + 1))
    kinds, params = inputs.robust_kind, inputs.robust_param
    joint_dof = float(params[kinds == STUDENT_T_JOINT][0]) if np.any(kinds == STUDENT_T_JOINT) else None
    forward, backward, pairwise = passes_for(n)
    innov, innov_sens = record if record is not None else (None, None)
    status, loglik, n_used = forward(
        steps,
        sight,
        inputs,
        model.prior_mean.copy(),
        model.prior_cov.copy(),
        use,
        float(prune_rad_per_step),
        joint_dof,
        weights,
        mu_a,
        P_a,
        innov,
        innov_sens,
        obs_loglik,
    )
    if smoothed is not None and status == OK:
        mu_g, P_g, d_mu, d_P = smoothed
        delta_Y, delta_z = np.empty((T, n, n)), np.empty((T, n))
        status = backward(steps, sight, inputs, use, weights, mu_a, P_a, mu_g, P_g, delta_Y, delta_z)
        if status == OK:
            status = pairwise(steps, mu_a, P_a, mu_g, delta_Y, delta_z, d_mu, d_P)
    return status, loglik, n_used, mu_a, P_a, weights
