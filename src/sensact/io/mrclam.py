"""The UTIAS MRCLAM dataset (Leung et al., IJRR 2011) as an EM log.

One robot's files become a ``LandmarkLog``:

* ``RobotN_Odometry.dat`` (time, commanded v [m/s], omega [rad/s], ~67-100 Hz) is resampled onto a fixed
  step (default 1/30 s, the thesis's frame rate) by a zero-order hold: each step takes the last command
  issued at or before it. Commands become ``v_mm_s`` and ``omega_rad_s``.
* ``RobotN_Measurement.dat`` (time, barcode, range [m], bearing [rad]) keeps the sightings of landmarks
  only; barcodes map to subjects through ``Barcodes.dat``, and subjects 1-5 are the other robots.
  Each sighting goes to the nearest step. Range becomes the ``range_mm`` reading.
* ``Landmark_Groundtruth.dat`` gives the landmark map (mm).
* ``RobotN_Groundtruth.dat`` (Vicon) is returned separately, on the step grid, for evaluation only.

Frames: MRCLAM's heading is counterclockwise from world +x and the robot drives along its own +x.
sensact's planar frame (sec. 2.5.1) has ``theta = 0`` facing world +y and the robot's forward axis is
its +y, so ``theta_sensact = theta_mrclam - pi/2``; positions and bearings are unchanged.
Lines starting with ``#`` are headers; line endings may be CRLF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.resample import HEADING_OFFSET_RAD, held_on_grid, nearest_steps, pose_truth_on_grid
from sensact.io.unit_checks import refuse_degrees_as_radians
from sensact.logs.landmark_log import LandmarkLog

ROBOT_SUBJECTS = range(1, 6)
COMMAND_NAMES = ("v_mm_s", "omega_rad_s")


@dataclass(frozen=True, eq=False)
class MrclamLog:
    data: LandmarkLog
    t0_s: float  # the dataset's clock at step 0
    groundtruth: dict[str, np.ndarray]  # x_mm, y_mm, theta_rad (sensact frame) and valid, on the step grid
    summary: dict[str, int]  # rows kept and dropped, by reason

    def truth_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Vicon's ``(T, 3)`` poses on the step grid and where they are valid."""
        gt = self.groundtruth
        return np.column_stack([gt["x_mm"], gt["y_mm"], gt["theta_rad"]]), gt["valid"] > 0

    def summary_line(self) -> str:
        s = self.summary
        return (
            f"robot {s['robot']}: {s['odometry_rows']} odometry rows -> {self.data.n_steps} steps of "
            f"{self.data.dt_s:.4g} s; kept {s['kept']} landmark sightings of {s['measurement_rows']}; dropped "
            f"{s['dropped_robot']} of other robots, {s['dropped_unknown_barcode']} with unknown barcodes, "
            f"{s['dropped_outside_time']} outside the odometry span"
        )


MAX_SPEED_M_S, MAX_TURN_RAD_S = 50.0, 50.0  # beyond any ground robot's (MRCLAM's iRobot Creates: 0.3 m/s)


