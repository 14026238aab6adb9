"""A simulated robot on continuous commands among five landmarks, and the EM settings that learn it from
a near start: the seeded-recovery oracle of the EM tests beyond the thesis (test_em_continuous.py,
test_em_searches.py, test_em_lost_fit.py, test_truth_residuals.py; its fit is conftest's ``continuous_fit``), a
log with its truth as the MRCLAM experiment reads it, and a tiny track log for the checks that refuse one."""

from __future__ import annotations

import math

import numpy as np

from sensact.core.pose_models import apply_displacement, landmark_bearing, landmark_distance
from sensact.learn.em import EMConfig
from sensact.learn.em.config import ChannelConfig
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.linear_action import command_features

TRUE_BETA = np.array([[5.0, 20.0, 0.02], [0.0, 0.9, 0.0], [30.0, 0.0, 0.8]])  # rows 1, v, omega
TRUE_SD = np.array([4.0, 5.0, 0.02])  # per step
LANDMARKS = np.array([[0.0, 2500.0], [3000.0, 0.0], [0.0, -2500.0], [-3000.0, 0.0], [2000.0, 2000.0]])


def simulate_continuous(
    seed: int,
    T: int = 9000,
    outlier_frac: float = 0.0,
    beta=TRUE_BETA,
    bearing_terms=(0.0, 0.0),
    sd=TRUE_SD,
    turn_var: float = 0.0,
    delay_steps: int = 0,
    beta_after=None,
):
    """A robot on continuous commands among five landmarks, range and bearing. The range reads
    ``1.05 d + 40 + d (a_1 b + a_2 b^2)`` with ``bearing_terms`` (a_1, a_2) at the measured bearing b.
    The heading's motion variance per step is ``sd[2]^2 + turn_var |omega_t|``. The robot obeys each
    command ``delay_steps`` steps late, and from step ``T // 2`` on obeys ``beta_after`` when it is given
    (a change during the run, as a new floor)."""
    rng = np.random.default_rng(seed)
    dt = 1 / 30
    seg = rng.integers(30, 120, T // 30)
    levels = np.column_stack([rng.uniform(0, 300, seg.size), rng.uniform(-0.6, 0.6, seg.size)])
    commands = np.repeat(levels, seg, axis=0)[:T]
    betas = [beta, beta if beta_after is None else beta_after]
    v = np.concatenate(
        [command_features("affine", 1, c) @ b for c, b in zip(np.split(commands, [T // 2]), betas, strict=True)]
    )
    poses = np.zeros((T, 3))
    for t in range(T - 1):
        b = betas[t >= T // 2]
        # steer back toward the middle, so the robot stays among the landmarks
        if np.hypot(*poses[t, :2]) > 1500:
            commands[t, 1] = 0.6
            v[t] = command_features("affine", 1, commands[t : t + 1]) @ b
        if delay_steps:
            late = max(t - delay_steps, 0)
            v[t] = command_features("affine", 1, commands[late : late + 1]) @ b
        step_sd = np.array([sd[0], sd[1], math.sqrt(sd[2] ** 2 + turn_var * abs(v[t, 2]))])
        poses[t + 1] = apply_displacement(poses[t], (v[t] + rng.normal(size=3) * step_sd / dt) * dt)[0]
    steps = np.arange(0, T, 6)
    which = rng.integers(0, len(LANDMARKS), steps.size)
    d = landmark_distance(poses[steps], LANDMARKS[which])
    rng_mm = 1.05 * d + 40.0 + rng.normal(size=d.size) * 30.0
    bearing = landmark_bearing(poses[steps], LANDMARKS[which]) + rng.normal(size=d.size) * 0.02
    a1, a2 = bearing_terms
    rng_mm += d * (a1 * bearing + a2 * bearing**2)
    bad = rng.random(d.size) < outlier_frac
    rng_mm[bad] = rng.uniform(200, 8000, bad.sum())
    data = LandmarkLog(
        "planar",
        dt,
        np.full(T, -1),
        np.zeros((0, 2)),
        ("v_mm_s", "omega_rad_s"),
        steps,
        which,
        rng_mm,
        bearing,
        LANDMARKS,
        reading_names=("range_mm",),
        step_commands=commands,
    )
    return data, poses


def continuous_config(**kw) -> EMConfig:
    base = dict(
        action_basis="affine",
        motion_noise="shared",
        motion_sd_mm=10.0,
        motion_sd_rad=0.05,
        channels=(ChannelConfig("range_mm", 1, 0.0, 0.8, 300.0),),
        start_prior_sd=(100.0, 100.0, 0.1),
        prune_rad_per_step=0.0,
        max_iterations=300,
        refine_from=0,  # a near start: no need to hold Sigma_m and the bearing terms first
    )
    base.update(kw)
    return EMConfig.of(**base)


class TruthLog:
    """What the MRCLAM experiment reads of an ``MrclamLog``: the log and its truth poses."""

    def __init__(self, data: LandmarkLog, poses: np.ndarray):
        self.data, self._poses = data, poses

    def truth_poses(self) -> tuple[np.ndarray, np.ndarray]:
        return self._poses, np.ones(len(self._poses), dtype=bool)


def tiny_track() -> LandmarkLog:
    """A five-step track log with one sighting: enough for the checks that refuse a track."""
    return LandmarkLog(
        "track",
        0.1,
        np.zeros(5, dtype=int),
        np.zeros((1, 1)),
        ("v",),
        np.array([0]),
        np.array([0]),
        np.array([100.0]),
        np.array([np.nan]),
        np.zeros((1, 2)),
        source="t.csv",
    )
