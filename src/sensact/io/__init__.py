"""Bytes to tables and log folders, and back; every reader refuses bad input in one line.

* ``atomic``, ``jsonfile`` and ``csvtable``: atomic writes, and JSON and CSV read with errors that name
  the file, the field and the fix;
* ``landmark_folder``, ``logfolder``, ``lidar2d_folder``, ``car_folder``, ``inertial_folder`` and
  ``velodyne_car_folder``: the native log folders (EM's, chapter 3's, the wheels-and-lidar robot's, a car-like
  robot's, the outdoor robot's, chapter 5's car's);
* ``intervals``: Censi et al.'s scan-matched intervals (JSON lines or CSV) and their folder;
* ``resample``, ``timed_csv``, ``track_csv``, ``mrclam`` and ``turtlebot``: a robot's own CSVs and public
  datasets as log folders; ``unit_checks``: a column whose numbers belie its unit;
* ``rosbag``, ``rosbag1_scan``, ``rosbag_lidar2d``, ``rosbag_car``, ``rosbag_inertial`` and ``rosbag_write``: ROS
  bags read (and written, for the simulators);
* ``velodyne``, ``spinning_lidar_packets`` and ``velodyne_calibration``: lidar captures and factory
  calibrations.
"""
