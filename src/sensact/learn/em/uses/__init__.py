"""A learned model put to use (beyond the thesis):

* ``place``: where the robot was in another log, by the E-step alone (``sensact localize``);
* ``warm_start``: EM started from a learned model placed on the log (``learn em --start-from``);
* ``consistency``: the model's one-step-ahead innovations against its predictive law (``evaluate log``);
* ``change_detect``: whether the robot has changed since, from the filter's innovations (``sensact monitor``);
* ``split_halves``: each half of the log learned on from the whole's model (``learn em --halves``);
* ``draw_log`` and ``error_bars``: logs drawn from the model and learned again, a parametric bootstrap
  (``learn em --uncertainty B``);
* ``information``: error bars from the likelihood's curvature and profiles (``learn em --uncertainty
  information``).
"""
