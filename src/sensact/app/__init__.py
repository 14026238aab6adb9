"""The application layer: everything a `sensact` command does, callable from Python.

``open_log(path)`` decides what a path is; ``calibrate(log, preset or config)`` learns its models and
returns a ``Calibration`` (the model, typed diagnostics, the scores when the log has truth);
``save_calibration`` writes it as `learn em --out` does. ``sensact learn em DIR`` is
``calibrate(open_log(DIR))`` and printing.
"""

from sensact.app.calibrate import Calibration, Diagnostics, FitEvents, StartFrom, calibrate
from sensact.app.logs import OpenedLog, open_log
from sensact.app.save import save_calibration
from sensact.app.scores import Scores, Unscored
from sensact.app.settings import Settings, read_settings_file, resolve_settings

__all__ = [
    "Calibration",
    "Diagnostics",
    "FitEvents",
    "OpenedLog",
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
