"""``sensact simulate``: write a simulated log folder with its ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from sensact.app.settings import layered_config
from sensact.cli.base import ConfigOpt, SetOpt, console, friendly, progress_bar, simulate_app

BagOpt = Annotated[
    Path | None,
    typer.Option(
        help="Also write the run as a ROS bag here: a .bag path is ROS 1, else a ROS 2 bag folder (--bag-format).",
        show_default=False,
    ),
]
BagFormatOpt = Annotated[str, typer.Option(help="A ROS 2 bag's storage: mcap or sqlite3.")]


@simulate_app.command("track1d")
@friendly
def simulate_track1d(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 150).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-3 Aibo walking toward and away from a beacon (sec. 3.3)."""
    from sensact.io.logfolder import write_log_folder
    from sensact.sim.track1d import Track1DConfig, log_tables, simulate_track

    cfg = layered_config(Track1DConfig, config, set_, seconds=seconds, seed=seed)
    run = simulate_track(cfg)
    write_log_folder(out, **log_tables(run))
    n_obs = int((run.heights_px == run.heights_px).sum())
    console.print(
        f"wrote {out}: {len(run.times_s)} steps, {n_obs} observations, "
        f"distance {run.distance_mm.min():.0f}-{run.distance_mm.max():.0f} mm (seed {cfg.seed})"
    )


