import json

import numpy as np

from sensact.io.mrclam import read_mrclam
from sensact.learn.em.estep import channel_inputs
from sensact.learn.em.landmarks import landmark_update
from sensact.models.em_model import EMModel

ml = read_mrclam("/work/shared/data/mrclam/MRCLAM_Dataset6", 3)
data = ml.data
poses, valid = ml.truth_poses()
survey = EMModel.from_dict(json.load(open("/tmp/after/mr3/model.json"))["model"])
rows = np.flatnonzero(valid[data.obs_step] > 0)
P = poses[data.obs_step[rows]][None]
readings = channel_inputs(survey.sensor, data)[0][rows]
w = np.ones((rows.size, 2))
w[~np.isfinite(readings[:, 0]), 0] = 0
rng = np.random.default_rng(0)
start = data.landmarks_xy + rng.normal(0, 300, data.landmarks_xy.shape)
xy, sd = landmark_update(
    P, data.obs_landmark[rows], readings, w, data.obs_bearing_rad[rows], survey.sensor, start, np.ones(len(start), bool)
)
print(
    "from 300 mm off, on Vicon poses: max err",
    np.abs(xy - data.landmarks_xy).max().round(1),
    "rms",
    np.sqrt(((xy - data.landmarks_xy) ** 2).sum(1).mean()).round(1),
)
xy0, _ = landmark_update(
    P,
    data.obs_landmark[rows],
    readings,
    w,
    data.obs_bearing_rad[rows],
    survey.sensor,
    data.landmarks_xy,
    np.ones(len(start), bool),
)
print("from the survey: rms move", np.sqrt(((xy0 - data.landmarks_xy) ** 2).sum(1).mean()).round(1))
