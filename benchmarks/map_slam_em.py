"""Prototype: the map carried by a filter, not the M-step. Each round: an EKF over (pose, landmarks) with
the current models gives the map (the landmarks are static, so their last filtered estimate is their
smoothed one); EM then learns the models on that map (as on a survey). Does the likelihood reach the
surveyed fit's?"""

import json
import sys
import time

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import PLANAR, observe_bearing, observe_height
from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em, initial_model, log_likelihood
from sensact.learn.em.actions import step_motion_var
from sensact.learn.em.estep import channel_inputs
from sensact.models.em_model import EMModel
from sensact.presets import mrclam_config


def slam_pass(model, data, prior_xy, prior_sd, start, start_sd):
    L = len(prior_xy)
    n = 3 + 2 * L
    x = np.r_[start, prior_xy.ravel()]
    P = np.zeros((n, n))
    P[:3, :3] = np.diag(np.square(start_sd))
    P[3:, 3:] = np.eye(2 * L) * prior_sd**2
    vel = model.action.step_velocity(data)
    var = step_motion_var(model, data, vel)
    ch = model.sensor.channels[0]
    readings = channel_inputs(model.sensor, data)[0][:, 0]
    gains = ch.bearing_gain(data.obs_bearing_rad) if ch.bearing_terms else np.zeros(data.n_observations)
    coef = np.asarray(ch.function.coef, float)
    mount = model.sensor.mount.as_array()
    Rn = np.diag([ch.sigma**2, model.sensor.sigma_bearing_rad**2])
    Hr, Hb = np.zeros(3), np.zeros(3)
    dt = data.dt_s
    ptr = data.obs_ptr
    for t in range(data.n_steps):
        for k in range(ptr[t], ptr[t + 1]):
            o, b, l = readings[k], data.obs_bearing_rad[k], int(data.obs_landmark[k])
            if not (np.isfinite(o) and np.isfinite(b)):
                continue
            j = 3 + 2 * l
            pr = observe_height(
                PLANAR, x[:3], x[j], x[j + 1], coef, ch.function.center, ch.function.scale, gains[k], mount, Hr
            )
            pb = observe_bearing(x[:3], x[j], x[j + 1], mount, Hb)
            idx = [0, 1, 2, j, j + 1]
            H = np.zeros((2, 5))
            H[0, :3] = Hr
            H[0, 3:] = -Hr[:2]
            H[1, :3] = Hb
            H[1, 3:] = -Hb[:2]
            PH = P[:, idx] @ H.T
            S = H @ PH[idx] + Rn
            innov = np.array([o - pr, wrap_angle(b - pb)])
            if innov @ np.linalg.solve(S, innov) > 25.0:
                continue
            K = np.linalg.solve(S, PH.T).T
            x = x + K @ innov
            P = P - K @ PH.T
            P = 0.5 * (P + P.T)
        if t + 1 < data.n_steps:
            c, s = np.cos(x[2]), np.sin(x[2])
            v = vel[t] * dt
            x[0] += c * v[0] - s * v[1]
            x[1] += s * v[0] + c * v[1]
            x[2] += v[2]
            F = np.eye(3)
            F[0, 2] = -s * v[0] - c * v[1]
            F[1, 2] = c * v[0] - s * v[1]
            Rt = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            P[:3, :] = F @ P[:3, :]
            P[:, :3] = P[:, :3] @ F.T
            P[:3, :3] += Rt @ np.diag(var[t]) @ Rt.T
    return x[3:].reshape(L, 2)


def align(A, B):
    a, b = A, B
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return R, cb - R @ ca


robot = int(sys.argv[1])
rounds = int(sys.argv[2]) if len(sys.argv) > 2 else 4
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
truth = data.landmarks_xy.copy()
blank = data.with_landmarks(np.full_like(truth, np.nan))
cfg = mrclam_config()
survey = EMModel.from_dict(json.load(open(f"/tmp/after/mr{robot}/model.json"))["model"])
print("survey fit on survey: ll", round(log_likelihood(survey, data), 1))
start = initial_model(blank, cfg)  # EKF-SLAM start map, frame at the origin
xy = start.landmarks.xy
model = None
best = (-np.inf, None, None)
poses, valid = ml.truth_poses()
t0 = time.time()
for r in range(rounds):
    mapped = data.with_landmarks(xy)
    res = fit_em(
        mapped, model, cfg if model is None else cfg.replace(refine_from=0, start_search_s=None, max_iterations=150)
    )
    model = res.model.replace(landmarks=None)
    if res.loglik_best > best[0]:
        best = (res.loglik_best, xy, res)
    elif r > 1:
        break  # the map got less likely: keep the best
    R, tr = align(xy, truth)
    rms = np.sqrt((((xy @ R.T + tr) - truth) ** 2).sum(1).mean())
    print(
        r,
        "map rms",
        rms.round(1),
        "EM ll",
        round(res.loglik_best, 1),
        "iters",
        res.iterations,
        "mount",
        model.sensor.mount,
        f"{time.time() - t0:.0f}s",
        flush=True,
    )
    xy = slam_pass(model, data, xy, 300.0, model.prior_mean, np.array([1.0, 1.0, 1e-3]))
ll, xy, res = best
R, tr = align(xy, truth)
p2 = res.posteriors.mean_gamma[:, :2] @ R.T + tr
v = valid > 0
print(
    "best: ll",
    round(ll, 1),
    "map rms",
    np.sqrt((((xy @ R.T + tr) - truth) ** 2).sum(1).mean()).round(1),
    "path median",
    np.median(np.hypot(*(p2[v] - poses[v, :2]).T)).round(1),
    "secs",
    round(time.time() - t0),
)
print("action", {k: round(v, 4) for k, v in res.model.action.named_parameters().items() if abs(v) > 0})
print("range sigma", [round(c.sigma, 1) for c in res.model.sensor.channels], "mount", res.model.sensor.mount)
