"""Chapter 4: EM with an extended Kalman smoother, in rooms by role.

The thesis's core, here: ``estep`` (sec. 4.2) -> ``mstep`` (sec. 4.3; the action models' own updates,
``models/action_model.py``; Sigma_m's in ``actions``; the sensor mount's in ``mount``) -> ``loop`` (secs.
4.1 and 4.4.1), run in ``stage``s (what the M-step may move) by ``fit`` from ``initial`` (sec. 4.4.1's
poor start) or a race of starts, with ``config`` its settings and ``result`` what it returns;
``progress`` projects when it will end. The compiled passes live in ``sensact.core.ekf_smoother``.

Beyond the thesis, for real logs, five rooms:

* ``searches/``: moves along the likelihood's ridges (start, ridge, delay, mount, facing);
* ``policies/``: how a fit starts and stays clean (warm start, late outliers);
* ``checks/``: what a finished fit says about itself (lost signs, health);
* ``uses/``: a learned model put to use (place, change detection, halves, error bars);
* ``unsurveyed/``: a map nobody surveyed, learned with the models (issue 92).
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
