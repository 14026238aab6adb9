import json
import sys

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em import fit_em, log_likelihood
from sensact.models.em_model import EMModel
from sensact.presets import mrclam_config

robot = int(sys.argv[1])
ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", robot)
data = ml.data
survey = EMModel.from_dict(json.load(open(f"/tmp/after/mr{robot}/model.json"))["model"])
print("survey fit, survey map: loglik", round(log_likelihood(survey, data), 1))
res = fit_em(data.with_landmarks(np.full_like(data.landmarks_xy, np.nan)), None, mrclam_config())
free = res.model
print(
    "map-free fit, its map:   loglik",
    round(log_likelihood(free, data.with_landmarks(free.landmarks.xy)), 1),
    "best",
    round(res.loglik_best, 1),
)
