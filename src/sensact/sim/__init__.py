"""Simulated robots and worlds, each keeping the truth that evaluation needs.

* ``track1d``: chapter 3's Aibo on a track; ``field2d``: chapter 4's field;
* ``diffdrive``: a differential drive among landmarks, as MRCLAM's robots (or with radio anchors);
* ``lidar2d``: a differential drive with encoders and a 2-D lidar in a furnished room;
* ``car``: a 1/10-scale car-like robot (VESC, servo, 270-degree lidar) lapping a corridor track;
* ``inertial``: a skid-steer robot over a field with wheel odometry, an IMU and GNSS;
* ``velodyne_car``: chapter 5's car with its spinning lidar in a town.
"""
