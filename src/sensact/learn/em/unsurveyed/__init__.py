"""A map nobody surveyed (docs/map.md): the landmarks' positions learned with the models, in rounds. The
map's own M-step (``learn/em/landmark_step.py``) and its start (``learn/em/slam_start.py``) are EM's core.

* ``slam_filter``: the map carried by a filter over (pose, landmarks) under the current models;
* ``rounds``: the filter's map and EM on it, in rounds, as ``fit.py`` runs a log without a map;
* ``anchors``: range-only anchors, placed on the path the given ones fix, then moved by the M-step.
"""
