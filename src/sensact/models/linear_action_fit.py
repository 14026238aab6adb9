"""The M-step of the linear action model ``A(c) = Phi(c) beta`` (sec. 4.3.1 generalized; see
``sensact.learn.em.actions``): weighted least squares, with the command delay searched alongside."""

from __future__ import annotations

import numpy as np

from sensact.core.polyfit import solve_scaled_grams, weighted_lstsq


def delayed(step_commands: np.ndarray, delay_steps: int) -> np.ndarray:
    """Row t is the command of step ``t - delay_steps`` (row 0 before the log's start)."""
    c = np.asarray(step_commands, dtype=float)
    if delay_steps == 0:
        return c
    held = min(delay_steps, len(c))  # a delay longer than the log holds its first command throughout
    return np.concatenate([np.repeat(c[:1], held, axis=0), c[: len(c) - held]])


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
    return fits_by_delay(features, disp_mean, var, dt, previous, free, [0], combined)[0][1]


def fits_by_delay(
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
