"""Figures (matplotlib), tables and pages; a ROS user reads REP 103 and SI everywhere (``frames``).

* ``tables``, ``tables_real`` and ``tables_fleet``: result tables with the thesis's numbers beside ours;
* ``figures1d``, ``figures_em``, ``figures_real``, ``figures_turtlebot_em`` and ``figures_velodyne_car``:
  the thesis's figures and their real-data kin;
* ``figures_bootstrap``, ``figures_fit``, ``figures_calibration``, ``figures_halves``, ``figures_log``,
  ``figures_monitor`` and ``figures_fleet``: one run's figures, drawn from the run alone;
* ``page``, ``lidar2d``, ``car`` and ``inertial``: a calibration's report page; ``html_report``: ``RESULTS/index.html``.
"""
