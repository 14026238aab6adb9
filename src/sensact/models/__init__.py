"""What is learned, as frozen values that convert to and from JSON.

* ``action_model`` and ``sensor_model``: the two protocols EM reads every action and sensor model through;
* ``action_table``, ``linear_action`` (with its M-step, ``linear_action_fit``) and ``wheel_drive``: the action
  models (a table of discrete actions; coefficients on continuous commands; read as a drive's numbers);
* ``landmark_sensor``: eq. 4.19's sensor, the first ``SensorModel``; ``polynomial``: its f (and chapter 3's);
* ``landmark_map``: the landmarks' positions, when EM learns them;
* ``em_model``: everything chapter 4's EM learns;
* ``spinning_lidar`` and ``laser_intrinsics``: chapter 5's 3-D units and their per-laser geometry;
  ``velodyne_car_dynamics``: chapter 5's car.
"""
