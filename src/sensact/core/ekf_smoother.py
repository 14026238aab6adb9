"""The E-step's compiled passes (sec. 4.2): an EKF forward, a two-filter smoother backward, the pairwise
posteriors.

Three passes run over ``T`` steps, each compiled on its own (``passes_for``), as dynamax splits its
filter and smoother; their inputs travel as three typed tuples (``StepInputs``, ``Sightings``,
``SensorInputs``):

* **forward (alpha):** the EKF of sec. 2.4. Each observation's channels (every reading channel
  ``f_i(dist)``, then the bearing) are scalar measurement updates in Joseph form, so the covariance
  stays symmetric positive definite; bearing innovations are wrapped to [-pi, pi). The forward pass also
  decides, once, how much each reading counts: 0 when it is missing, outside its channel's distance
  window or gated, the Student-t weight when the channel is robust, else 1. Every later pass reuses
  those weights, so that alpha, beta and xi describe the same model. The log-likelihood
  ``log P(O | C, lambda)`` is summed from the innovations (eq. 4.14). Frames without an observation
  get only the time update (eq. 2.28).
* **backward (beta, eq. 4.4)** in information form ``beta_t(w) ∝ exp(-e'Y e / 2 + z'e)``,
  ``e = w - mu_alpha,t``. It starts from ``Y = 0``: the thesis's "infinite covariance", exactly.
  Its linearizations use the forward means; the thesis's backward EKF would linearize at its own mean,
  which does not exist while ``Y`` is singular.
* **gamma** (eqs. 4.9, 4.10): alpha times beta, in the same backward pass, which keeps each step's
  ``delta`` for the next.
* **pairwise: xi** (eqs. 4.11, 4.12): the joint of ``(w_t, w_t+1)`` from ``alpha_t``,
  ``delta_t+1 = beta_t+1 P(o_t+1 | w_t+1)`` and the
  pseudo-measurement ``D(w_t, w_t+1) ~ N(A(c_t) dt, Sigma_m)``, linearized at the smoothed means. It is
  solved in information form because ``delta``'s covariance may be infinite.

Exact for a linear-Gaussian model: the forward pass is then the Kalman filter, gamma the RTS smoother's
marginals and xi the exact pairwise posterior (tests/test_estep.py checks all three against dense
Gaussian conditioning).

Robust channels (an extension beyond the thesis, ``docs/em-real.md``): a Student-t channel updates with
variance ``r / w``, ``w = (nu + 1) / (nu + e^2 / S)`` from the innovation ``e`` and its variance ``S``,
and adds the Student-t log density; joint Student-t readings (``STUDENT_T_JOINT``) share one weight, that
of their sighting's innovations as one multivariate t (``_joint_weight``), and update first; a gated
channel drops a reading beyond ``gate`` innovation sigmas and adds the Gaussian log density at the gate,
so that the likelihood cannot grow by gating more.

What a run does not use is not compiled: the innovations' record (``innov`` None) and the joint Student-t
(``joint_dof`` None) are pruned from the forward pass before numba types it, so the E-step's first run
compiles neither.

Angles inside the passes are not wrapped, so that theta is one continuous coordinate for the
information-form algebra; only differences and innovations are wrapped.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from sensact.core.angles import wrap
from sensact.core.pose_models import (
    displacement,
    landmark_range,
    motion_covariance,
    observe_bearing,
    observe_height,
    predict,
)
from sensact.core.smallmat import (
    add_sandwich,
    cholesky,
    cholesky_inverse,
    cholesky_solve_vec,
    forward_substitute,
    lu_solve_inplace,
    symmetrize,
)

OK = 0
NOT_POSITIVE_DEFINITE = 1
SINGULAR = 2

GAUSSIAN = 0
STUDENT_T = 1
GATE = 2
STUDENT_T_JOINT = 3  # a Student-t reading that shares its sighting's one weight (``_joint_weight``)

# what a sighting reads, the kernel's switch as ``mode`` is the geometry's: each sensor model names its kind
LANDMARK = 0  # range-like channels f_i(dist) of a landmark, then its bearing (eq. 4.19)


@njit(cache=True, error_model="numpy")
def _hph(P, H, n):
    s = 0.0
    for i in range(n):
        for j in range(n):
            s += H[i] * P[i, j] * H[j]
    return s


@njit(cache=True, error_model="numpy")
def _reading_weight(kind, param, nu, S):
    """How much a reading with innovation ``nu`` (variance ``S``) counts, and its log density."""
    if kind == STUDENT_T:
        q = nu * nu / S
        w = (param + 1.0) / (param + q)
        ld = (
            math.lgamma(0.5 * (param + 1.0))
            - math.lgamma(0.5 * param)
            - 0.5 * np.log(param * np.pi * S)
            - 0.5 * (param + 1.0) * np.log1p(q / param)
        )
        return w, ld
    if kind == GATE:
        q = nu * nu / S
        if q > param * param:
            return 0.0, -0.5 * (param * param + np.log(2.0 * np.pi * S))
    return 1.0, -0.5 * (nu * nu / S + np.log(2.0 * np.pi * S))


@njit(cache=True, error_model="numpy")
def _joint_weight(Hj, ej, rj, d, P, n, S, L, y, param):
    """One weight for a sighting's ``d`` Student-t readings, read as one multivariate t with ``param``
    degrees of freedom (Lange, Little and Taylor 1989): ``w = (param + d) / (param + q)``, ``q = e' S^-1 e``
    over the innovations ``ej`` (rows ``Hj``, variances ``rj``) at the prediction, ``S = Hj P Hj' + diag(rj)``.
    Returns ``(w, log density, ok)``; with ``d = 1`` it is ``_reading_weight``'s Student-t, bit for bit
    in exact arithmetic."""
    for a in range(d):
        for b in range(a + 1):
            s = 0.0
            for i in range(n):
                for j in range(n):
                    s += Hj[a, i] * P[i, j] * Hj[b, j]
            S[a, b] = s
            S[b, a] = s
        S[a, a] += rj[a]
    if not cholesky(S, L, d):
        return 0.0, 0.0, False
    q = 0.0
    logdet = 0.0
    for a in range(d):
        s = ej[a]
        for b in range(a):
            s -= L[a, b] * y[b]
        y[a] = s / L[a, a]
        q += y[a] * y[a]
        logdet += 2.0 * np.log(L[a, a])
    w = (param + d) / (param + q)
    ld = (
        math.lgamma(0.5 * (param + d))
        - math.lgamma(0.5 * param)
        - 0.5 * d * np.log(param * np.pi)
        - 0.5 * logdet
        - 0.5 * (param + d) * np.log1p(q / param)
    )
    return w, ld, True


@njit(cache=True, error_model="numpy")
def _scalar_update(m, P, H, nu, r, n, PH, K, A, tmp, tmp2):
    """Joseph-form scalar measurement update (eqs. 2.17-2.19); returns the innovation's log density."""
    S = r
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += P[i, j] * H[j]
        PH[i] = s
        S += H[i] * s
    for i in range(n):
        K[i] = PH[i] / S
        m[i] += K[i] * nu
    for i in range(n):
        for j in range(n):
            A[i, j] = (1.0 if i == j else 0.0) - K[i] * H[j]
    # P <- A P A' + r K K', into tmp2 then back (P is read while the product is formed)
    for i in range(n):
        for j in range(n):
            tmp2[i, j] = r * K[i] * K[j]
    add_sandwich(A, P, tmp2, tmp, n)
    for i in range(n):
        for j in range(n):
            P[i, j] = tmp2[i, j]
    symmetrize(P, n)
    return -0.5 * (nu * nu / S + np.log(2.0 * np.pi * S))


