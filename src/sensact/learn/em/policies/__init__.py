"""How a fit is started and kept clean (beyond the thesis):

* ``warm_start``: a learned model as the start (another robot's, or this one's before a change), placed
  on the log first;
* ``late_outliers``: sec. 4.4.1's gate again, on the smoothed path, when the robust readings take over.
"""
