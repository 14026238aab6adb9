"""Scoring chapter 5's learned models against the simulated Applanix and the true calibration (sec. 5.4)."""

from __future__ import annotations

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.models.velodyne_car_dynamics import CarDynamics, fit_car_dynamics


def laser_angle_error(learned_rad: np.ndarray, true_rad: np.ndarray) -> dict[str, float | None]:
    """RMS over the lasers of the learned theta_l + theta_b, in degrees and as % of the true angles' range
    (None for a unit whose lasers all point alike, as an HDL-32E's and a VLP-16's do)."""
    err = np.degrees(wrap_angle(np.asarray(learned_rad) - np.asarray(true_rad)))
    rms = float(np.sqrt(np.mean(err**2)))
    span = float(np.degrees(np.ptp(np.unwrap(true_rad))))
    pct = 100 * rms / span if span > 0 else None
    return {"laser_angle_rms_deg": rms, "laser_angle_rms_pct": pct, "laser_angle_range_deg": span}


def factory_comparison(learned_rad: np.ndarray, factory_horizontal_rad: np.ndarray) -> dict[str, float]:
    """The learned theta_l + theta_b (eq. 2.35) against a factory calibration's theta_l (ROS's rot_correction).

    The factory does not know how the unit sits on the car, so their difference is theta_b plus each
    laser's disagreement: theta_b is taken as the differences' circular mean (for small disagreements,
    the shift that leaves the least squared disagreement), and the RMS and largest disagreement are about
    it. Never used to learn."""
    diff = wrap_angle(np.asarray(learned_rad) - np.asarray(factory_horizontal_rad))
    mount = float(np.angle(np.mean(np.exp(1j * diff))))
    err = np.degrees(wrap_angle(diff - mount))
    return {
        "mount_yaw_deg": float(np.degrees(mount)),
        "rms_deg": float(np.sqrt(np.mean(err**2))),
        "max_deg": float(np.max(np.abs(err))),
    }


def truth_motion(times_s, poses, starts_s, dt_s):
    """v, omega, a per interval from pose differences over dt, as the thesis used the Applanix (sec. 5.4)."""
    th = np.unwrap(poses[:, 2])

    def at(t):
        return np.interp(t, times_s, poses[:, 0]), np.interp(t, times_s, poses[:, 1]), np.interp(t, times_s, th)

    x0, y0, t0 = at(starts_s)
    x1, y1, t1 = at(starts_s + dt_s)
    mid = 0.5 * (t0 + t1)
    v = (-(x1 - x0) * np.sin(mid) + (y1 - y0) * np.cos(mid)) / dt_s  # forward is +y at theta = 0
    w = (t1 - t0) / dt_s
    a = np.r_[np.diff(v), 0.0] / dt_s
    return v, w, a


def table_5_1(model: CarDynamics, actions, v_true, w_true, a_true, dt_s, v0=None) -> dict[str, float]:
    """Table 5.1: RMS of the accelerations and velocities the model predicts from the actions alone,
    against the truth, each also as % of the truth's range, beside the same model family fitted to the
    truth itself (From-Truth)."""
    K = len(v_true) - 1
    out: dict[str, float] = {}
    truth_fit = fit_car_dynamics(v_true[:K], a_true[:K], w_true[:K], actions[:K])
    for name, m, start in (("", model, v_true[0] if v0 is None else v0), ("_from_truth", truth_fit, v_true[0])):
        pv, pa, pw = m.predict(actions[:K], start, dt_s)
        for key, pred, true in (
            ("accel_rms", pa, a_true[:K]),
            ("fwd_vel_rms", pv, v_true[:K]),
            ("ang_vel_rms", pw, w_true[:K]),
        ):
            rms = float(np.sqrt(np.mean((pred - true) ** 2)))
            out[key + name] = rms
            if not name:
                out[key + "_pct"] = 100 * rms / float(np.ptp(true))
    out["ranges"] = {
        "accel": float(np.ptp(a_true[:K])),
        "fwd_vel": float(np.ptp(v_true[:K])),
        "ang_vel": float(np.ptp(w_true[:K])),
    }
    out["from_truth_model"] = truth_fit.to_dict()
    return out
