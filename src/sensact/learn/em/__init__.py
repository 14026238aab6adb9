"""Chapter 4: EM with an extended Kalman smoother, in rooms by role; each room imports only the rooms
listed before it.

The thesis's core, here:

* ``config``: the settings, each field with its source; ``stage``: what the M-step may move, in turn;
* ``estep`` (sec. 4.2): the compiled passes of ``sensact.core.ekf_smoother`` on a model and a log;
* ``mstep`` (sec. 4.3): the action model's own update (``models/action_model.py``), the sensor's
  (``models/sensor_model.py``), Sigma_m's (``actions``), the sensor mount's (``mount``) and, on a map
  nobody surveyed, the landmarks' (``landmark_step``);
* ``initial``: sec. 4.4.1's poor start, and on a map nobody surveyed its frame and first map (``slam_start``);
* ``late_outliers``: sec. 4.4.1's gate again, when the robust readings take over;
* ``squarem``: EM's map extrapolated (SQUAREM), on coordinates where every point is a model;
* ``space``: the learned parameters as one vector, where the curvature is taken and steps are measured;
* ``fixed_point``: the deterministic EM's stop at its fixed point, its steps measured in the observed
  information;
* ``result``: what a fit returns, and the signs that it lost the robot;
* ``loop`` (secs. 4.1 and 4.4.1): E- and M-steps in stages, the searches between them;
* ``fit``: a whole fit, from the start race or a given start, with its restarts and map rounds;
* ``progress``: when a fit will end, projected from its convergence.

Beyond the thesis, for real logs, four rooms:

* ``searches/``: moves along the likelihood's ridges (start, ridge, delay, mount, facing), which
  ``loop`` runs;
* ``checks/``: what a finished fit says about itself (lost signs, health);
* ``unsurveyed/``: a map nobody surveyed, carried in rounds by a filter (docs/map.md);
* ``uses/``: a learned model put to use (warm start, place, change detection, consistency, halves,
  error bars by bootstrap and by the likelihood's curvature).
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
