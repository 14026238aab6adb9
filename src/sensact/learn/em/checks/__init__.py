"""Checks on a finished fit, with no ground truth (beyond the thesis):

* ``lost_signs``: signs that EM lost the robot (a range function that turns back, a likelihood still
  falling), which the restart policy in ``fit.py`` acts on;
* ``fit_health``: whether the fit is a result at all (degenerate, unfinished): flags that end a command
  with exit code 3;
* ``diagnostics``: every check run once on a fit, each warning as one line.
"""
