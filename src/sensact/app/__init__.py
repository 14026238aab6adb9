"""The application layer: everything a `sensact` command does, callable from Python.

``open_log(path)`` decides what a path is, through one registry of log kinds (``log_kinds``);
``calibrate(log, preset or config)`` runs that kind's learner and returns its calibration (on a landmark
log a ``Calibration``: the model, typed diagnostics, the scores when the log has truth);
``save_calibration`` writes it as `learn em --out` does. ``sensact learn em DIR`` is
``calibrate(open_log(DIR))`` and printing, for every kind.

* ``log_kinds``: the registry, one door per log kind: its opener, learner and writer (``opened``: what the
  kinds whose readers refuse what they doubt share once opened, and those fitted in seconds once fitted);
* ``calibrate``: ``calibrate(log)``, by the learner of the log's kind;
* ``logs`` with ``em``, ``save``, ``scores`` and ``report``: a landmark log learned by EM, written, scored
  against its truth and reported; ``uncertainty``: its error bars;
* ``lidar2d``: a wheels-and-2-D-lidar log learned and written; ``car``: a car-like robot's (VESC and lidar);
  ``intervals``: Censi et al.'s scan-matched intervals'; ``inertial``: an odometry-IMU-GNSS log's;
  ``velodyne_car``: chapter 5's car;
  ``bootstrap``: chapter 3's Algorithm 1 scored;
* ``settings``: every command's settings, resolved in one place;
* ``localize`` and ``monitor``: a learned model placed on, and run over, another log;
* ``fleet`` and ``shared_map``: many robots' logs learned and cross-scored, on a Dask cluster;
* ``export``, ``export_lidar2d``, ``export_inertial``, ``export_car`` and ``ros_params``: learned models as ROS
  reads them.
"""

from sensact.app.calibrate import calibrate
from sensact.app.em import Calibration, Diagnostics, FitEvents, StartFrom
from sensact.app.lidar2d import Lidar2DCalibration, OpenedLidar2DLog
from sensact.app.log_kinds import KINDS, LogKind, open_log, save_calibration
from sensact.app.logs import OpenedLandmarkLog
from sensact.app.scores import Scores, Unscored
from sensact.app.settings import Settings, read_settings_file, resolve_settings

__all__ = [
    "KINDS",
    "Calibration",
    "Diagnostics",
    "FitEvents",
    "Lidar2DCalibration",
    "LogKind",
    "OpenedLandmarkLog",
    "OpenedLidar2DLog",
    "Scores",
    "Settings",
    "StartFrom",
    "Unscored",
    "calibrate",
    "open_log",
    "read_settings_file",
    "resolve_settings",
    "save_calibration",
]
