"""A map nobody surveyed (issue 92; docs/map.md): the landmarks' positions learned with the models.

* ``slam_start``: the frame (the robot's start), the scale and the first map (EKF-SLAM on the commands at
  face value), for ``initial.py``'s starting model;
* ``slam_filter``: the map carried by a filter over (pose, landmarks) under the current models;
* ``landmark_step``: the landmarks' M-step (Gauss-Newton on Q), their sds, and which are placed;
* ``rounds``: the filter's map and EM on it, in rounds, as ``fit.py`` runs a log without a map;
* ``anchors``: range-only anchors, placed on the path the given ones fix, then moved by the M-step.
"""
