"""``sensact export``: a learned model for a ROS stack (app/export.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from sensact.cli.base import ForceOpt, app, console, err_console, friendly
from sensact.errors import EXIT_FLAGGED


@app.command("export")
@friendly
def export_cmd(
    model: Annotated[Path, typer.Argument(help="A model.json from `sensact learn em` or `learn car`.")],
    format_: Annotated[
        str,
        typer.Option(
            "--format",
            help="robot-localization (YAML), tum (trajectory for evo), velodyne (YAML), landmarks (CSV), urdf "
            "(a xacro <robot> to include), for an odometry-IMU-GNSS model diff-drive-controller, navsat-transform "
            "and kalibr (YAML), and for a car model vesc (YAML).",
        ),
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="The file to write; by default beside the model: MODEL.tum, MODEL.robot_localization.yaml, "
            "MODEL.velodyne.yaml, MODEL.landmarks.csv or MODEL.urdf.xacro.",
            show_default=False,
        ),
    ] = None,
    truth_out: Annotated[
        Path | None,
        typer.Option(help="tum: where the truth's trajectory goes (default OUT_truth.tum, when the log has truth)."),
    ] = None,
    force: ForceOpt = False,
) -> None:
    """Write a learned model in SI units and REP 103 axes (x forward, y left; yaw 0 facing the map's +x).

    robot-localization: the process_noise_covariance (15x15, per second) from the learned Sigma_m as a ROS 2
    parameter file for robot_localization's ekf_filter_node (--params-file loads it), and beside it
    OUT.sensact.yaml with a command's twist covariance, the action model's gains and offsets and the
    sensor's mount. tum: EM's smoothed path (timestamp x y z qx qy qz qw, on
    the log's own clock) and the truth's beside it, so that `evo_ape tum OUT_truth.tum OUT` compares them.
    velodyne: a car model's learned laser angles as a ROS velodyne calibration. landmarks: a map EM learned
    (id,x_m,y_m in the map's frame, placed landmarks only), the file `convert csv --landmarks` reads, so
    that one robot's learned map serves the next robot's calibration. urdf: a wheels-and-2-D-lidar model's
    lidar joint (<origin xyz rpy>) and wheel radii and separation (or, learned from /odom or /cmd_vel,
    diff_drive_controller's two multipliers) as xacro properties in a <robot> to include, metres and radians;
    its robot-localization is the process noise from the drive's learned noise (docs/lidar2d.md).

    An odometry-IMU-GNSS model (docs/inertial.md): diff-drive-controller (the wheel multipliers and
    twist_covariance_diagonal), robot-localization (an ekf with odom0 and imu0 blocks, the process noise
    and rejection thresholds), navsat-transform (yaw_offset; only its sum with the declination is learned),
    urdf (the IMU's and the antenna's joints in a <robot>) and kalibr (imu.yaml, in-motion values).

    A car model (docs/ackermann.md): vesc (vesc.yaml's speed_to_erpm_gain, speed_to_erpm_offset,
    steering_angle_to_servo_gain, steering_angle_to_servo_offset and wheelbase, as the F1TENTH stack reads them)
    and urdf (the lidar's joint on base_link, the rear axle's middle).

    A model that was flagged when it was learned is exported all the same, with one warning line naming its
    flags, and the command exits 3."""
    from sensact.app.export import default_out, export_model

    done = export_model(model, format_, out or default_out(model, format_), truth_out, force=force)
    for note in done.notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    console.print("wrote " + ", ".join(str(p) for p in done.written), highlight=False)
    if format_ == "tum" and len(done.written) == 2:
        console.print(f"compare with evo: `evo_ape tum {done.written[1]} {done.written[0]}`", highlight=False)
    if done.flags:  # written, as asked; but the model's doubt goes with it
        err_console.print(
            f"[bold yellow]warning:[/] {model} was flagged when it was learned ({', '.join(done.flags)}): what was "
            "exported is as doubtful; its health in the model says why.",
            highlight=False,
            soft_wrap=True,
        )
        raise typer.Exit(EXIT_FLAGGED)
