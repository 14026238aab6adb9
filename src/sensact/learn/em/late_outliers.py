"""Sec. 4.4.1's outlier gate again, when the robust readings take over (``EMConfig.prune_when_freed``).

The thesis drops a sighting in the first iteration when its bearing innovation exceeds 0.6 rad per step
since the previous sighting. A camera that sees a landmark every few frames, as MRCLAM's does, is k = 7
steps or more from its last sighting, and 0.6 k is then beyond pi: no bearing can fail the gate. On
Dataset 6 robot 5 keeps five sightings 2.6-2.8 rad off Vicon's bearing (misread barcodes, four within
1.2 s); the Gaussian stage (graduated robustness, docs/em-real.md) counts them in full, and the
Student-t stage after it stays with the widened sigmas it inherits. When the Gaussian stage ends, each
sighting has a smoothed pose at its own step, so the gate is applied once more with k = 1.
"""

from __future__ import annotations

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.core.pose_models import landmark_bearing, sensor_poses
from sensact.learn.em.estep import Posteriors
from sensact.logs.landmark_log import LandmarkLog


def bearing_outliers(
    post: Posteriors, data: LandmarkLog, gate_rad: float, mount: np.ndarray | None = None
) -> np.ndarray:
    """``(K,)`` bool: the sightings ``post`` used whose measured bearing is more than ``gate_rad`` from the
    bearing of their landmark at the smoothed mean pose of their own step (sec. 4.4.1's gate, k = 1), seen
    from the sensor at ``mount`` (forward mm, left mm, yaw rad; None: the robot's own point)."""
    out = np.zeros(data.n_observations, dtype=bool)
    if not data.geometry.has_heading or not gate_rad > 0:
        return out
    rows = np.flatnonzero(post.obs_used & np.isfinite(data.obs_bearing_rad))
    lm = data.landmarks_xy[data.obs_landmark[rows]]
    res = wrap_angle(
        data.obs_bearing_rad[rows]
        - landmark_bearing(
            sensor_poses(post.mean_gamma[data.obs_step[rows]], np.zeros(3) if mount is None else mount), lm
        )
    )
    out[rows[np.abs(res) > gate_rad]] = True
    return out
