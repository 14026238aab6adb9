"""Typed logs, as the learners read them (``io/`` reads them from bytes).

* ``landmark_log``: a robot among landmarks, EM's input (ch. 4);
* ``lidar2d_log``: wheels (or /odom, /cmd_vel) and a 2-D lidar's scans;
* ``car_log``: a car-like robot's VESC ERPM, servo commands and 2-D scans;
* ``intervals_log``: scan-matched intervals as Censi et al.'s tool holds them;
* ``inertial_log``: wheel odometry, an IMU and GNSS fixes (an outdoor robot's);
* ``track_log``: a 1-D log on one time grid, chapter 3's input.
"""
