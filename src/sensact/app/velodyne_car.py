"""``sensact simulate car`` and ``sensact learn car`` as functions (chapter 5): a simulated drive written as a
log folder, Algorithm 3 (or the laser angles alone) on a car log, and a learned drive scored against the
simulator's truth. ``experiments/velodyne_car.py`` runs the thesis's experiment with them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sensact.errors import ConfigError
from sensact.evaluate.velodyne_car import laser_angle_error, table_5_1, truth_motion
from sensact.io.velodyne_calibration import read_calibration
from sensact.io.velodyne_car_folder import CarLog, write_car_log
from sensact.learn.velodyne_car_dynamics import (
    CarLearningConfig,
    CarLearningResult,
    LaserAnglesResult,
    learn_car,
    learn_laser_angles,
)
from sensact.models.laser_intrinsics import LaserIntrinsics
from sensact.models.spinning_lidar import OUSTER_BEAMS, UNITS
from sensact.progress import Progress
from sensact.records import JsonObject
from sensact.sim.velodyne_car import (
    CarConfig,
    CarRun,
    log_tables,
    nominal_intrinsics,
    nominal_unit_intrinsics,
    scan_chunks,
    simulate_drive,
)

# each model's calibration in the shared data: the geometry of a real unit
SHARED_CALIBRATIONS = {
    "HDL-64E": "calibration/64e_utexas.yaml",
    "HDL-32E": "calibration/32db.yaml",
    "VLP-16": "calibration/VLP16db.yaml",
    "OS-1": "ouster_example.json",
}


def default_calibration_path(model: str = "HDL-64E") -> Path | None:
    from sensact.app.logs import data_root

    name = SHARED_CALIBRATIONS.get(model)
    return None if name is None else data_root() / "velodyne" / name


def true_intrinsics(cfg: CarConfig) -> LaserIntrinsics:
    """The simulated unit's true geometry: ``calibration_yaml``, else the model's real unit in the shared
    data (the UT Austin HDL-64E is the thesis's), else its nominal geometry (``nominal_unit_intrinsics``)."""
    if cfg.calibration_yaml:
        intr = read_calibration(cfg.calibration_yaml)
        unit = cfg.unit
        if intr.n_lasers != unit.lasers and (unit.velodyne or intr.n_lasers not in OUSTER_BEAMS):
            fits = [name for name, u in UNITS.items() if u.lasers == intr.n_lasers and u.velodyne]
            raise ConfigError(
                f"{cfg.calibration_yaml} gives {intr.n_lasers} lasers, but lidar is {cfg.lidar}, of {unit.lasers}.",
                field="calibration_yaml",
                fix="set lidar to the unit the file is of ("
                + " or ".join([*fits, "OS-1 for its metadata JSON"])
                + ").",
            )
        return intr
    path = default_calibration_path(cfg.lidar)
    if path is not None and path.is_file():
        return read_calibration(path)
    return nominal_intrinsics() if cfg.lidar == "HDL-64E" else nominal_unit_intrinsics(cfg.unit)


def simulate_car_log(cfg: CarConfig, folder: str | Path, progress: Progress | None = None) -> CarRun:
    """Simulate the drive and write its log folder (pcap and all)."""
    intr = true_intrinsics(cfg)
    run = simulate_drive(cfg, intr)
    write_car_log(folder, log_tables(run), scan_chunks(run, progress), intr)
    return run


def learn_from_log(
    log: CarLog, config: CarLearningConfig | None = None, progress: Progress | None = None
) -> CarLearningResult:
    """Algorithm 3 on a car log read by ``sensact.io.velodyne_car_folder.read_car_log``."""
    if log.actions is None or log.action_times_s is None:
        raise ValueError("Algorithm 3 needs the log's actions; learn_angles_from_log needs none")
    fields = (log.rotation_rad, log.distance_m, log.vertical_rad, log.firing_hz, log.omega_rad_s)
    return learn_car(*fields, log.action_times_s, log.actions, config, progress, log.delay_s)


def learn_angles_from_log(
    log: CarLog, config: CarLearningConfig | None = None, progress: Progress | None = None
) -> LaserAnglesResult:
    """The laser angles and C from a car log's scans alone (no actions needed)."""
    fields = (log.rotation_rad, log.distance_m, log.vertical_rad, log.firing_hz, log.omega_rad_s)
    return learn_laser_angles(*fields, config, progress, log.delay_s)


def evaluate_run(run_truth: JsonObject, log_truth: dict[str, np.ndarray], res: CarLearningResult, dt_s: float):
    scores = laser_angle_error(res.laser_angles_rad, np.asarray(run_truth["laser_angles_rad"]))
    poses = np.column_stack([log_truth["x_m"], log_truth["y_m"], log_truth["theta_rad"]])
    v, w, a = truth_motion(log_truth["t_s"], poses, res.interval_times_s, dt_s)
    scores.update(table_5_1(res.model, res.actions, v, w, a, dt_s, res.speed_m_s[0]))
    return scores, (v, w, a)
