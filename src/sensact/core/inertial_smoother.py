"""The E-step of the outdoor robot's EM (docs/inertial.md): an extended Kalman filter and a Rauch-Tung-Striebel
smoother over the path, with the wheel odometry as the action (sec. 4.1's ``A``, its gains learned) and the
gyro and GNSS as sensors. The constant parameters ride in the state (their prior broad, no process noise),
so the smoother's posterior is their error bar; the previous step's pose and bias ride as clones, so every
transition's residual (what EM's M-step needs) is a function of one smoothed state.

The state, in sensact's frame (x right, y forward, heading 0 facing +y, mm): see the indices below.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from sensact.core.pose_models import sensor_point

X, Y, TH, CX, CY, CTH, B, CB, GF, GT, S, LF, LL = range(13)
N_STATE = 13
# the noise, in q's order: along-track mm^2 per mm, across-track mm^2 per mm, turn rad^2 per rad, turn rad^2
# per mm travelled, bias walk (rad/s)^2 per s, gyro (rad/s)^2 per Hz, GNSS mm^2, along-track mm^2 and turn
# rad^2 per second in motion (a reported velocity's own noise: the twist is an estimate, per message). The
# odometry errs only as the wheels turn (a robot standing still reports no motion and makes none): each step
# adds a floor of FLOOR_MM^2 and FLOOR_RAD^2 per second only to keep the covariances positive definite.
Q_ALONG, Q_ACROSS, Q_TURN, Q_TURN_D, Q_BIAS, R_GYRO, R_GNSS, Q_ALONG_T, Q_TURN_T, R_OUTLIER, OUTLIER_SHARE = range(11)
N_NOISE = 11  # the last two: GNSS's outliers' variance (mm^2) and share, for the likelihood's mixture
FLOOR_MM2 = 1e-2
FLOOR_RAD2 = 1e-10


@njit(cache=True, error_model="numpy")
def odometry_move(m, sub_d, sub_a, a, J):
    """Eq. 2.28 with the odometry's gains, dead-reckoned at the odometry's own rate: from the pose in ``m`` the
    robot drives ``GF * sub_d[j]`` at heading ``GT * sub_a[j]`` from the start's (each piece's middle) and turns
    ``GT * a`` in all. Returns the pose after, and its Jacobian ``J`` (3 x n) in the state."""
    th = m[TH]
    gt = m[GT]
    gf = m[GF]
    sx = 0.0
    sy = 0.0
    gx = 0.0
    gy = 0.0
    for j in range(sub_d.shape[0]):
        sn = np.sin(gt * sub_a[j])
        cs = np.cos(gt * sub_a[j])
        sx -= sub_d[j] * sn
        sy += sub_d[j] * cs
        gx -= sub_d[j] * sub_a[j] * cs
        gy -= sub_d[j] * sub_a[j] * sn
    c = np.cos(th)
    s = np.sin(th)
    dx = gf * (c * sx - s * sy)
    dy = gf * (s * sx + c * sy)
    J[:, :] = 0.0
    J[0, X] = 1.0
    J[1, Y] = 1.0
    J[2, TH] = 1.0
    J[0, TH] = -dy
    J[1, TH] = dx
    J[0, GF] = c * sx - s * sy
    J[1, GF] = s * sx + c * sy
    J[0, GT] = gf * (c * gx - s * gy)
    J[1, GT] = gf * (s * gx + c * gy)
    J[2, GT] = a
    return m[X] + dx, m[Y] + dy, th + gt * a


@njit(cache=True, error_model="numpy")
def _transition(m, dt, d, a, sub_d, sub_a, q, out, F, Q):
    n = m.shape[0]
    J = np.empty((3, n))
    x, y, th = odometry_move(m, sub_d, sub_a, a, J)
    mid = m[TH] + 0.5 * m[GT] * a
    out[:] = m
    out[X] = x
    out[Y] = y
    out[TH] = th
    out[CX] = m[X]
    out[CY] = m[Y]
    out[CTH] = m[TH]
    out[CB] = m[B]
    F[:, :] = 0.0
    for i in range(n):
        F[i, i] = 1.0
    for c in (CX, CY, CTH, CB):
        F[c, c] = 0.0
    F[CX, X] = 1.0
    F[CY, Y] = 1.0
    F[CTH, TH] = 1.0
    F[CB, B] = 1.0
    for r in range(3):
        for j in range(n):
            F[r, j] = J[r, j]
    Q[:, :] = 0.0
    sn = np.sin(mid)
    cs = np.cos(mid)
    moving = dt if (abs(d) > 1e-9 or abs(a) > 1e-12) else 0.0
    va = q[Q_ALONG] * abs(d) + q[Q_ALONG_T] * moving + FLOOR_MM2 * dt
    vc = q[Q_ACROSS] * abs(d) + FLOOR_MM2 * dt
    # along the travel (-sin, cos), across it (cos, sin)
    Q[X, X] = va * sn * sn + vc * cs * cs
    Q[Y, Y] = va * cs * cs + vc * sn * sn
    Q[X, Y] = (vc - va) * sn * cs
    Q[Y, X] = Q[X, Y]
    Q[TH, TH] = q[Q_TURN] * abs(a) + q[Q_TURN_D] * abs(d) + q[Q_TURN_T] * moving + FLOOR_RAD2 * dt
    Q[B, B] = q[Q_BIAS] * dt


@njit(cache=True, error_model="numpy")
def gyro_model(m, dt, H):
    """The gyro's turn over a step, about base_link's z: its scale times the turn plus the bias's integral,
    the trapezoid between its values at the step's ends (a bias held over each step would make the walk's
    increments those of step means, 2/3 of its variance)."""
    H[:] = 0.0
    turn = m[TH] - m[CTH]
    H[TH] = m[S]
    H[CTH] = -m[S]
    H[CB] = dt / 2
    H[B] = dt / 2
    H[S] = turn
    return m[S] * turn + (m[CB] + m[B]) * dt / 2


@njit(cache=True, error_model="numpy")
def gnss_model(m, sub_d, sub_a, ap, H):
    """Where the antenna, at (forward LF, left LL) on the robot (``pose_models.sensor_point``), is at a fix
    taken after the robot drove the odometry's pieces ``sub_d``, ``sub_a`` and turned ``ap`` from the state's
    pose."""
    n = m.shape[0]
    J = np.empty((3, n))
    px, py, pth = odometry_move(m, sub_d, sub_a, ap, J)
    pose = np.array([px, py, pth])
    mount = np.array([m[LF], m[LL], 0.0])
    sx, sy, dsx, dsy = sensor_point(pose, mount)
    for j in range(n):
        H[0, j] = J[0, j] + dsx * J[2, j]
        H[1, j] = J[1, j] + dsy * J[2, j]
    c = np.cos(pth)
    s = np.sin(pth)
    H[0, LF] += -s
    H[1, LF] += c
    H[0, LL] += -c
    H[1, LL] += -s
    return sx, sy


@njit(cache=True, error_model="numpy")
def _fix_update(m, P, z, sub_d, sub_a, ap, use, r_gnss, r_out, share, gate, H2):
    """One fix's update of ``m``, ``P`` in place, as GNSS's mixture says (inliers N(0, r_gnss), a share of
    outliers N(0, r_out)): each component's Kalman update weighed by its posterior probability and the two
    collapsed to one Gaussian by their moments (an assumed-density filter). Returns the innovation and its
    inlier covariance, the fix's log-likelihood (the mixture's), and the inlier probability. ``use`` False
    (a jackknife's deleted fix) or an inlier NIS beyond ``gate`` > 0 (a filter's outlier test, the mixture
    held at its inliers): the fix is recorded, not used."""
    hx, hy = gnss_model(m, sub_d, sub_a, ap, H2)
    rr = np.array([z[0] - hx, z[1] - hy])
    PHt = P @ H2.T
    S0 = H2 @ PHt
    S_in = S0.copy()
    S_in[0, 0] += r_gnss
    S_in[1, 1] += r_gnss
    det = S_in[0, 0] * S_in[1, 1] - S_in[0, 1] * S_in[1, 0]
    if det <= 0:
        return rr, S_in, np.nan, 1.0
    if not use:
        return rr, S_in, 0.0, 1.0
    li = _gauss2(rr, S_in)
    gamma = 1.0
    term = li
    if share > 0:
        S_out = S0.copy()
        S_out[0, 0] += r_out
        S_out[1, 1] += r_out
        lo = _gauss2(rr, S_out)
        top = max(li, lo)
        a_in = (1 - share) * np.exp(li - top)
        a_out = share * np.exp(lo - top)
        term = top + np.log(a_in + a_out)
        gamma = a_in / (a_in + a_out)
    Si = np.linalg.inv(S_in)
    if gate > 0 and rr @ Si @ rr > gate:
        return rr, S_in, term, 0.0
    K_in = PHt @ Si
    m_in = m + K_in @ rr
    P_in = P - K_in @ PHt.T
    if gamma >= 1.0 - 1e-12:
        m[:] = m_in
        P[:, :] = P_in
        return rr, S_in, term, gamma
    S_out = S0.copy()
    S_out[0, 0] += r_out
    S_out[1, 1] += r_out
    K_out = PHt @ np.linalg.inv(S_out)
    m_out = m + K_out @ rr
    P_out = P - K_out @ PHt.T
    mean = gamma * m_in + (1 - gamma) * m_out
    d_in = m_in - mean
    d_out = m_out - mean
    P[:, :] = gamma * (P_in + np.outer(d_in, d_in)) + (1 - gamma) * (P_out + np.outer(d_out, d_out))
    m[:] = mean
    return rr, S_in, term, gamma


@njit(cache=True, error_model="numpy")
def _gauss2(r, S):
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    nis = (S[1, 1] * r[0] * r[0] - 2 * S[0, 1] * r[0] * r[1] + S[0, 0] * r[1] * r[1]) / det
    return -0.5 * (2 * np.log(2 * np.pi) + np.log(det) + nis)


@njit(cache=True, error_model="numpy")
def run_filter(dt, d, a, gz, sub_ptr, sub_d, sub_a, fix_step, fix_ptr, fix_sub_d, fix_sub_a, fix_ap, fix_xy, fix_use,
               q, m0, P0, gate=0.0):  # fmt: skip
    """Forward pass. Step k takes the state from ``t_k`` to ``t_k+1``, the odometry's pieces
    ``sub_*[sub_ptr[k]:sub_ptr[k+1]]`` (travel, and heading from the step's start); the fixes of step k
    (``fix_step``, sorted), taken after the robot drove their own pieces (``fix_ptr``) and turned ``fix_ap``
    from ``t_k``, update the state at ``t_k`` before it moves.

    Returns filtered and predicted means and covariances, the transitions' Jacobians, the log-likelihood, the
    gyro's innovation and its variance per step, each fix's innovation and its inlier covariance
    (one-step-ahead), whether the covariances stayed positive, and each fix's inlier probability as the filter
    saw it. A NaN ``gz`` is a step without the gyro; ``fix_use`` False, a fix left out; ``gate`` > 0, a fix
    whose inliers' normalized innovation squared exceeds it is recorded but not used."""
    T = dt.shape[0]
    n = m0.shape[0]
    K = fix_step.shape[0]
    m_f = np.empty((T + 1, n))
    P_f = np.empty((T + 1, n, n))
    m_p = np.empty((T + 1, n))
    P_p = np.empty((T + 1, n, n))
    Fs = np.empty((T, n, n))
    nu_g = np.full(T, np.nan)
    s_g = np.full(T, np.nan)
    nu_n = np.full((K, 2), np.nan)
    s_n = np.full((K, 2, 2), np.nan)
    inlier = np.ones(K)
    m_p[0] = m0
    P_p[0] = P0
    m = m0.copy()
    P = P0.copy()
    F = np.empty((n, n))
    Q = np.empty((n, n))
    H = np.empty(n)
    H2 = np.empty((2, n))
    ll = 0.0
    ok = True
    j = 0
    for k in range(T + 1):
        while j < K and fix_step[j] == k:
            lo, hi = fix_ptr[j], fix_ptr[j + 1]
            rr, Sm, term, gamma = _fix_update(
                m, P, fix_xy[j], fix_sub_d[lo:hi], fix_sub_a[lo:hi], fix_ap[j], fix_use[j], q[R_GNSS], q[R_OUTLIER],
                q[OUTLIER_SHARE], gate, H2,
            )  # fmt: skip
            inlier[j] = gamma
            nu_n[j] = rr
            s_n[j] = Sm
            if np.isnan(term):
                ok = False
            ll += term if not np.isnan(term) else 0.0
            j += 1
        P = 0.5 * (P + P.T)
        m_f[k] = m
        P_f[k] = P
        if k == T or not ok:
            break
        pred = np.empty(n)
        lo, hi = sub_ptr[k], sub_ptr[k + 1]
        _transition(m, dt[k], d[k], a[k], sub_d[lo:hi], sub_a[lo:hi], q, pred, F, Q)
        P = F @ P @ F.T + Q
        m = pred
        Fs[k] = F
        m_p[k + 1] = m
        P_p[k + 1] = P
        if gz[k] != gz[k]:  # NaN: no gyro reading over this step (a jackknife's deleted block)
            continue
        h = gyro_model(m, dt[k], H)
        PH = P @ H
        sv = H @ PH + q[R_GYRO] * dt[k]
        r = gz[k] - h
        Kg = PH / sv
        m = m + Kg * r
        P = P - np.outer(Kg, PH)
        nu_g[k] = r
        s_g[k] = sv
        ll += -0.5 * (np.log(2 * np.pi * sv) + r * r / sv)
    return m_f, P_f, m_p, P_p, Fs, ll, nu_g, s_g, nu_n, s_n, ok, inlier


@njit(cache=True, error_model="numpy")
def run_smoother(m_f, P_f, m_p, P_p, Fs, active, dt):
    """Backward pass (RTS) over the ``active`` states (those with any variance; the others are fixed, their
    gain zero), and the variance of the bias's integral over the run (``sum_k b_k dt_k``), through the lag
    covariances ``Cov(x_k, x_j) = J_k Cov(x_k+1, x_j)``."""
    T = Fs.shape[0]
    n = m_f.shape[1]
    na = active.shape[0]
    m_s = m_f.copy()
    P_s = P_f.copy()
    J = np.zeros((n, n))
    Pa = np.empty((na, na))
    sc = np.empty(na)
    J_next = np.zeros((n, n))
    C = np.zeros(n)  # Cov(x_j, sum of the bias over steps j-1 on), from the end
    var_sum = 0.0
    for k in range(T - 1, -1, -1):
        for i in range(na):
            sc[i] = 1.0 / np.sqrt(P_p[k + 1][active[i], active[i]])
        for i in range(na):
            for j in range(na):
                Pa[i, j] = P_p[k + 1][active[i], active[j]] * sc[i] * sc[j]
        PF = P_f[k] @ Fs[k].T
        Pinv = np.linalg.inv(Pa)  # of the correlations: the variances span 20 orders of magnitude
        for i in range(na):
            for j in range(na):
                Pinv[i, j] *= sc[i] * sc[j]
        J[:, :] = 0.0
        for i in range(n):
            for j in range(na):
                acc = 0.0
                for l in range(na):
                    acc += PF[i, active[l]] * Pinv[l, j]
                J[i, active[j]] = acc
        m_s[k] = m_f[k] + J @ (m_s[k + 1] - m_p[k + 1])
        P = P_f[k] + J @ (P_s[k + 1] - P_p[k + 1]) @ J.T
        P_s[k] = 0.5 * (P + P.T)
        # the bias during step k is the clone CB of state k+1 (= b_k)
        if k == T - 1:
            C = P_s[k + 1][:, CB] * dt[k]
            var_sum += dt[k] * dt[k] * P_s[k + 1][CB, CB]
        else:
            JC = J_next @ C
            var_sum += dt[k] * dt[k] * P_s[k + 1][CB, CB] + 2.0 * dt[k] * JC[CB]
            C = P_s[k + 1][:, CB] * dt[k] + JC
        J_next[:, :] = J
    return m_s, P_s, var_sum
