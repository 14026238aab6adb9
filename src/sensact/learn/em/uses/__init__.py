"""A learned model put to use (beyond the thesis):

* ``place``: where the robot was in another log, by the E-step alone (``sensact localize``);
* ``change_detect``: whether the robot has changed since, from the filter's innovations (``sensact monitor``);
* ``split_halves``: each half of the log learned on from the whole's model (``learn em --halves``);
* ``draw_log`` and ``error_bars``: logs drawn from the model and learned again, a parametric bootstrap
  (``learn em --uncertainty``).
"""