@simulate_app.command("field2d")
@friendly
def simulate_field2d(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 900).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    setting: Annotated[
        str, typer.Option(help="simulation (0.05 s steps, sec. 4.4.2) or real_robot (30 Hz, sec. 4.4.1).")
    ] = "simulation",
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-4 Aibo walking among four beacons with 40 actions (secs. 4.4.1-4.4.2)."""
    from sensact.errors import ConfigError
    from sensact.io.logfolder import write_log_folder
    from sensact.sim.field2d import Field2DConfig, log_tables, simulate_field

    if setting not in ("simulation", "real_robot"):
        raise ConfigError(f"unknown setting {setting!r}.", field="--setting", fix="use simulation or real_robot.")
    cfg = layered_config(Field2DConfig, config, set_, base=Field2DConfig.preset(setting), seconds=seconds, seed=seed)
    run = simulate_field(cfg)
    write_log_folder(out, **log_tables(run))
    console.print(
        f"wrote {out}: {len(run.times_s)} steps of {cfg.dt_s:.4g} s, {run.obs_step.size} observations "
        f"({int(run.obs_false.sum())} false positives), 40 actions (seed {cfg.seed})"
    )


@simulate_app.command("car")
@friendly
def simulate_car(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write (velodyne.pcap, actions.csv, ...).")],
    seconds: Annotated[float | None, typer.Option(help="Length of the drive (default 200).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
) -> None:
    """Simulate the chapter-5 car with a spinning lidar driving through a town (secs. 2.5.2, 5.4): the thesis's
    Velodyne HDL-64E, or --set lidar=HDL-32E, VLP-32C, VLP-16, "Puck Hi-Res" or OS-1."""
    from sensact.app.velodyne_car import simulate_car_log
    from sensact.sim.velodyne_car import CarConfig, log_summary

    cfg = layered_config(CarConfig, config, set_, seconds=seconds, seed=seed)
    with progress_bar() as progress:
        run = simulate_car_log(cfg, out, progress)
    s = log_summary(run)
    console.print(
        f"wrote {out}: {s['seconds']:.0f} s drive, top speed {s['max_speed_m_s']:.2f} m/s, turned "
        f"{s['turned_deg']:.0f}°, {s['obstacles']} obstacles; velodyne.pcap holds "
        f"{int(cfg.seconds * cfg.firing_rate_hz) // cfg.unit.firings_per_packet} {cfg.lidar} packets (seed {cfg.seed})"
    )


@simulate_app.command("diffdrive")
@friendly
def simulate_diffdrive_cmd(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write (with groundtruth.csv and em_config.yaml).")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 900).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    bag: Annotated[
        Path | None,
        typer.Option(
            help="Also write the run as a ROS bag here, with map.csv beside it: a .bag path is ROS 1, else a ROS "
            "2 bag folder (--bag-format).",
            show_default=False,
        ),
    ] = None,
    bag_format: BagFormatOpt = "mcap",
    no_map: Annotated[
        bool,
        typer.Option("--no-map", help="Leave the landmarks' positions out of the log: EM learns them (scored only)."),
    ] = False,
) -> None:
    """Simulate a differential drive on continuous commands among landmarks, as in the MRCLAM logs.

    Writes the EM settings of the MRCLAM results beside it (em_config.yaml); `sensact learn em OUT
    --config OUT/em_config.yaml` then scores the learned model against the true poses and the
    simulated model. `--set wheel_axle_mm=235` logs the wheel speeds (left_mm_s, right_mm_s) instead
    of v and omega, as a robot driven wheel by wheel is logged. `--set sidestep_mm_s=60` makes a
    robot that can side-step, as a legged one, logged as (v_mm_s, v_left_mm_s, omega_rad_s), with
    settings in which every velocity, sideways too, is affine in every command. `--set sensor=radio`
    reads ranges alone, in every direction (UWB anchors, sonar beacons): no bearings in the log, and
    settings without them that start EM where the robot was put (start_pose). `--no-map` leaves the
    landmarks' positions out (EM learns them; the true ones stay in meta.json's survey, for scoring).
    `--set sensor=lidar2d` is another robot: wheel encoders and a 2-D lidar in a furnished room, a TurtleBot's
    /joint_states, /odom, /cmd_vel and /scan with its URDF a few centimetres and degrees off (docs/lidar2d.md)."""
    if _wants_lidar2d(set_, config):
        if no_map:
            from sensact.errors import ConfigError

            raise ConfigError(
                "--no-map is for a robot among landmarks; a 2-D lidar needs no map.", field="--no-map", fix="drop it."
            )
        _simulate_lidar2d(out, seconds, seed, set_, config, bag, bag_format)
        return
    from sensact.cli.convert import config_header
    from sensact.io.atomic import write_text
    from sensact.io.landmark_folder import write_landmark_log
    from sensact.presets import settings_yaml, simulator_settings
    from sensact.sim.diffdrive import DiffDriveConfig, simulate_diffdrive

    cfg = layered_config(DiffDriveConfig, config, set_, seconds=seconds, seed=seed)
    fmt = _bag_format(bag, bag_format) if bag is not None else None
    run = simulate_diffdrive(cfg)
    log, survey = run.log(), None
    if no_map:  # the landmarks unknown to the learner; their true positions kept to score the learned map
        import numpy as np

        survey, log = log.landmarks_xy, log.with_landmarks(np.full_like(log.landmarks_xy, np.nan))
    write_landmark_log(out, log, groundtruth=run.groundtruth(), meta_extra={"truth": cfg.truth()}, survey_xy=survey)
    em_cfg = out / "em_config.yaml"
    start = (
        () if cfg.reads_bearing else ("thesis.start_prior_mean", "thesis.start_prior_sd")
    )  # a radio's: where the robot was put
    header = config_header(log.command_names, range_only=not cfg.reads_bearing)
    preset = "differential_drive_camera" if cfg.reads_bearing else "range_only_anchors"
    write_text(em_cfg, settings_yaml(preset, simulator_settings(cfg), log, header, start))
    console.print(
        f"wrote {out}: {len(run.commands)} steps of {cfg.dt_s:.4g} s, {run.obs_step.size} sightings of "
        f"{len(cfg.landmarks_xy_mm)} landmarks ({int(run.obs_misread.sum())} misread"
        + ("" if cfg.reads_bearing else "; ranges alone, no bearings")
        + "), commands "
        + f"{', '.join(log.command_names)}, command delay {cfg.delay_s:g} s and lag {cfg.lag_s:g} s (seed {cfg.seed}); "
        f"learn with `sensact learn em {out}` (settings: {em_cfg})"
    )
    if bag is not None:
        _write_bag(run, bag, fmt)


def _wants_lidar2d(set_: list[str] | None, config: Path | None) -> bool:
    from sensact.config import load_yaml_mapping, parse_overrides

    given = parse_overrides(set_ or [])
    if "sensor" in given:
        return given["sensor"] == "lidar2d"
    return config is not None and load_yaml_mapping(config).get("sensor") == "lidar2d"


def _simulate_lidar2d(
    out: Path,
    seconds: float | None,
    seed: int | None,
    set_: list[str] | None,
    config: Path | None,
    bag: Path | None,
    bag_format: str,
) -> None:
    from sensact.io.lidar2d_folder import write_lidar2d_log
    from sensact.sim.lidar2d import Lidar2DConfig, simulate_lidar2d

    cfg = layered_config(Lidar2DConfig, config, set_, seconds=seconds, seed=seed)
    fmt = _bag_format(bag, bag_format) if bag is not None else None
    run = simulate_lidar2d(cfg)
    write_lidar2d_log(out, run.log(str(out)), run.tables())
    console.print(
        f"wrote {out}: {run.scan_t.size} scans of {cfg.beams} beams, wheels at {cfg.joint_hz:g} Hz, /odom and /cmd_vel "
        f"(seed {cfg.seed}); learn with `sensact learn em {out}`"
    )
    if bag is not None:
        from sensact.io.rosbag_write import write_lidar_bag

        path = write_lidar_bag(bag, fmt, run)
        console.print(f"wrote {path} ({fmt}); convert with `sensact convert bag {path}`")


def _bag_format(bag: Path, bag_format: str) -> str:
    """The bag's format, checked before anything is simulated: ros1 for a .bag path, else ``bag_format``."""
    from sensact.errors import ConfigError

    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise ConfigError(
            "writing a ROS bag needs the rosbags package.", field="--bag", fix="pip install 'sensact[ros]'"
        ) from None
    fmt = "ros1" if bag.suffix == ".bag" else bag_format
    if fmt not in ("mcap", "sqlite3", "ros1"):
        raise ConfigError(
            f"--bag-format {bag_format} is not a ROS 2 storage.", field="--bag-format", fix="mcap or sqlite3"
        )
    if bag.exists():
        raise ConfigError(f"{bag} is there already.", field="--bag", fix="give a new path (a bag is never overwritten)")
    return fmt


