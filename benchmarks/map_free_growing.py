import sys
import time
from dataclasses import replace

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em, initial_model, log_likelihood
from sensact.presets import mrclam_config

robot = int(sys.argv[1])
parts = int(sys.argv[2]) if len(sys.argv) > 2 else 3
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
poses, valid = ml.truth_poses()
truth = data.landmarks_xy.copy()
blank = data.with_landmarks(np.full_like(truth, np.nan))
cfg = mrclam_config()
if len(sys.argv) > 3:
    cfg = cfg.replace(sensor_mount=(0.0, 0.0, 0.0))


def align(A, B):
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    a, b = A[ok], B[ok]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return R, cb - R @ ca, ok


t0 = time.time()
model = None
for k in range(1, parts + 1):
    stop = data.n_steps * k // parts
    part = blank.slice_steps(0, stop)
    start = initial_model(part, cfg)
    if model is not None:  # the last window's models and map; new landmarks from EKF-SLAM
        xy = np.where(np.isfinite(model.landmarks.xy), model.landmarks.xy, start.landmarks.xy)
        start = model.replace(landmarks=replace(model.landmarks, xy=xy))
    res = fit_em(part, start, cfg if model is None else cfg.replace(refine_from=0))
    model = res.model
    R, t, ok = align(model.landmarks.xy, truth)
    err = np.hypot(*((model.landmarks.xy[ok] @ R.T + t) - truth[ok]).T)
    print(
        k,
        "steps",
        stop,
        "map rms",
        np.sqrt((err**2).mean()).round(1),
        "placed",
        ok.sum(),
        "iters",
        res.iterations,
        "ll",
        round(res.loglik_best, 1),
    )
p2 = res.posteriors.mean_gamma[:, :2] @ R.T + t
v = valid[: len(p2)] > 0
print(
    "path median",
    np.median(np.hypot(*(p2[v] - poses[: len(p2)][v, :2]).T)).round(1),
    "secs",
    round(time.time() - t0, 1),
)
print("ll on its map", round(log_likelihood(model, data.with_landmarks(model.landmarks.xy)), 1), model.sensor.mount)
