import sys
import time

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em
from sensact.presets import mrclam_config

robot = int(sys.argv[1])
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
poses, valid = ml.truth_poses()
truth_map = data.landmarks_xy.copy()
cfg = mrclam_config()
if len(sys.argv) > 2 and sys.argv[2] != "-":  # a mount to hold: forward,left,yaw
    cfg = cfg.replace(sensor_mount=tuple(float(v) for v in sys.argv[2].split(",")))
for kv in sys.argv[3:]:  # config fields, name=value
    k, v = kv.split("=")
    cfg = cfg.replace(**{k: float(v)})
t0 = time.time()
res = fit_em(data.with_landmarks(np.full_like(truth_map, np.nan)), None, cfg)
t1 = time.time()
m = res.model.landmarks


def align(A, B):
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    a, b = A[ok], B[ok]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return R, cb - R @ ca, ok


counts = np.bincount(data.obs_landmark, minlength=len(truth_map))
R, t, ok = align(m.xy, truth_map)
err = np.hypot(*((m.xy[ok] @ R.T + t) - truth_map[ok]).T)
print(
    "robot",
    robot,
    "map rms mm",
    np.sqrt((err**2).mean()).round(1),
    "placed",
    ok.sum(),
    "of",
    len(ok),
    "sightings",
    counts,
)
print("per landmark err", err.round(0))
p2 = res.posteriors.mean_gamma[:, :2] @ R.T + t
v = valid > 0
print(
    "path median mm",
    np.median(np.hypot(*(p2[v] - poses[v, :2]).T)).round(1),
    "iters",
    res.iterations,
    "secs",
    round(t1 - t0, 1),
    res.stop_reason,
)
print("action", {k: round(v, 4) for k, v in res.model.action.named_parameters().items() if abs(v) > 0})
print("sigma", [c.sigma for c in res.model.sensor.channels], res.model.sensor.sigma_bearing_rad, res.model.sensor.mount)
a = m.xy[ok]
b = truth_map[ok]
ca, cb = a.mean(0), b.mean(0)
print("scale truth/learned", np.sqrt(((b - cb) ** 2).sum() / ((a - ca) ** 2).sum()).round(4))
ch = res.model.sensor.channels[0]
x = np.array([1000.0, 3000.0, 5000.0])
print("f", ch.function(x).round(0), "terms", np.round(ch.bearing_terms, 4), "start", res.model.prior_mean.round(3))