def _write_bag(run, bag: Path, fmt: str) -> None:
    """The run as a ROS robot records it (io.rosbag_write.recording_of), and its map beside it."""
    from sensact.errors import ConfigError
    from sensact.io.rosbag_write import recording_of, write_map_csv, write_robot_bag

    try:
        rec = recording_of(run)
    except ValueError as err:
        raise ConfigError(f"cannot write this robot as a bag: {err}.", field="--bag", fix="drop --bag") from None
    path = write_robot_bag(bag, fmt, rec)
    grid = write_map_csv(bag.parent / "map.csv", rec.map_xy_m)
    console.print(
        f"wrote {path} ({fmt}) and its map {grid}; convert with `sensact convert bag {path} --landmarks {grid}`"
    )


@simulate_app.command("ackermann")
@friendly
def simulate_ackermann(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 300).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    bag: BagOpt = None,
    bag_format: BagFormatOpt = "mcap",
) -> None:
    """Simulate a 1/10-scale car-like robot (F1TENTH, MuSHR) lapping a corridor track with a 270-degree lidar
    (docs/ackermann.md).

    Its vesc.yaml is a few per cent off and its steering's zero two degrees off, the wheels follow the servo 80 ms
    late and the lidar sits a few millimetres from where the URDF says. `--set scale=3` makes the track three times
    larger (gentle curves only: the wheelbase cannot be told from the steering gain), `--set
    speed_to_erpm_gain=-4614` reverses the motor. The bag holds /scan, /sensors/core, /sensors/servo_position_command,
    /drive, /odom and /tf_static; `sensact learn em OUT` scores what it learns against the truth in meta.json."""
    from sensact.io.car_folder import write_car_log
    from sensact.sim.car import CarConfig, simulate_car

    cfg = layered_config(CarConfig, config, set_, seconds=seconds, seed=seed)
    fmt = _bag_format(bag, bag_format) if bag is not None else None
    run = simulate_car(cfg)
    write_car_log(out, run.log(str(out)))
    console.print(
        f"wrote {out}: {run.scan_t.size} scans of {cfg.beams} beams, {run.vesc_t.size} VESC reports and "
        f"{run.servo_t.size} servo commands over {cfg.seconds:g} s (seed {cfg.seed}); "
        f"learn with `sensact learn em {out}`"
    )
    if bag is not None:
        from sensact.io.rosbag_write import write_car_bag

        path = write_car_bag(bag, fmt, run)
        console.print(f"wrote {path} ({fmt}); convert with `sensact convert bag {path} --out DIR`")


@simulate_app.command("outdoor")
@friendly
def simulate_outdoor(
    out: Annotated[Path, typer.Option("--out", help="Log folder to write.")],
    seconds: Annotated[float | None, typer.Option(help="Length of the log (default 600).")] = None,
    seed: Annotated[int | None, typer.Option(help="Random seed (default 0).")] = None,
    set_: SetOpt = None,
    config: ConfigOpt = None,
    bag: BagOpt = None,
    bag_format: BagFormatOpt = "mcap",
) -> None:
    """Simulate a skid-steer robot driving over a field with wheel odometry, an IMU and GNSS (docs/inertial.md).

    A Husky's log: /odom's gains off, a gyro with a wandering bias, a scale and a clock offset, mounted in an
    odd orientation, and a GNSS antenna on a lever arm with noise, outliers and a covariance it misreports.
    `--set gnss_hz=0` leaves the receiver out, `--set gnss_sigma_m=1.0` makes it metre-grade, `--set
    tf_imu=none` (or wrong) leaves /tf_static's IMU out (or wrong), `--set turns=left` never turns right,
    `--set accel=no_gravity` (or g) publishes accelerations as some drivers do, `--set imu_orientation=true`
    adds the IMU's orientation. `sensact learn em OUT` then scores what it learns against the truth in meta.json."""
    from sensact.io.inertial_folder import write_inertial_log
    from sensact.sim.inertial import InertialConfig, simulate_inertial

    cfg = layered_config(InertialConfig, config, set_, seconds=seconds, seed=seed)
    fmt = _bag_format(bag, bag_format) if bag is not None else None
    run = simulate_inertial(cfg)
    write_inertial_log(out, run.log(str(out)))
    log = run.log_
    console.print(
        f"wrote {out}: {log.odom_t.size} odometry rows, {log.imu_t.size} IMU readings, {log.gnss_t.size} GNSS fixes "
        f"over {cfg.seconds:g} s (seed {cfg.seed}); learn with `sensact learn em {out}`"
    )
    if bag is not None:
        from sensact.io.rosbag_write import write_inertial_bag

        path = write_inertial_bag(bag, fmt, run)
        console.print(f"wrote {path} ({fmt}); convert with `sensact convert bag {path} --out DIR`")
