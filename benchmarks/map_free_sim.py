import sys
import time

import numpy as np

from sensact.learn.em import fit_em
from sensact.presets import planar_config
from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

secs = float(sys.argv[1]) if len(sys.argv) > 1 else 300
run = simulate_diffdrive(DiffDriveConfig(seconds=secs, seed=1, range_gain=1.0))
data = run.log()
truth_map = data.landmarks_xy.copy()
cfg = planar_config(data.command_names)
if len(sys.argv) > 2:
    cfg = cfg.replace(sensor_mount=(0.0, 0.0, 0.0))
t0 = time.time()
full = fit_em(data, None, cfg)
t1 = time.time()
hidden = data.with_landmarks(np.full_like(truth_map, np.nan))
res = fit_em(hidden, None, cfg)
t2 = time.time()
m = res.model.landmarks


def align(A, B):
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    a, b = A[ok], B[ok]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return R, cb - R @ ca, ok


R, t, ok = align(m.xy, truth_map)
err = (m.xy[ok] @ R.T + t) - truth_map[ok]
print("map rms mm", np.sqrt((err**2).sum(1).mean()), "placed", ok.sum(), "of", len(ok))
print("sd", np.nanmean(m.sd, 0))
path = res.posteriors.mean_gamma.copy()
p2 = path[:, :2] @ R.T + t
off = np.hypot(*(p2 - run.poses[:, :2]).T)
off_full = np.hypot(*(full.posteriors.mean_gamma[:, :2] - run.poses[:, :2]).T)
print("path median mm", np.median(off), "with map", np.median(off_full))
print("iters", res.iterations, full.iterations, "secs", t2 - t1, t1 - t0, res.stop_reason)
print("action", {k: round(v, 4) for k, v in res.model.action.named_parameters().items() if abs(v) > 0})
print("action full", {k: round(v, 4) for k, v in full.model.action.named_parameters().items() if abs(v) > 0})
print("sigma range", [c.sigma for c in res.model.sensor.channels], [c.sigma for c in full.model.sensor.channels])
a = m.xy[ok]
b = truth_map[ok]
ca, cb = a.mean(0), b.mean(0)
k = np.sqrt(((b - cb) ** 2).sum() / ((a - ca) ** 2).sum())
print("scale truth/learned", k)
ch = res.model.sensor.channels[0]
x = np.array([1000.0, 3000.0, 5000.0, 7000.0])
print("f", ch.function(x).round(0), "slope", ch.function.slope(x).round(3), "terms", ch.bearing_terms)
ch = full.model.sensor.channels[0]
print("f full", ch.function(x).round(0), "slope", ch.function.slope(x).round(3), "terms", ch.bearing_terms)
print("mount", res.model.sensor.mount, full.model.sensor.mount)
