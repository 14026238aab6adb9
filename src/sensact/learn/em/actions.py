"""The action side of EM: per-step means and motion noise for the E-step, and their M-step.

* ``step_motion_var``: Sigma_m at every step, for the E-step (each action model gives its own
  ``step_velocity``).
* ``table_velocities``: eq. 4.18, the mean of ``D(mu_xi,t)`` over the steps of each action, over dt.
* ``linear_coefficients``: the continuous model ``A(c) = Phi(c) beta``. The motion term of the expected
  complete-data log-likelihood (sec. 4.3.1) is ``-1/2 sum_t E[(D_t - Phi_t beta dt)' Sigma_t^-1 (...)]``;
  with ``D`` linearized under xi_t this is ``(Dbar_t - Phi_t beta dt)' Sigma_t^-1 (...)`` plus terms free of
  beta, so beta is the weighted least-squares fit of ``Dbar_t`` on ``Phi_t dt``, one column per velocity
  component (Sigma_m is diagonal). With a one-hot Phi it is eq. 4.18 exactly.
* ``motion_noise``: the same expectation maximized over a diagonal ``Sigma_m`` gives
  ``Sigma_m = mean_t [(Dbar_t - A(c_t) dt)^2 + Var_xi(D_t)]`` per component (the expected squared
  deviation of the linearized D, using the xi covariances: ``motion_second_moments``), over all steps
  (shared) or each action's.
* ``turning_variance``: the heading's share of that expectation when its variance is ``a + b |turn_t|``.
"""

from __future__ import annotations

import numpy as np

from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel


def step_motion_var(model: EMModel, data: LandmarkLog, velocity: np.ndarray | None = None) -> np.ndarray:
    """``(T, n)``: the diagonal of Sigma_m at each step (per action when the model has one row each;
    with ``turn_var``, the heading's grows by ``turn_var |A(c_t)_theta|``, from ``velocity`` when the
    caller has ``step_velocity`` already)."""
    var = model.motion_sd**2
    if var.shape[0] == 1:
        out = np.repeat(var, data.n_steps, axis=0)
        if model.turn_var is not None:
            v = model.action.step_velocity(data) if velocity is None else velocity
            out[:, 2] += model.turn_var * np.abs(v[:, 2])
        return out
    out = np.repeat(var.mean(axis=0, keepdims=True), data.n_steps, axis=0)
    ok = data.actions >= 0
    out[ok] = var[data.actions[ok]]
    return out


def motion_noise(
    second: np.ndarray, groups: np.ndarray | None, n_groups: int, floor_sd: np.ndarray, previous: np.ndarray
) -> np.ndarray:
    """Sigma_m (as standard deviations, rows per group) from the steps' ``motion_second_moments``; see
    the module docstring. ``groups[t]`` is the action of step t (None = shared)."""
    out = np.array(previous, dtype=float, copy=True)
    if groups is None:
        out = np.sqrt(second.mean(axis=0, keepdims=True))
    else:
        ok = groups >= 0
        counts = np.bincount(groups[ok], minlength=n_groups)
        for i in range(second.shape[1]):
            sums = np.bincount(groups[ok], weights=second[ok, i], minlength=n_groups)
            seen = counts > 0
            out[seen, i] = np.sqrt(sums[seen] / counts[seen])
    return np.maximum(out, floor_sd)


def motion_second_moments(disp_mean: np.ndarray, disp_cov: np.ndarray, mean_disp: np.ndarray) -> np.ndarray:
    """``(T-1, n)``: ``E[(D_t - A(c_t) dt)^2]`` per component under xi_t, with D linearized (the angle's
    deviation wrapped)."""
    dev = disp_mean - mean_disp
    if dev.shape[1] == 3:
        dev[:, 2] = np.mod(dev[:, 2] + np.pi, 2 * np.pi) - np.pi
    return dev**2 + np.diagonal(disp_cov, axis1=1, axis2=2)


def turning_variance(
    second: np.ndarray, turn: np.ndarray, floor_var: float, previous: tuple[float, float]
) -> tuple[float, float]:
    """``(a, b)`` of a heading variance ``a + b |turn_t|`` per step, from the expected squared heading
    deviations ``second`` (the heading term of the expected complete-data log-likelihood, sec. 4.3.1,
    with a variance that differs by step).

    Each ``second_t`` has mean ``v_t = a + b |turn_t|``, and the maximum over (a, b) solves
    ``sum_t (second_t - v_t) / v_t^2 (1, |turn_t|) = 0``: least squares weighted by ``1 / v_t^2``,
    iterated (Fisher scoring), with ``a >= floor_var`` and ``b >= 0``.
    """
    w_turn = np.abs(turn)
    a, b = max(previous[0], floor_var), max(previous[1], 0.0)
    for _ in range(50):
        w = 1.0 / (a + b * w_turn) ** 2
        sw, st, stt = w.sum(), (w * w_turn).sum(), (w * w_turn**2).sum()
        y0, y1 = (w * second).sum(), (w * w_turn * second).sum()
        det = sw * stt - st * st
        if det > 1e-12 * sw * max(stt, 1e-300):
            a_new, b_new = (stt * y0 - st * y1) / det, (sw * y1 - st * y0) / det
        else:  # the log never turns: nothing to learn b from
            a_new, b_new = y0 / sw, 0.0
        if b_new < 0.0:
            a_new, b_new = y0 / sw, 0.0
        if a_new < floor_var:
            a_new = floor_var
            b_new = max((w * w_turn * (second - a_new)).sum() / stt, 0.0) if stt > 0 else 0.0
        done = abs(a_new - a) <= 1e-9 * a and abs(b_new - b) <= 1e-9 * max(b, a)
        a, b = float(a_new), float(b_new)
        if done:
            break
    return a, b
