"""The learning algorithms, one module (or package) each.

* ``bootstrap`` with its compiled core ``bootstrap_kernel``: chapter 3's Algorithm 1;
* ``em/``: chapter 4's EM, in rooms by role;
* ``spinning_lidar_intrinsics`` (sec. 5.1), ``scan_odometry`` (sec. 5.2) and ``velodyne_car_dynamics``
  (sec. 5.3): chapter 5's car;
* ``inertial``: wheel odometry's gains, the gyro, the IMU's mount and GNSS, by EM over the path;
* ``scan_match2d`` and ``wheel_lidar``: a differential drive's wheels and its 2-D lidar's mount, from
  scan matching (beyond the thesis); ``car_lidar``: a car's VESC numbers, wheelbase and lidar mount the same way.
"""