@njit(cache=True, error_model="numpy")
def _record(innov, innov_sens, k, c, nu, S, H, Sv, n):
    sd = np.sqrt(S)
    innov[k, c] = nu / sd
    for a in range(n):
        s = 0.0
        for i in range(n):
            s += H[i] * Sv[a, i]
        innov_sens[k, c, a] = -s / sd


@njit(cache=True, error_model="numpy")
def _sensitivity_update(Sv, H, K, n):
    """The measurement update's effect on d mean / d g: ``(I - K H)`` (eq. 2.18 differentiated)."""
    for a in range(n):
        s = 0.0
        for i in range(n):
            s += H[i] * Sv[a, i]
        for i in range(n):
            Sv[a, i] -= K[i] * s


@njit(cache=True, error_model="numpy")
def _sensitivity_predict(mode, m, velocity, dt, F, Sv, n):
    """The time update's: ``F s + d g(m, disp) / d g_a`` (eq. 2.28 differentiated), where the gain ``g_a``
    scales the displacement's component ``a``; ``F`` is the step's Jacobian at ``m``."""
    one, out, old = np.zeros(n), np.zeros(n), np.zeros(n)
    Fa = np.zeros((n, n))
    for a in range(n):
        for i in range(n):
            one[i] = 0.0
            old[i] = Sv[a, i]
        one[a] = velocity[a] * dt
        predict(mode, m, one, out, Fa)  # linear in the displacement: out - m is component a's move
        for i in range(n):
            s = out[i] - m[i]
            for j in range(n):
                s += F[i, j] * old[j]
            Sv[a, i] = s


