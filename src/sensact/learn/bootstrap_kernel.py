"""The compiled core of Algorithm 1 (sec. 3.2.3): one time step, and the batch loop over a log.

``step_kernel`` is the only implementation of the algorithm; ``sensact.learn.bootstrap`` calls it once per
``update()`` (streaming) or through ``run_kernel`` (batch), so both paths give bit-identical models. The state
is a tuple of arrays in the order of ``STATE_NAMES``; scalars and parameters live in small vectors
indexed by the constants below.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensact.core.degree import restart_fit, should_raise_degree, stats_add
from sensact.core.recursive import (
    accumulate_poly,
    accumulate_vector,
    poly_eval,
    shift_features,
    solve_normal_equations,
)

# ---- compiled state layout ----------------------------------------------------------------------------
# fmt: off
# scalar state, sc[...]
(W_A, W_S, T0, T_PREV, C_PREV, A0_PREV, HAS_PREV, N_OBS, N_S, DEG_S, STATUS, T_DIVERGED, N_GATED,
 GATE_SUM, GATE_W, S_READY, A_READY, W_REF, N_A, T_RESTART, RESTARTED, N_STEPS, BUF_I, BUF_N) = range(24)
N_SCAL = 24
# float parameters, prm[...]
(P_GAMMA, P_ALPHA, P_T_START, P_CMD_SCALE, P_OBS_CENTER, P_OBS_SCALE, P_TIME_SCALE, P_RIDGE, P_DIV,
 P_REBASE, P_DEG_THRESHOLD, P_OBS_MIN, P_OBS_MAX, P_GATE, P_DEG_WARMUP, P_DEG_EVAL) = range(16)
N_PRM = 16
# integer parameters, iprm[...]
I_LEARN_S, I_LEARN_A, I_AUTO, I_DEG_MAX, I_P, I_Q, I_WINDOW = range(7)
N_IPRM = 7
# the state tuple passed to the kernels
STATE_NAMES = ("Gs", "hs", "cs", "cs_prev", "Ls", "Ga", "ha", "ca", "ca_prev", "La", "xa", "xbar", "stats", "ring",
               "buf_o", "buf_w", "buf_x", "fixed_s", "fixed_a", "sc", "prm", "iprm")
# fmt: on
# eq. 3.2's cumulative regressors are re-based once one exceeds this (in units of time_scale_s)
REBASE_BOUND = 4.0
assert [STATE_NAMES.index(n) for n in ("cs", "ca", "sc", "prm")] == [2, 7, 19, 20]  # literal indices in run_kernel
# step_kernel return codes
NO_OBS, OBS_WITH_WS, OBS_EARLY, OBS_GATED, DIVERGED, STOPPED, WAITING = range(7)
STATUS_OK, STATUS_DIVERGED = 0, 1


@njit(cache=True)
def _finite_all(a, n):
    for i in range(n):
        if not np.isfinite(a[i]):
            return False
    return True


@njit(cache=True)
def step_kernel(state, t, c, a0c, o):
    """One time step of Algorithm 1 (or of a half-method, by ``iprm``). Returns a code (see above)."""
    # fmt: off
    (Gs, hs, cs, cs_prev, Ls, Ga, ha, ca, ca_prev, La, xa, xbar, stats, ring, buf_o, buf_w, buf_x, fixed_s,
     fixed_a, sc, prm, iprm) = state  # the order of STATE_NAMES
    # fmt: on
    if sc[STATUS] != STATUS_OK:
        return STOPPED
    P = iprm[I_P]
    Q = iprm[I_Q]
    na = Q - 1
    gamma = prm[P_GAMMA]
    ts = prm[P_TIME_SCALE]
    learn_s = iprm[I_LEARN_S] == 1
    learn_a = iprm[I_LEARN_A] == 1
    if learn_s and learn_a and sc[HAS_PREV] == 0.0 and c == 0.0:
        # Algorithm 1's clock starts when the robot is first commanded (sec. 3.3's Aibo walks from the
        # start): a robot held still first would teach S that every reading is w_a = 0, and A_t, learned
        # from that S, would stay at zero
        return WAITING
    sc[N_STEPS] += 1.0

    # ---- motion since the previous step (Algorithm 1, lines 3-7) ----
    if sc[HAS_PREV] == 0.0:
        sc[T0] = t
        sc[HAS_PREV] = 1.0
    else:
        dt = t - sc[T_PREV]
        u = sc[C_PREV] / prm[P_CMD_SCALE]
        if learn_a:
            if sc[T_PREV] - sc[T0] < 2.0 * prm[P_T_START] or sc[A_READY] == 0.0:
                v = sc[A0_PREV]  # line 4: the fixed starting model A0 for t < 2 t_start
            else:
                v = poly_eval(ca[1:], u, na) / ts  # line 6: the current estimate A_t
        else:
            v = poly_eval(fixed_a, u, na)
        sc[W_A] += v * dt
        # eq. 3.2 regressors: dt * sum_{i<t} c_i^j, kept near zero by exact re-basing
        pw = 1.0
        rebase = False
        for j in range(na):
            xa[j + 1] += pw * dt / ts
            pw *= u
            if abs(xa[j + 1]) > prm[P_REBASE]:
                rebase = True
        if rebase:
            shift_features(Ga, ha, xa, Q)
            for j in range(1, Q):
                for i in range(buf_x.shape[0]):
                    buf_x[i, j] -= xa[j]
                xa[j] = 0.0
    sc[T_PREV] = t
    sc[C_PREV] = c
    sc[A0_PREV] = a0c
    tr = t - sc[T0]
    if tr <= 2.0 * prm[P_T_START]:
        sc[W_REF] = max(sc[W_REF], abs(sc[W_A]))

    # ---- observation (lines 8-15) ----
    if not (o == o) or o < prm[P_OBS_MIN] or o > prm[P_OBS_MAX]:
        return NO_OBS
    sc[N_OBS] += 1.0
    uo = (o - prm[P_OBS_CENTER]) / prm[P_OBS_SCALE]
    code = OBS_EARLY
    s_active = (not learn_s) or (tr > prm[P_T_START] and sc[S_READY] == 1.0)  # line 9
    if learn_s and s_active and prm[P_GATE] > 0.0:
        e = poly_eval(cs, uo, P) - sc[W_A]
        cap = prm[P_GATE] ** 2 * sc[GATE_SUM] / sc[GATE_W] if sc[GATE_W] > 0.0 else np.inf
        # winsorized scale: a rejected innovation still counts, clipped at the gate, so a long run of
        # rejections widens the gate instead of locking the learner out
        sc[GATE_SUM] = gamma * sc[GATE_SUM] + min(e * e, cap)
        sc[GATE_W] = gamma * sc[GATE_W] + 1.0
        if sc[GATE_W] >= 20.0 and cap > 0.0 and e * e > cap:  # a zero scale says nothing yet
            sc[N_GATED] += 1.0
            return OBS_GATED
    # Errors-in-variables guard (not in the thesis): regress on the mean of the last `window`
    # observations and the mean of w_a and eq. 3.2's regressors at the same instants. window = 1 is
    # exactly Algorithm 1.
    win = iprm[I_WINDOW]
    bi = int(sc[BUF_I])
    buf_o[bi] = uo
    buf_w[bi] = sc[W_A]
    for j in range(Q):
        buf_x[bi, j] = xa[j]
    sc[BUF_I] = (bi + 1) % win
    nb = int(min(sc[BUF_N] + 1.0, win))
    sc[BUF_N] = nb
    ub = 0.0
    wb = 0.0
    for i in range(nb):
        ub += buf_o[i]
        wb += buf_w[i]
    ub /= nb
    wb /= nb
    for j in range(Q):
        acc = 0.0
        for i in range(nb):
            acc += buf_x[i, j]
        xbar[j] = acc / nb
    target = wb
    if s_active:
        ws = poly_eval(cs if learn_s else fixed_s, ub, P)  # line 10: w_s = S_t(o_t)
        sc[W_S] = ws
        code = OBS_WITH_WS
        if learn_a:
            accumulate_vector(Ga, ha, xbar, ws, gamma, Q)  # line 11: UPDATE A_t (eq. 3.2)
            sc[N_A] += 1.0
            if sc[N_A] >= Q:
                for i in range(Q):
                    ca_prev[i] = ca[i]
                if solve_normal_equations(Ga, ha, Q, prm[P_RIDGE], La, ca):
                    sc[A_READY] = 1.0
        if learn_s and learn_a:
            delta = prm[P_ALPHA] * (ws - wb)  # line 12: w_a <- (1 - alpha) w_a + alpha w_s
            sc[W_A] += delta
            for i in range(nb):
                buf_w[i] += delta
            target = wb + delta
    if learn_s:
        # line 14: UPDATE S_t from (o_t, w_a)
        p = int(sc[DEG_S]) + 1
        auto = iprm[I_AUTO] == 1
        if auto and sc[S_READY] == 1.0 and tr - sc[T_RESTART] >= prm[P_DEG_WARMUP]:
            stats_add(stats, ring, win, target - poly_eval(cs, ub, P), gamma)
        accumulate_poly(Gs, hs, ub, target, gamma, p)
        sc[N_S] += 1.0
        # after a degree restart, keep using the old S until the new fit has a t_start of data
        if sc[N_S] >= p and (sc[RESTARTED] == 0.0 or tr - sc[T_RESTART] >= prm[P_T_START]):
            for i in range(P):
                cs_prev[i] = cs[i]
            if solve_normal_equations(Gs, hs, p, prm[P_RIDGE], Ls, cs):
                for i in range(p, P):
                    cs[i] = 0.0
                sc[S_READY] = 1.0
        if (
            auto
            and p - 1 < iprm[I_DEG_MAX]
            and tr - sc[T_RESTART] >= prm[P_DEG_WARMUP] + prm[P_DEG_EVAL]
            and should_raise_degree(stats, 1.0, prm[P_DEG_THRESHOLD])
        ):
            sc[DEG_S] += 1.0  # sec. 3.3.3: raise the degree and restart the regression
            restart_fit(Gs, hs, stats)
            sc[N_S] = 0.0
            sc[T_RESTART] = tr
            sc[RESTARTED] = 1.0

    # ---- divergence: non-finite or runaway estimates end the run with the last good models ----
    bad = not (np.isfinite(sc[W_A]) and np.isfinite(sc[W_S]))
    bad = bad or not _finite_all(cs, P) or not _finite_all(ca, Q)
    if learn_s and learn_a and sc[W_REF] > 0.0 and tr > 2.0 * prm[P_T_START]:  # once A_t drives w_a
        lim = prm[P_DIV] * sc[W_REF]
        bad = bad or abs(sc[W_A]) > lim or abs(sc[W_S]) > lim
    if bad:
        sc[STATUS] = STATUS_DIVERGED
        sc[T_DIVERGED] = tr
        for i in range(P):
            cs[i] = cs_prev[i]
        for i in range(Q):
            ca[i] = ca_prev[i]
        return DIVERGED
    return code


@njit(cache=True)
def run_kernel(
    state, times, commands, a0v, obs, k0, k1, w_a_out, w_s_out, snap_t, snap_s, snap_a, snap_deg, n_snap, snap_interval
):
    """The batch path: ``step_kernel`` over steps ``k0..k1-1``, recording w_a, w_s and model snapshots."""
    cs, ca, sc, prm = state[2], state[7], state[19], state[20]  # numba needs literal tuple indices
    ns = n_snap[0]
    for k in range(k0, k1):
        code = step_kernel(state, times[k], commands[k], a0v[k], obs[k])
        if code == STOPPED:
            break
        if code == WAITING:  # before the first command: no estimate yet (w_a_out stays NaN)
            continue
        w_a_out[k] = sc[W_A]
        w_s_out[k] = sc[W_S] if code == OBS_WITH_WS else np.nan
        tr = times[k] - sc[T0]
        if ns < snap_t.shape[0] and (
            ns == 0 or tr >= snap_t[ns - 1] + snap_interval or k == times.shape[0] - 1 or code == DIVERGED
        ):
            snap_t[ns] = tr
            for i in range(cs.shape[0]):
                snap_s[ns, i] = cs[i] if sc[S_READY] == 1.0 else np.nan
            for i in range(ca.shape[0] - 1):
                snap_a[ns, i] = ca[i + 1] / prm[P_TIME_SCALE] if sc[A_READY] == 1.0 else np.nan
            snap_deg[ns] = sc[DEG_S]
            ns += 1
        if code == DIVERGED:
            break
    n_snap[0] = ns
