"""One door per log kind, as kiss-icp's ``dataset_factory``: ``open_log(path)`` asks each registered kind,
in order, whether ``path`` is one of its logs and opens it with that kind's opener; ``calibrate(log, ...)``
runs the learner of the kind that opened it. ``sensact learn em DIR`` is ``calibrate(open_log(DIR))`` and
printing, for every kind. A new kind of log is one module with its opener and learner, and one
``register`` here; nothing outside this module asks what kind a log is.

The kinds:

* ``lidar2d``: a folder of wheel encoders (or /odom, /cmd_vel) and 2-D scans (``meta.json``'s ``kind``);
* ``car``: a folder of a car-like robot's VESC ERPM, servo commands and 2-D scans (``meta.json``'s ``kind``);
* ``intervals``: a folder of scan-matched intervals (``convert intervals``; ``meta.json``'s ``kind``);
* ``imu_gnss``: a folder of wheel odometry, an IMU and optionally GNSS (``meta.json``'s ``kind``);
* ``turtlebot_csv``: the Turtlebot's 1-D CSV, read by EM with the Turtlebot's settings;
* ``landmarks``: a log folder of actions and landmark sightings, EM's own: range and bearing, range-only
  or a 1-D track, as its ``meta.json`` says (the geometry and the sensor model are types of their own).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sensact.app.car import CarCalibration, OpenedCarLog, calibrate_opened_car, open_car_log, save_car
from sensact.app.em import Calibration, calibrate_em
from sensact.app.inertial import (
    InertialCalibration,
    OpenedInertialLog,
    calibrate_opened_inertial,
    evaluate_inertial,
    halves_inertial,
    open_inertial_log,
    save_inertial,
)
from sensact.app.intervals import (
    IntervalsCalibration,
    OpenedIntervalsLog,
    calibrate_opened_intervals,
    open_intervals_log,
    save_intervals,
)
from sensact.app.lidar2d import (
    Lidar2DCalibration,
    OpenedLidar2DLog,
    calibrate_opened_lidar2d,
    open_lidar2d_log,
    save_lidar2d,
)
from sensact.app.logs import OpenedLandmarkLog, open_landmark_folder, open_turtlebot_csv
from sensact.app.save import Saved, save_em_calibration
from sensact.errors import ConfigError, LogFormatError
from sensact.io.car_folder import KIND as CAR_KIND
from sensact.io.inertial_folder import KIND as INERTIAL_KIND
from sensact.io.intervals import KIND as INTERVALS_KIND
from sensact.io.lidar2d_folder import KIND as LIDAR2D_KIND
from sensact.io.logfolder import meta_kind

OpenedAny = OpenedLandmarkLog | OpenedLidar2DLog | OpenedCarLog | OpenedIntervalsLog | OpenedInertialLog
CalibratedAny = Calibration | Lidar2DCalibration | CarCalibration | IntervalsCalibration | InertialCalibration

# `learn em`'s options beyond the log and --out that a kind may or may not take
EM_OPTIONS = frozenset({"--start-from", "--halves", "--preset", "--set", "--config", "--uncertainty"})


@dataclass(frozen=True)
class LogKind:
    name: str
    family: str  # the logs its learner reads, as a refusal names them ("EM's landmark logs")
    what: str  # what such a log is, as a refusal names it
    recognizes: Callable[[Path], bool]
    open: Callable[[Path, int], Any]  # (path, bins) -> the opened log
    opened: type  # what ``open`` returns
    learn: Callable[..., Any]  # (opened, preset, config, *, sets, start_from, events) -> its calibration
    calibrated: type  # what ``learn`` returns
    save: Callable[..., Saved]  # (calibration, out, report) -> what `learn em --out OUT` writes
    options: frozenset[str]  # the `learn em` options it takes
    # `evaluate log`'s scoring of a model on such a log: (opened log, model doc, model path) -> JSON; None where
    # the command's own (EM's landmark scoring) does it
    evaluate: Callable[[Any, Any, Path], Any] | None = None
    # `learn em --halves`: (calibration, progress) -> the halves' JSON; None where the command's own (EM's) does it
    halves: Callable[[Any, Any], Any] | None = None


KINDS: list[LogKind] = []


def register(kind: LogKind) -> LogKind:
    KINDS.append(kind)
    return kind


def kind_of(path: str | Path) -> LogKind:
    """The kind of log ``path`` is: the first registered kind that recognizes it."""
    p = Path(path)
    for kind in KINDS:
        if kind.recognizes(p):
            return kind
    raise LogFormatError(
        "not a log sensact reads.",
        file=p,
        fix="give " + "; or ".join(k.what for k in KINDS) + ".",
    )


def _kind_opened(log: Any) -> LogKind:
    """The kind whose opener returns ``log``'s type (kinds that share an opened type share their learner)."""
    for kind in KINDS:
        if isinstance(log, kind.opened):
            return kind
    raise TypeError(f"{type(log).__name__} is not a log that `open_log` opens")


def save_calibration(cal: Any, out: str | Path, *, report: bool = True) -> Saved:
    """``cal`` written at ``out`` as `learn em --out OUT` writes it, by its kind's writer."""
    for kind in KINDS:
        if isinstance(cal, kind.calibrated):
            return kind.save(cal, Path(out), report)
    raise TypeError(f"{type(cal).__name__} is not a calibration that `calibrate` returns")


