"""The action side of EM: per-step means and motion noise for the E-step, and their M-step.

* ``step_velocity`` / ``step_motion_var``: what the E-step needs at every step, from either action model.
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

from sensact.core.polyfit import solve_scaled_grams, weighted_lstsq
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import ActionModel, EMModel
from sensact.models.linear_action import LinearActionModel, delayed


def step_velocity(action: ActionModel, data: LandmarkLog) -> np.ndarray:
    """``(T, n)``: the model's mean robot-frame velocity in force from each step to the next."""
    if isinstance(action, LinearActionModel):
        if data.step_commands is None:
            raise ValueError("a continuous action model needs a log with per-step commands")
        return action.step_features(data.step_commands) @ action.coefficients
    if data.n_actions != action.n_actions:
        raise ValueError(f"the action table has {action.n_actions} actions but the log has {data.n_actions}")
    out = np.zeros((data.n_steps, action.velocities.shape[1]))
    ok = data.actions >= 0
    out[ok] = action.velocities[data.actions[ok]]
    return out


def step_motion_var(model: EMModel, data: LandmarkLog, velocity: np.ndarray | None = None) -> np.ndarray:
    """``(T, n)``: the diagonal of Sigma_m at each step (per action when the model has one row each;
    with ``turn_var``, the heading's grows by ``turn_var |A(c_t)_theta|``, from ``velocity`` when the
    caller has ``step_velocity`` already)."""
    var = model.motion_sd**2
    if var.shape[0] == 1:
        out = np.repeat(var, data.n_steps, axis=0)
        if model.turn_var is not None:
            v = step_velocity(model.action, data) if velocity is None else velocity
            out[:, 2] += model.turn_var * np.abs(v[:, 2])
        return out
    out = np.repeat(var.mean(axis=0, keepdims=True), data.n_steps, axis=0)
    ok = data.actions >= 0
    out[ok] = var[data.actions[ok]]
    return out


def table_velocities(disp_mean: np.ndarray, data: LandmarkLog, previous: np.ndarray) -> np.ndarray:
    """Eq. 4.18: mu_a is the mean of D(mu_xi,t) over Q(a) = {t : c_t = a}, divided by dt.

    An action that never ran keeps its previous velocity.
    """
    a = data.actions[:-1]
    valid = a >= 0
    counts = np.bincount(a[valid], minlength=data.n_actions).astype(float)
    out = np.array(previous, dtype=float, copy=True)
    seen = counts > 0
    for i in range(out.shape[1]):
        sums = np.bincount(a[valid], weights=disp_mean[valid, i], minlength=data.n_actions)
        out[seen, i] = sums[seen] / counts[seen] / data.dt_s
    return out


def linear_coefficients(
    features: np.ndarray,
    disp_mean: np.ndarray,
    var: np.ndarray,
    dt: float,
    previous: np.ndarray,
    free: np.ndarray | None = None,
    combined: dict[int, np.ndarray] | None = None,
) -> np.ndarray:
    """beta minimizing ``sum_t (Dbar_t,i - Phi_t beta_i dt)^2 / var_t,i`` for each component i.

    ``features`` is ``(T-1, F)``, ``disp_mean`` and ``var`` ``(T-1, n)``. Features that never vary keep
    their previous coefficients: they are zero at every step, so the log says nothing about them.
    Coefficients not ``free`` (``(F, n)`` bool, as ``LinearActionModel.free_coefficients``) are held at
    zero; each component is fitted on its free columns only (the components are independent). A
    component in ``combined`` (``LinearActionModel.combined_inputs``) is ``beta_i = P theta``, fitted on
    the columns ``Phi P`` (an input zero on every row gets 0, not its previous coefficient).
    """
    return _fits_by_delay(features, disp_mean, var, dt, previous, free, [0], combined)[0][1]


def linear_action_update(
    action: LinearActionModel, data: LandmarkLog, disp_mean: np.ndarray, var: np.ndarray, max_delay: int
) -> LinearActionModel:
    """The M-step of ``A(c) = Phi(c) beta`` with its command delay: for each delay in ``0..max_delay``
    the weighted least-squares beta, and of those the pair with the least weighted squared error (the
    same expected log-likelihood, maximized over a discrete parameter too)."""
    delays = list(range(max_delay + 1)) if max_delay > 0 else [action.delay_steps]
    Phi0 = action.step_features(data.step_commands, 0)
    free, combined = action.free_coefficients, action.combined_inputs
    fits = _fits_by_delay(Phi0, disp_mean, var, data.dt_s, action.coefficients, free, delays, combined)
    best = min(range(len(fits)), key=lambda k: fits[k][0])  # the first of equals, as a strict < keeps
    return action.with_coefficients(fits[best][1], delays[best])


