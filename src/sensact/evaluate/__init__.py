"""Learned models against ground truth (never used for learning).

* ``bars``: the bars a result must clear, each said in words;
* ``scaled``, ``measured``, ``track1d`` and ``real_track``: chapter 3's scale-free comparison, against the
  simulator's or a real log's measured models;
* ``em``, ``landmark_truth``, ``map_truth``, ``simulated_robot``, ``turtlebot_em`` and ``halves``: chapter
  4's fits against their truth, a learned map against its survey, two halves against each other;
* ``velodyne_car``: chapter 5's car against its simulated truth.
"""
