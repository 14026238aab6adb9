import sys
import time

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em
from sensact.presets import mrclam_config

robot = int(sys.argv[1])
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
truth = data.landmarks_xy.copy()
poses, valid = ml.truth_poses()
t0 = time.time()
res = fit_em(data.with_landmarks(np.full_like(truth, np.nan)), None, mrclam_config())
secs = time.time() - t0
m = res.model.landmarks
ok = np.isfinite(m.xy).all(1)
a, b = m.xy[ok], truth[ok]
ca, cb = a.mean(0), b.mean(0)
U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
R = (U @ D @ Vt).T
t = cb - R @ ca
print(
    "robot",
    robot,
    "map rms",
    np.sqrt((((a @ R.T + t) - b) ** 2).sum(1).mean()).round(1),
    "placed",
    ok.sum(),
    "sd",
    np.nanmean(m.sd, 0).round(1),
)
p2 = res.posteriors.mean_gamma[:, :2] @ R.T + t
v = valid > 0
print(
    "path median",
    np.median(np.hypot(*(p2[v] - poses[v, :2]).T)).round(1),
    "ll",
    round(res.loglik_best, 1),
    "secs",
    round(secs, 1),
    res.iterations,
)
