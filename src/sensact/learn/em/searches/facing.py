"""Which way is forward, for a robot whose sensor reads no bearing (beyond the thesis, whose camera did).

A range-only sensor (UWB anchors, sonar beacons) sees only where the robot is. Turn every heading of
the path by pi and negate every action's translation in the robot's frame (v_x and v_y; the turn rate
stays): the positions, so every range, are unchanged, and so is the likelihood (eq. 4.14), since
Sigma_m's translational part is symmetric under it. EM re-estimates the prior from gamma_0 (sec. 4.3),
so the prior's heading does not hold it to one of the two, and it can end in either: a robot that
drives backward facing the other way. Both are the same model; sensact reports the one in which the
robot, on average over the log's steps, drives forward (+y), the one a user means by "forward".
With bearings the heading is observed, and nothing is turned.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from sensact.core.angles import wrap_angle
from sensact.learn.em.estep import Posteriors
from sensact.logs.landmark_log import LandmarkLog
from sensact.models.em_model import EMModel

# robot-frame (v_x, v_y, v_theta): the translation flips, the turn stays
FLIP = np.array([-1.0, -1.0, 1.0])


def drives_backward(model: EMModel, data: LandmarkLog) -> bool:
    """Whether a planar model without bearings has the robot drive backward on average over ``data``'s
    steps: the labelling to turn by pi. False whenever the sensor reads bearings."""
    if not model.geometry.has_heading or model.sensor.reads_bearing:
        return False
    return float(np.mean(model.action.step_velocity(data)[:, 1])) < 0.0


def turned_model(model: EMModel) -> EMModel:
    """The same model with the robot facing the other way: headings + pi, translations negated."""
    a = model.action
    action = a.with_parameters(a.parameters * FLIP)
    mean = model.prior_mean.copy()
    mean[2] = float(wrap_angle(mean[2] + np.pi))
    return model.replace(action=action, prior_mean=mean)  # a constant turn leaves the covariances as they are


def turned_posteriors(post: Posteriors) -> Posteriors:
    """The E-step's posteriors of ``turned_model``: the headings + pi; the robot-frame displacements'
    translation negated, with its covariance with the heading change."""

    def headings(m: np.ndarray) -> np.ndarray:
        out = m.copy()
        out[:, 2] = wrap_angle(out[:, 2] + np.pi)
        return out

    return replace(
        post,
        mean_alpha=headings(post.mean_alpha),
        mean_gamma=headings(post.mean_gamma),
        disp_mean=post.disp_mean * FLIP,
        disp_cov=post.disp_cov * np.outer(FLIP, FLIP),
    )