@njit(cache=True, error_model="numpy")
def _resolvent(A, B, w, Mx, RHS, n):
    """Solve ``(I + A B) [X | x] = [A | w]`` into ``RHS``; the form of both the backward time update and
    the alpha-beta combination. Returns False if ``I + A B`` is singular."""
    for i in range(n):
        for j in range(n):
            s = 1.0 if i == j else 0.0
            for k in range(n):
                s += A[i, k] * B[k, j]
            Mx[i, j] = s
            RHS[i, j] = A[i, j]
        RHS[i, n] = w[i]
    return lu_solve_inplace(Mx, RHS, n, n + 1)


class StepInputs(NamedTuple):
    """The action model along the log: step ``t`` moves by ``velocity[t] * dt`` (robot frame) with the
    diagonal motion noise ``motion_var[t]``."""

    mode: int  # pose_models.PLANAR or TRACK
    dt: float
    velocity: np.ndarray  # (T, n)
    motion_var: np.ndarray  # (T, n)


class Sightings(NamedTuple):
    """The log's observations: rows ``ptr[t]:ptr[t+1]`` belong to step ``t``. A NaN reading or bearing is
    a missing channel."""

    ptr: np.ndarray  # (T+1,) int64
    landmark: np.ndarray  # (K,) int64, rows of SensorInputs.landmarks
    readings: np.ndarray  # (K, C) reading channel c of row k
    gain: np.ndarray  # (K, C) adds gain * d to channel c's prediction (its bearing terms; 0 in the thesis)
    bearing: np.ndarray  # (K,) rad


class SensorInputs(NamedTuple):
    """A sensor model as the passes read it (``models.sensor_model.SensorModel.kernel_inputs``), of ``kind``
    (``LANDMARK``): channel ``c`` predicts the polynomial ``coefs[c]`` in ``(d - centers[c]) / scales[c]``
    with variance ``reading_var[c]``, read only within ``[window_lo[c], window_hi[c]]``; ``robust_kind`` and
    ``robust_param`` pick each channel's likelihood, the last entry the bearing's. ``mount`` (forward mm,
    left mm, yaw rad) is where the sensor sits on the robot (zeros: eq. 4.19 exactly)."""

    kind: int
    landmarks: np.ndarray  # (L, 2)
    coefs: np.ndarray  # (C, P)
    centers: np.ndarray  # (C,)
    scales: np.ndarray  # (C,)
    reading_var: np.ndarray  # (C,)
    window_lo: np.ndarray  # (C,)
    window_hi: np.ndarray  # (C,)
    var_bearing: float
    mount: np.ndarray  # (3,)
    robust_kind: np.ndarray  # (C+1,) int64
    robust_param: np.ndarray  # (C+1,)


@njit(cache=True, error_model="numpy", inline="always")
def _is_read(sight, sensor, k, c, dist, has_b):
    """Whether channel ``c`` of sighting ``k`` is read: a reading within its channel's distance window
    (``dist`` predicted), or a bearing the sighting has (``c = C``)."""
    if c < sight.readings.shape[1]:
        return np.isfinite(sight.readings[k, c]) and not (dist < sensor.window_lo[c] or dist > sensor.window_hi[c])
    return has_b


@njit(cache=True, error_model="numpy", inline="always")
def _window_distance(mode, sight, sensor, k, w):
    """The distance sighting ``k``'s channel windows are judged at, predicted at ``w``."""
    if sensor.kind == LANDMARK:
        j = sight.landmark[k]
        return landmark_range(mode, w, sensor.landmarks[j, 0], sensor.landmarks[j, 1], sensor.mount)
    return np.nan