def halves_of(cal: Any) -> Callable[[Any, Any], Any] | None:
    """The ``--halves`` of the kind whose learner returned ``cal``; None where it is EM's own."""
    for kind in KINDS:
        if isinstance(cal, kind.calibrated):
            return kind.halves
    return None


def open_log(path: str | Path, *, bins: int = 21) -> OpenedAny:
    """``path`` opened by its kind's opener (``bins``: the actions a 1-D track's continuous commands are
    binned into)."""
    return kind_of(path).open(Path(path), bins)


def refuse_options(log: Any, given: Mapping[str, Any]) -> None:
    """One line for the first option in ``given`` (name -> value; None, False and empty are not given)
    that the kind of ``log`` (an opened log, or a path) does not take, before any work."""
    kind = kind_of(log) if isinstance(log, str | Path) else _kind_opened(log)
    path = log if isinstance(log, str | Path) else log.path
    for option, value in given.items():
        if value is None or value is False or (isinstance(value, tuple | list) and not value) or option in kind.options:
            continue
        takes = dict.fromkeys(k.family for k in KINDS if option in k.options)
        raise ConfigError(
            f"{option} is for {' and '.join(takes) or 'no logs'}; {path} is {kind.what}, learned without it.",
            field=option,
            fix=f"run `sensact learn em {path}` without {option}.",
        )


def learner(log: Any) -> Callable[..., Any]:
    """The learner of the kind that opened ``log`` (``refuse_options`` says which options it takes)."""
    return _kind_opened(log).learn


def refuse_other_kinds(path: str | Path, command: str) -> None:
    """``path`` must be a landmark log for ``command`` (it reads no other kind): one line naming the command
    that reads this one otherwise, before anything is read."""
    kind = kind_of(path)
    if not issubclass(kind.opened, OpenedLandmarkLog):
        raise LogFormatError(
            f"{command} reads landmark logs (EM's), and this is {kind.what}.",
            file=Path(path),
            fix=f"learn it with `sensact learn em {path}`.",
        )


def landmark_log(path: str | Path, command: str, *, bins: int = 21) -> OpenedLandmarkLog:
    """``path`` opened through the door, for a command that reads landmark logs only (``refuse_other_kinds``)."""
    refuse_other_kinds(path, command)
    return open_log(path, bins=bins)


def _is_lidar2d_folder(path: Path) -> bool:
    return meta_kind(path) == LIDAR2D_KIND


def _is_csv(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() == ".csv"


register(
    LogKind(
        "lidar2d",
        "wheels-and-2-D-lidar logs",
        "a wheels-and-2-D-lidar log folder (meta.json, scans.csv and wheels.csv, odom.csv or cmd_vel.csv)",
        _is_lidar2d_folder,
        lambda path, bins: open_lidar2d_log(path),
        OpenedLidar2DLog,
        calibrate_opened_lidar2d,
        Lidar2DCalibration,
        save_lidar2d,
        frozenset(),
    )
)
register(
    LogKind(
        "car",
        "car logs",
        "a car's log folder (meta.json, scans.csv, vesc.csv and servo.csv, as `convert bag` writes)",
        lambda path: meta_kind(path) == CAR_KIND,
        lambda path, bins: open_car_log(path),
        OpenedCarLog,
        calibrate_opened_car,
        CarCalibration,
        save_car,
        frozenset(),
    )
)
register(
    LogKind(
        "intervals",
        "scan-matched intervals",
        "a folder of scan-matched intervals (meta.json and intervals.csv, as `convert intervals` writes)",
        lambda path: meta_kind(path) == INTERVALS_KIND,
        lambda path, bins: open_intervals_log(path),
        OpenedIntervalsLog,
        calibrate_opened_intervals,
        IntervalsCalibration,
        save_intervals,
        frozenset(),
    )
)
register(
    LogKind(
        "imu_gnss",
        "wheel-odometry-IMU-GNSS logs",
        "an odometry-IMU-GNSS log folder (meta.json, odometry.csv, imu.csv and gnss.csv)",
        lambda path: meta_kind(path) == INERTIAL_KIND,
        lambda path, bins: open_inertial_log(path),
        OpenedInertialLog,
        calibrate_opened_inertial,
        InertialCalibration,
        save_inertial,
        frozenset({"--halves"}),
        lambda opened, doc, model: evaluate_inertial(opened.data, doc, model),
        halves_inertial,
    )
)
register(
    LogKind(
        "turtlebot_csv",
        "EM's landmark logs",
        "a Turtlebot CSV (time, velocity_command and the sonar and IR columns)",
        _is_csv,
        lambda path, bins: open_turtlebot_csv(path, bins=bins),
        OpenedLandmarkLog,
        calibrate_em,
        Calibration,
        save_em_calibration,
        EM_OPTIONS,
    )
)
register(
    LogKind(
        "landmarks",
        "EM's landmark logs",
        "a landmark log folder (meta.json, actions.csv and observations.csv, as `convert` and `simulate` write)",
        lambda path: not path.is_file(),
        lambda path, bins: open_landmark_folder(path, bins=bins),
        OpenedLandmarkLog,
        calibrate_em,
        Calibration,
        save_em_calibration,
        EM_OPTIONS,
    )
)
