"""The application layer: everything a `sensact` command does, callable from Python.

``open_log(path)`` decides what a path is, through one registry of log kinds (``log_kinds``);
``calibrate(log, preset or config)`` runs that kind's learner and returns its calibration (on a landmark
log a ``Calibration``: the model, typed diagnostics, the scores when the log has truth);
``save_calibration`` writes it as `learn em --out` does. ``sensact learn em DIR`` is
``calibrate(open_log(DIR))`` and printing, for every kind.
"""

from sensact.app.calibrate import Calibration, Diagnostics, FitEvents, StartFrom
from sensact.app.lidar2d import Lidar2DCalibration, OpenedLidar2DLog
from sensact.app.log_kinds import KINDS, LogKind, calibrate, open_log, save_calibration
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
