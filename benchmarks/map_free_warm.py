import json
import sys

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em, initial_model
from sensact.models.em_model import EMModel
from sensact.presets import mrclam_config

robot = int(sys.argv[1])
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
truth = data.landmarks_xy.copy()
blank = data.with_landmarks(np.full_like(truth, np.nan))
cfg = mrclam_config()
survey = EMModel.from_dict(json.load(open(f"/tmp/after/mr{robot}/model.json"))["model"])
start = initial_model(blank, cfg)
start = survey.replace(prior_mean=start.prior_mean, prior_cov=start.prior_cov, landmarks=start.landmarks)
res = fit_em(blank, start, cfg.replace(refine_from=0))


def align(A, B):
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    a, b = A[ok], B[ok]
    ca, cb = a.mean(0), b.mean(0)
    U, _, Vt = np.linalg.svd((a - ca).T @ (b - cb))
    D = np.diag([1, np.sign(np.linalg.det(U @ Vt))])
    R = (U @ D @ Vt).T
    return R, cb - R @ ca, ok


R, t, ok = align(res.model.landmarks.xy, truth)
err = np.hypot(*((res.model.landmarks.xy[ok] @ R.T + t) - truth[ok]).T)
print(
    "warm from survey models: map rms",
    np.sqrt((err**2).mean()).round(1),
    "ll",
    round(res.loglik_best, 1),
    res.iterations,
    res.model.sensor.mount,
)
