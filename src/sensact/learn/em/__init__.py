"""Chapter 4: EM with an extended Kalman smoother.

``estep`` (sec. 4.2) -> ``mstep`` (sec. 4.3) -> ``fit`` (the loop, secs. 4.1 and 4.4.1). The compiled
forward and backward passes live in ``sensact.core.ekf_smoother``. Beyond the thesis, for real logs:
``start`` (where the robot starts: a grid and a race), ``ridge`` (a line search along the path's
trade-off with the range functions' offset) and ``delay_search`` (the command delay, chosen by the
likelihood).
"""

from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors, e_step, log_likelihood, motion_variance
from sensact.learn.em.fit import EMResult, fit_em, initial_model
from sensact.learn.em.mstep import m_step
from sensact.logs.landmark_log import LandmarkLog

__all__ = [
    "EMConfig",
    "EMResult",
    "LandmarkLog",
    "Posteriors",
    "e_step",
    "fit_em",
    "initial_model",
    "log_likelihood",
    "m_step",
    "motion_variance",
]
