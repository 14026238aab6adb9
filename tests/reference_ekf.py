"""The independent reference for the E-step's forward pass (tests/test_estep.py), also the plain-Python
baseline of benchmarks/em_speed.py."""

from __future__ import annotations

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing


def reference_ekf(model, data, var, steps=None):
    """A plain, loop-by-loop EKF (sec. 2.4) written independently of the compiled kernel: the filtered
    means and the log-likelihood over the first ``steps`` steps (all by default)."""
    steps = data.n_steps if steps is None else steps
    m = model.prior_mean.copy()
    P = model.prior_cov.copy()
    f = model.sensor.height
    ll = 0.0
    means = []
    for t in range(steps):
        for k in range(data.obs_ptr[t], data.obs_ptr[t + 1]):
            L = data.landmarks_xy[data.obs_landmark[k]]
            for channel in ("height", "bearing"):
                dx, dy = L - m[:2]
                r = np.hypot(dx, dy)
                if channel == "height":
                    eps = 1e-3
                    slope = (f(r + eps) - f(r - eps)) / (2 * eps)
                    Hr = np.array([-slope * dx / r, -slope * dy / r, 0.0])
                    nu = data.obs_height_px[k] - f(r)
                    rvar = model.sensor.sigma_height_px**2
                else:
                    Hr = np.array([dy / r**2, -dx / r**2, -1.0])
                    nu = wrap_angle(data.obs_bearing_rad[k] - landmark_bearing(m, L)[0])
                    rvar = model.sensor.sigma_bearing_rad**2
                S = Hr @ P @ Hr + rvar
                K = P @ Hr / S
                m = m + K * nu
                P = P - np.outer(K, Hr @ P)
                ll += -0.5 * (nu**2 / S + np.log(2 * np.pi * S))
        means.append(m.copy())
        if t < steps - 1:
            v = model.action.velocities[data.actions[t]] * data.dt_s
            c, s = np.cos(m[2]), np.sin(m[2])
            F = np.eye(3)
            F[0, 2] = -s * v[0] - c * v[1]
            F[1, 2] = c * v[0] - s * v[1]
            Rm = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            m = m + Rm @ v
            P = F @ P @ F.T + Rm @ np.diag(var) @ Rm.T
    return np.array(means), ll