def _table(path: Path, columns: int) -> np.ndarray:
    if not path.is_file():
        raise LogFormatError(
            "file not found.", file=path, fix="give the dataset folder (e.g. .../MRCLAM_Dataset6) and a robot 1-5."
        )
    try:
        text_lines = path.read_text(encoding="utf-8").splitlines()
    except UnicodeDecodeError:
        raise LogFormatError(
            "not a text file (it is not UTF-8).", file=path, fix="give the dataset's own file."
        ) from None
    rows = []
    for i, line in enumerate(text_lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split()
        try:
            values = [float(x) for x in parts]
        except ValueError:
            raise LogFormatError(
                f"line {i}: {text[:40]!r} is not numeric.", file=path, fix="only '#' lines may hold text."
            ) from None
        if not all(math.isfinite(v) for v in values):
            raise LogFormatError(
                f"line {i}: {text[:40]!r} holds a number that is not finite.",
                file=path,
                fix="every value of an MRCLAM file is a finite number.",
            )
        if len(values) != columns:
            raise LogFormatError(
                f"line {i}: {len(values)} columns, expected {columns}.",
                file=path,
                fix="each data line of this file has exactly that many whitespace-separated numbers.",
            )
        rows.append(values)
    if not rows:
        raise LogFormatError("no data lines.", file=path, fix="check that this is an unmodified MRCLAM file.")
    return np.asarray(rows, dtype=float)


def read_mrclam(folder: str | Path, robot: int, *, dt_s: float = 1.0 / 30.0) -> MrclamLog:
    """One MRCLAM robot as a planar, continuous-command ``LandmarkLog`` (see the module docstring)."""
    folder = Path(folder)
    if robot not in ROBOT_SUBJECTS:
        raise LogFormatError(f"robot {robot} does not exist.", file=folder, field="robot", fix="choose 1 to 5.")
    if not dt_s > 0:
        raise LogFormatError(f"dt_s = {dt_s} is not a step.", file=folder, field="dt_s", fix="give dt_s > 0.")
    odo = _table(folder / f"Robot{robot}_Odometry.dat", 3)
    meas = _table(folder / f"Robot{robot}_Measurement.dat", 4)
    truth = _table(folder / f"Robot{robot}_Groundtruth.dat", 4)
    barcodes = _table(folder / "Barcodes.dat", 2)
    marks = _table(folder / "Landmark_Groundtruth.dat", 5)
    bad = np.flatnonzero(meas[:, 2] <= 0)
    if bad.size:
        raise LogFormatError(
            f"row {bad[0] + 1} has range {meas[bad[0], 2]:g} m; a range is positive.",
            file=folder / f"Robot{robot}_Measurement.dat",
            field="range",
            fix="drop the row, or give the dataset's own file.",
        )
    odo_file = folder / f"Robot{robot}_Odometry.dat"
    for col, (name, limit, unit) in enumerate((("v", MAX_SPEED_M_S, "m/s"), ("omega", MAX_TURN_RAD_S, "rad/s")), 1):
        over = np.flatnonzero(~(np.abs(odo[:, col]) <= limit))
        if over.size:
            raise LogFormatError(
                f"row {over[0] + 1}'s {name} is {odo[over[0], col]:g} {unit}: beyond any ground robot's ({limit:g}).",
                file=odo_file,
                field=name,
                fix="give the dataset's own file (v in m/s, omega in rad/s).",
            )
    refuse_degrees_as_radians(
        folder / f"Robot{robot}_Measurement.dat", meas[:, 3], "bearing", "give the dataset's bearings, in radians."
    )
    odo = odo[np.argsort(odo[:, 0], kind="stable")]
    truth = truth[np.argsort(truth[:, 0], kind="stable")]  # interpolated below, which needs its times in order
    t0, held = held_on_grid(odo[:, 0], odo[:, 1:3], dt_s, str(folder / f"Robot{robot}_Odometry.dat"))
    commands = np.column_stack([held[:, 0] * 1000.0, held[:, 1]])
    T = len(commands)

    subject_of = {int(b): int(s) for s, b in barcodes}
    landmark_ids = [int(s) for s in marks[:, 0]]
    row_of = {s: j for j, s in enumerate(landmark_ids)}
    subjects = np.array([subject_of.get(int(b), -1) for b in meas[:, 1]])
    is_robot = np.isin(subjects, list(ROBOT_SUBJECTS))
    is_landmark = np.isin(subjects, landmark_ids)
    step, inside = nearest_steps(meas[:, 0], t0, dt_s, T)
    keep = is_landmark & inside
    order = np.argsort(step[keep], kind="stable")
    sel = np.flatnonzero(keep)[order]
    data = LandmarkLog(
        "planar",
        dt_s,
        np.full(T, -1, dtype=np.int64),
        np.zeros((0, 2)),
        COMMAND_NAMES,
        step[sel],
        np.array([row_of[s] for s in subjects[sel]], dtype=np.int64),
        meas[sel, 2] * 1000.0,
        meas[sel, 3],
        marks[:, 1:3] * 1000.0,
        tuple(f"subject{s}" for s in landmark_ids),
        f"{folder.name}/Robot{robot}",
        ("range_mm",),
        commands,
    )
    # Vicon on the step grid, valid where its samples around a step are under 0.1 s apart
    gt = pose_truth_on_grid(
        t0 + np.arange(T) * dt_s,
        truth[:, 0],
        truth[:, 1],
        truth[:, 2],
        truth[:, 3],
        max_gap_s=0.1,
        position_scale=1000.0,
        heading_offset_rad=HEADING_OFFSET_RAD,
    )
    summary = {
        "robot": robot,
        "odometry_rows": len(odo),
        "measurement_rows": len(meas),
        "kept": int(keep.sum()),
        "dropped_robot": int((is_robot & inside).sum()),
        "dropped_unknown_barcode": int((~is_robot & ~is_landmark & inside).sum()),
        "dropped_outside_time": int((~inside).sum()),
    }
    return MrclamLog(data, float(t0), gt, summary)