def _fits_by_delay(
    Phi0: np.ndarray,
    disp_mean: np.ndarray,
    var: np.ndarray,
    dt: float,
    previous: np.ndarray,
    free: np.ndarray | None,
    delays: list[int],
    combined: dict[int, np.ndarray] | None = None,
) -> list[tuple[float, np.ndarray]]:
    """``(weighted squared error, beta)`` of ``linear_coefficients`` on ``delayed(Phi0, d)[:T-1]`` for
    each delay ``d``, from sums over the rows formed once per delay instead of a least-squares solve on
    the rows for each (the M-step tries 16 delays every iteration on 27,000 steps), and every delay's
    small systems solved in one batched call.

    Delayed row t is ``Phi0[max(t - d, 0)]``, so ``X'WX = sum_{t >= d} w_t Phi0_{t-d} Phi0_{t-d}'`` plus
    ``Phi0_0 Phi0_0'`` times the first ``d`` weights; with a shared Sigma_m that is the weight times all
    rows' outer products but the last ``d``, plus ``d`` times the first's. ``X'Wy`` likewise, and the
    error is ``y'Wy - 2 beta'X'Wy + beta'X'WX beta``."""
    n_rows, n = disp_mean.shape
    F = Phi0.shape[1]
    free = np.ones((F, n), dtype=bool) if free is None else free
    heads = [min(d, n_rows) for d in delays]
    L = max(heads)
    X = Phi0[:n_rows]
    w = 1.0 / var
    wy = w * disp_mean
    wyy = float(np.einsum("ti,ti->", wy, disp_mean))
    first = np.outer(Phi0[0], Phi0[0])
    wy_head = np.concatenate([np.zeros((1, n)), np.cumsum(wy[:L], axis=0)])  # sums of the first h rows
    rhs = np.stack([wy[h:].T @ X[: n_rows - h] for h in heads]) + wy_head[heads][:, :, None] * Phi0[0]
    if np.all(var == var[0]):  # Sigma_m shared: each gram is the one weight times sums of outer products
        tail = X[n_rows - L :][::-1]  # the last rows, last first
        tail_sums = np.concatenate([np.zeros((1, F, F)), np.cumsum(tail[:, :, None] * tail[:, None, :], axis=0)])
        kept = (X.T @ X)[None] - tail_sums[heads] + np.asarray(heads, dtype=float)[:, None, None] * first
        gram = w[0][None, :, None, None] * kept[:, None]
    else:
        outer = (X[:, :, None] * X[:, None, :]).reshape(n_rows, F * F)
        w_head = np.concatenate([np.zeros((1, n)), np.cumsum(w[:L], axis=0)])
        gram = np.stack([w[h:].T @ outer[: n_rows - h] for h in heads]).reshape(len(heads), n, F, F)
        gram += w_head[heads][:, :, None, None] * first
    # a feature zero on every row a delay reads says nothing at that delay (it keeps its coefficient)
    reads = [max(n_rows - d, 1) for d in delays]
    if X[: min(reads)].any(axis=0).all():
        used = np.ones((len(delays), F), dtype=bool)
    else:
        nonzero = Phi0 != 0.0
        first_nonzero = np.where(nonzero.any(axis=0), nonzero.argmax(axis=0), len(Phi0))
        used = first_nonzero[None, :] < np.asarray(reads)[:, None]
    betas = np.repeat(np.asarray(previous, dtype=float)[None], len(delays), axis=0)
    betas[:, ~free] = 0.0
    # one batched solve per distinct set of columns (usually one: every delay, every component)
    systems: dict[bytes, list[tuple[int, int]]] = {}
    combined = combined or {}
    for j in range(len(delays)):
        for i in range(n):
            if i in combined:
                continue
            cols = used[j] & free[:, i]
            if cols.any():
                systems.setdefault(cols.tobytes(), []).append((j, i))
    for key, members in systems.items():
        cols = np.frombuffer(key, dtype=bool)
        js, cs = np.array([m[0] for m in members]), np.array([m[1] for m in members])
        G = gram[js, cs][:, cols][:, :, cols] * (dt * dt)
        coef, ok = solve_scaled_grams(G, rhs[js, cs][:, cols] * dt)
        for k in np.flatnonzero(~ok):  # ill-conditioned sums: solve from the rows
            coef[k] = weighted_lstsq(delayed(Phi0, delays[js[k]])[:n_rows, cols] * dt, disp_mean[:, cs[k]], w[:, cs[k]])
        idx = np.flatnonzero(cols)
        betas[js[:, None], idx[None, :], cs[:, None]] = coef
    for i, P in combined.items():  # beta_i = P theta: the sums projected onto P's columns
        G = np.einsum("fa,dfg,gb->dab", P, gram[:, i], P) * (dt * dt)
        coef, ok = solve_scaled_grams(G, np.einsum("fa,df->da", P, rhs[:, i]) * dt)
        for k in np.flatnonzero(~ok):
            coef[k] = weighted_lstsq(delayed(Phi0, delays[k])[:n_rows] @ P * dt, disp_mean[:, i], w[:, i])
        betas[:, :, i] = coef @ P.T
    sse = (
        wyy
        - 2.0 * dt * np.einsum("dfi,dif->d", betas, rhs)
        + dt * dt * np.einsum("dfi,difg,dgi->d", betas, gram, betas)
    )
    return [(float(sse[j]), betas[j]) for j in range(len(delays))]


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
