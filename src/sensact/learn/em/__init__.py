"""Chapter 4: EM with an extended Kalman smoother.

``estep`` (sec. 4.2) -> ``mstep`` (sec. 4.3, its action and motion-noise updates in ``actions``) ->
``fit`` (the loop, secs. 4.1 and 4.4.1) from ``initial`` (sec. 4.4.1's poor start), with ``config`` its
settings. The compiled forward and backward passes live in ``sensact.core.ekf_smoother``. Beyond the
thesis, for real logs:

* ``start``: where the robot starts, when nobody says (a grid and a race); ``given_start``: a start the
  user gave, for a sensor without bearings, and when EM moved it;
* ``ridge``: a line search along the path's trade-off with the range functions' offset;
* ``delay_search``: the command delay, chosen by the likelihood;
* ``outliers``: sec. 4.4.1's gate again when the robust readings take over;
* ``checks``: signs, without ground truth, that a fit lost its robot;
* ``forward``: which way is forward for a robot whose sensor reads no bearing;
* ``localize``: a learned model put to use, the E-step alone on another log, its start searched for.
"""

from sensact.learn.em.config import EMConfig
from sensact.learn.em.estep import Posteriors, e_step, log_likelihood
from sensact.learn.em.fit import EMResult, fit_em
from sensact.learn.em.initial import initial_model
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
]