@njit(cache=True, error_model="numpy", inline="always")
def _channel(mode, sight, sensor, k, c, w, H):
    """Channel ``c`` of sighting ``k`` predicted at ``w``: ``(innovation, variance)``, ``H`` its gradient;
    ``c = C`` is the bearing (its innovation wrapped). Every pass reads every sensor through this one
    function, which switches on the sensor's ``kind``. Inlined: called per reading in every pass."""
    if sensor.kind == LANDMARK:
        j = sight.landmark[k]
        lx = sensor.landmarks[j, 0]
        ly = sensor.landmarks[j, 1]
        if c < sight.readings.shape[1]:
            f_c = observe_height(
                mode, w, lx, ly, sensor.coefs[c], sensor.centers[c], sensor.scales[c], sight.gain[k, c], sensor.mount, H
            )
            return sight.readings[k, c] - f_c, sensor.reading_var[c]
        return wrap(sight.bearing[k] - observe_bearing(w, lx, ly, sensor.mount, H)), sensor.var_bearing
    return np.nan, np.inf  # a kind these passes were not built with: no information


def _passes_for(n_state: int):
    """The three passes compiled for a state of ``n_state`` numbers. With the size a constant the compiler
    unrolls every small-matrix loop: a third faster on MRCLAM's 3-number pose, the results unchanged
    bit for bit (the same operations in the same order).

    nogil: the start race runs its trials in threads. error_model="numpy" (here and in the helpers): IEEE
    division without a zero check before each one, a third of the E-step's time on MRCLAM, the results bit
    for bit the same; a zero divisor gives inf or NaN, which the status checks report.
    """
    n = n_state

    @njit(cache=True, nogil=True, error_model="numpy")
    def forward(
        steps,
        sight,
        sensor,
        prior_mean,
        prior_cov,
        obs_use,
        prune_rad_per_step,
        joint_dof,
        weights,
        mu_a,
        P_a,
        innov,
        innov_sens,
        obs_loglik,
    ):
        """alpha_t (eq. 4.3) into ``mu_a, P_a`` and the likelihood (eq. 4.14); returns ``(status, loglik,
        n_used)``. Decides each reading's weight into ``weights[k, c]`` (0 = not used) for the later passes.

        ``joint_dof`` is the joint Student-t's degrees of freedom, None when no reading is joint.
        ``innov, innov_sens`` receive the standardized innovations and their sensitivities, or are None;
        ``obs_loglik`` (zeros, or None) each sighting's share of the likelihood (the sandwich's scores).
        With ``prune_rad_per_step > 0`` an observation whose bearing innovation exceeds that times the
        steps since the last step with a kept observation is marked unused in ``obs_use`` (sec. 4.4.1),
        every observation of a step judged against the same prediction.
        """
        mode, dt, velocity, motion_var = steps
        ptr, bearing = sight.ptr, sight.bearing
        robust_kind, robust_param = sensor.robust_kind, sensor.robust_param
        T = mu_a.shape[0]
        C = sight.readings.shape[1]
        Sv = np.zeros((n, n))  # row a: d mean / d g_a (``innov_sens``)
        m = prior_mean.copy()
        P = prior_cov.copy()
        H, PH, K, gm, disp, var = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        A, tmp, tmp2, F, Q = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        Hj = np.zeros((C + 1, n))
        ej, rj, yj = np.zeros(C + 1), np.zeros(C + 1), np.zeros(C + 1)
        Sj, Lj = np.zeros((C + 1, C + 1)), np.zeros((C + 1, C + 1))
        loglik = 0.0
        n_used = 0
        last_obs = -1
        for t in range(T):
            if prune_rad_per_step > 0.0 and mode == 0:
                # sec. 4.4.1's gate, per frame: every sighting of step t is judged against the same
                # prediction, and k counts the steps since the last step with a kept sighting (read per
                # sighting, the 2nd..nth sightings of a frame would have k = 0 and all be dropped)
                steps_since = t - last_obs if last_obs >= 0 else t + 1
                for k in range(ptr[t], ptr[t + 1]):
                    if obs_use[k] and np.isfinite(bearing[k]):
                        nu, _ = _channel(mode, sight, sensor, k, C, m, H)  # the bearing's innovation
                        if abs(nu) > prune_rad_per_step * steps_since:
                            obs_use[k] = False
            for k in range(ptr[t], ptr[t + 1]):
                for c in range(C + 1):
                    weights[k, c] = 0.0
                    if innov is not None:
                        innov[k, c] = np.nan
                if not obs_use[k]:
                    continue
                has_b = mode == 0 and np.isfinite(bearing[k])
                last_obs = t
                n_used += 1
                dist = _window_distance(mode, sight, sensor, k, m)  # the windows are judged once, at the prediction
                w_joint = 1.0
                if joint_dof is not None:
                    # the sighting's joint readings are one multivariate t, judged at the prediction: a
                    # misread barcode spoils its range and its bearing together (docs/em-real.md)
                    d = 0
                    for c in range(C + 1):
                        if robust_kind[c] != STUDENT_T_JOINT:
                            continue
                        if not _is_read(sight, sensor, k, c, dist, has_b):
                            continue
                        ej[d], rj[d] = _channel(mode, sight, sensor, k, c, m, H)
                        for i in range(n):
                            Hj[d, i] = H[i]
                        d += 1
                    if d > 0:
                        w_joint, ld, ok = _joint_weight(Hj, ej, rj, d, P, n, Sj, Lj, yj, joint_dof)
                        if not ok:
                            return NOT_POSITIVE_DEFINITE, loglik, n_used
                        loglik += ld
                        if obs_loglik is not None:
                            obs_loglik[k] += ld
                # the joint readings update first, so that the others' densities are conditional on them
                # (the chain rule); without joint readings the second round is the whole
                for joint_round in (True, False):
                    for c in range(C + 1):
                        if (robust_kind[c] == STUDENT_T_JOINT) != joint_round:
                            continue
                        if not _is_read(sight, sensor, k, c, dist, has_b):
                            continue
                        nu, r = _channel(mode, sight, sensor, k, c, m, H)
                        if innov is not None:
                            _record(innov, innov_sens, k, c, nu, _hph(P, H, n) + r, H, Sv, n)
                        if joint_round:
                            w = w_joint
                        else:
                            w, ld = _reading_weight(robust_kind[c], robust_param[c], nu, _hph(P, H, n) + r)
                            loglik += ld
                            if obs_loglik is not None:
                                obs_loglik[k] += ld
                        if w > 0.0:
                            weights[k, c] = w
                            _scalar_update(m, P, H, nu, r / w, n, PH, K, A, tmp, tmp2)
                            if innov is not None:
                                _sensitivity_update(Sv, H, K, n)
            for i in range(n):
                mu_a[t, i] = m[i]
                for j in range(n):
                    P_a[t, i, j] = P[i, j]
            if t == T - 1:
                break
            # time update (eqs. 2.20, 2.21 with the Jacobian of eq. 2.28)
            for i in range(n):
                disp[i] = velocity[t, i] * dt
            predict(mode, m, disp, gm, F)
            if innov is not None:
                _sensitivity_predict(mode, m, velocity[t], dt, F, Sv, n)
            for i in range(n):
                var[i] = motion_var[t, i]  # copied, not viewed (see ``backward``)
            motion_covariance(mode, m[n - 1], var, Q)
            add_sandwich(F, P, Q, tmp, n)  # Q <- F P F' + Q
            for i in range(n):
                m[i] = gm[i]
                for j in range(n):
                    P[i, j] = Q[i, j]
            symmetrize(P, n)
        return OK, loglik, n_used

    @njit(cache=True, nogil=True, error_model="numpy")
    def backward(steps, sight, sensor, obs_use, weights, mu_a, P_a, mu_g, P_g, Yd_all, zd_all):
        """beta_t (eq. 4.4) in information form and gamma_t (eqs. 4.9, 4.10) into ``mu_g, P_g``; keeps
        ``delta_t+1 = beta_t+1 P(o_t+1 | w_t+1)`` as ``(Yd_all[t], zd_all[t])`` for ``pairwise``. Returns
        the status."""
        mode, dt, velocity, motion_var = steps
        ptr = sight.ptr
        T = mu_a.shape[0]
        C = sight.readings.shape[1]
        H, gm, disp = np.zeros(n), np.zeros(n), np.zeros(n)
        F, Q, tmp = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        Y = np.zeros((n, n))  # Y = 0: the thesis's "infinite covariance", exactly
        Ft, Mx, J = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        z, jv, b, colp = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        RHS = np.zeros((n, n + 1))
        # the step's rows are copied into these, not taken as views: a view costs two atomic reference
        # counts, which perf put at 7 % of an E-step loop's samples when taken every step
        Yd, Pa = np.zeros((n, n)), np.zeros((n, n))
        zd, mref, mt, var = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        for i in range(n):
            mu_g[T - 1, i] = mu_a[T - 1, i]
            for j in range(n):
                P_g[T - 1, i, j] = P_a[T - 1, i, j]
        for t in range(T - 2, -1, -1):
            # delta_t+1 = beta_t+1 x P(o_t+1 | w_t+1), linearized at mu_alpha,t+1
            for i in range(n):
                zd[i] = z[i]
                mref[i] = mu_a[t + 1, i]
                mt[i] = mu_a[t, i]
                var[i] = motion_var[t, i]
                for j in range(n):
                    Yd[i, j] = Y[i, j]
                    Pa[i, j] = P_a[t, i, j]
            for k in range(ptr[t + 1], ptr[t + 2]):
                if not obs_use[k]:
                    continue
                for c in range(C + 1):
                    if weights[k, c] <= 0.0:
                        continue
                    nu, r = _channel(mode, sight, sensor, k, c, mref, H)
                    r = r / weights[k, c]
                    for i in range(n):
                        zd[i] += H[i] * nu / r
                        for j in range(n):
                            Yd[i, j] += H[i] * H[j] / r
            for i in range(n):
                zd_all[t, i] = zd[i]
                for j in range(n):
                    Yd_all[t, i, j] = Yd[i, j]
            # backward time update through w_t+1 = g(w_t) + q, linearized at mu_alpha,t
            for i in range(n):
                disp[i] = velocity[t, i] * dt
            predict(mode, mt, disp, gm, F)
            motion_covariance(mode, mt[n - 1], var, Q)
            for i in range(n):
                b[i] = gm[i] - mu_a[t + 1, i]
            # J = (I + Yd Q)^-1 Yd, j = (I + Yd Q)^-1 zd
            if not _resolvent(Yd, Q, zd, Mx, RHS, n):
                return SINGULAR
            for i in range(n):
                jv[i] = RHS[i, n]
                for j in range(n):
                    J[i, j] = RHS[i, j]
            symmetrize(J, n)
            # Y = F' J F, z = F'(j - J b)
            for i in range(n):
                s = jv[i]
                for k in range(n):
                    s -= J[i, k] * b[k]
                colp[i] = s
            for i in range(n):
                s = 0.0
                for k in range(n):
                    s += F[k, i] * colp[k]
                z[i] = s
                for j in range(n):
                    Y[i, j] = 0.0
            for i in range(n):
                for j in range(n):
                    Ft[i, j] = F[j, i]
            add_sandwich(Ft, J, Y, tmp, n)
            symmetrize(Y, n)
            # gamma_t: Sigma = (I + P Y)^-1 P, mu = mu_alpha + (I + P Y)^-1 P z
            for i in range(n):
                s = 0.0
                for k in range(n):
                    s += Pa[i, k] * z[k]
                colp[i] = s
            if not _resolvent(Pa, Y, colp, Mx, RHS, n):
                return SINGULAR
            symmetrize(RHS, n)  # its first n columns, (I + P Y)^-1 P
            for i in range(n):
                mu_g[t, i] = mu_a[t, i] + RHS[i, n]
                for j in range(n):
                    P_g[t, i, j] = RHS[i, j]
        return OK

    n2 = 2 * n

    @njit(cache=True, nogil=True, error_model="numpy")
    def pairwise(steps, mu_a, P_a, mu_g, Yd_all, zd_all, d_mu, d_P):
        """xi_t (eqs. 4.11, 4.12): the joint of ``(w_t, w_t+1)`` from ``alpha_t``, ``delta_t+1`` and the
        pseudo-measurement ``D(w_t, w_t+1) ~ N(A(c_t) dt, Sigma_m)`` linearized at the smoothed means,
        solved in information form over ``e = (w_t - mu_alpha,t, w_t+1 - mu_alpha,t+1)``; the mean and
        covariance of ``D`` under it into ``d_mu, d_P``. Returns the status."""
        mode, dt, velocity, motion_var = steps
        T = mu_a.shape[0]
        disp, colp, D, rv, mx1, mx2 = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        Dm = np.zeros(n)
        Lam, L2 = np.zeros((n2, n2)), np.zeros((n2, n2))
        Wt = np.zeros((n2, n))
        eta = np.zeros(n2)
        Lp, Pinv = np.zeros((n, n)), np.zeros((n, n))
        G, Gm = np.zeros((n, n2)), np.zeros((n, n2))
        var = np.zeros(n)  # the step's rows, copied rather than viewed (see ``backward``)
        Pa = np.zeros((n, n))
        w1, w2 = np.zeros(n), np.zeros(n)
        for t in range(T - 2, -1, -1):
            for i in range(n):
                disp[i] = velocity[t, i] * dt
                var[i] = motion_var[t, i]
                w1[i] = mu_g[t, i]
                w2[i] = mu_g[t + 1, i]
                for j in range(n):
                    Pa[i, j] = P_a[t, i, j]
            # sizes read off the arrays, not this closure's n: a literal n compiled each helper once per size
            if not cholesky(Pa, Lp, Lp.shape[0]):
                return NOT_POSITIVE_DEFINITE
            cholesky_inverse(Lp, Pinv, colp, Lp.shape[0])
            # Lam = diag(P_alpha^-1, Yd) + G' Sigma_m^-1 G. The Cholesky factorization reads only the lower
            # triangle, so only that is formed; G's zeros add nothing and are skipped (the sums unchanged)
            for i in range(n):
                eta[i] = 0.0
                eta[n + i] = zd_all[t, i]
                for j in range(n):
                    Lam[n + i, j] = 0.0
                for j in range(i + 1):
                    Lam[i, j] = Pinv[i, j]
                    Lam[n + i, n + j] = Yd_all[t, i, j]
            displacement(mode, w1, w2, D, G)
            for i in range(n):
                s = disp[i] - D[i]
                if mode == 0 and i == 2:
                    s = wrap(s)
                for j in range(n):
                    s += G[i, j] * (w1[j] - mu_a[t, j]) + G[i, n + j] * (w2[j] - mu_a[t + 1, j])
                rv[i] = s / var[i]
            for i in range(n2):
                s = 0.0
                for k in range(n):
                    s += G[k, i] * rv[k]
                eta[i] += s
                for j in range(i + 1):
                    s = 0.0
                    for k in range(n):
                        if G[k, i] != 0.0 and G[k, j] != 0.0:
                            s += G[k, i] * G[k, j] / var[k]
                    Lam[i, j] += s
            if not cholesky(Lam, L2, L2.shape[0]):
                return NOT_POSITIVE_DEFINITE
            cholesky_solve_vec(L2, eta, eta, L2.shape[0])
            for i in range(n):
                mx1[i] = mu_a[t, i] + eta[i]
                mx2[i] = mu_a[t + 1, i] + eta[n + i]
            displacement(mode, mx1, mx2, Dm, Gm)
            for i in range(n):
                d_mu[t, i] = Dm[i]  # D(mu_xi,t): eq. 4.18 with D linearized, as the thesis does
            # Cov[D] = G Lam^-1 G' = W'W with W = L2^-1 G'; W'W is formed once per pair (i, j)
            for i in range(n2):
                for j in range(n):
                    Wt[i, j] = Gm[j, i]
            forward_substitute(L2, Wt, n2, n)
            for i in range(n):
                for j in range(i + 1):
                    s = 0.0
                    for k in range(n2):
                        s += Wt[k, i] * Wt[k, j]
                    d_P[t, i, j] = s
                    d_P[t, j, i] = s
        return OK

    return forward, backward, pairwise


_PASSES = {size: _passes_for(size) for size in (1, 3)}  # a track's distance; a planar pose


def passes_for(n_state: int):
    """The compiled E-step passes ``(forward, backward, pairwise)`` for a state of ``n_state`` numbers."""
    if n_state not in _PASSES:
        raise ValueError(f"the E-step is compiled for states of 1 (track) or 3 (planar) numbers, not {n_state}")
    return _PASSES[n_state]
