"""``sensact convert bag``: a ROS 1 or ROS 2 bag to a log folder, through the timed CSVs of ``convert csv``
(a robot among landmarks) or ``convert track`` (a 1-D robot with Range sensors)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

import typer

from sensact.cli.base import console, convert_app, friendly
from sensact.cli.convert import convert_csv, convert_track

TABLES = "bag_tables"  # the CSVs read from the bag, kept in the log folder to check by eye


def _reads_back(out: Path) -> None:
    """What convert wrote is what `learn em` reads: a folder its own reader would refuse is refused here, with
    the reader's reason, and nothing is left behind (the caller's ``nothing_half_written``)."""
    from sensact.app import open_log
    from sensact.errors import LogFormatError

    try:
        open_log(out)
    except LogFormatError as exc:
        raise LogFormatError(
            f"the log this bag converts to would not be read: {exc.problem}",
            file=exc.file,
            field=exc.field,
            fix=exc.fix,
        ) from None


def _mapping(path: Path | None):
    """The roles a YAML mapping file names (``commands``, ``readings``, ``sightings``, ``truth``)."""
    from sensact.config import safe_yaml
    from sensact.errors import LogFormatError
    from sensact.io.rosbag import Roles

    if path is None:
        return {}
    import yaml

    try:
        doc = safe_yaml(path.read_text(encoding="utf-8"), path, LogFormatError)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise LogFormatError(f"not a readable YAML mapping ({type(exc).__name__}).", file=path, fix="--help") from None
    known = set(Roles.__dataclass_fields__)
    if not isinstance(doc, dict) or not set(doc) <= known:
        raise LogFormatError(
            f"a mapping holds only {', '.join(sorted(known))}, a topic each (readings: a list).",
            file=path,
            fix="write e.g. `commands: /cmd_vel` and `sightings: /tf`, a line per role.",
        )
    out = {k: v for k, v in doc.items() if v is not None}
    if "readings" in out:
        r = out["readings"]
        out["readings"] = tuple(r) if isinstance(r, list) else (r,)
    for role, topic in out.items():  # a topic is a name: a nested list or a map is not one
        topics = topic if role == "readings" and isinstance(topic, tuple) else (topic,)
        if not topics or not all(isinstance(t, str) and t for t in topics):
            raise LogFormatError(
                f"{doc[role]!r} is not a topic's name" + (" or a list of them." if role == "readings" else "."),
                file=path,
                field=role,
                fix=f"write `{role}: /topic_name`" + (" or `readings: [/sonar, /ir]`." if role == "readings" else "."),
            )
    return out


@convert_app.command("bag")
@friendly
def convert_bag(
    bag: Annotated[Path, typer.Argument(help="A ROS 1 .bag, or a ROS 2 bag folder (sqlite3 or MCAP) or its file.")],
    out: Annotated[Path, typer.Option("--out", help="The log folder to write.")] = Path("robot_log"),
    landmarks: Annotated[
        Path | None,
        typer.Option(
            help="The map, id,x_m,y_m (a tag's id is its number), for tag sightings; optional: EM learns the "
            "positions it does not give."
        ),
    ] = None,
    survey: Annotated[
        Path | None, typer.Option(help="For scoring a learned map only: id,x_m,y_m, as --landmarks.")
    ] = None,
    learn_unlisted: Annotated[
        bool,
        typer.Option("--learn-unlisted", help="A partial --landmarks map: learn the tags it does not list."),
    ] = False,
    commands: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="Twist, TwistStamped or Odometry (its twist).")
    ] = None,
    readings: Annotated[
        list[str] | None, typer.Option(metavar="TOPIC", help="A sensor_msgs/Range topic (repeat for each).")
    ] = None,
    sightings: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="/tf with tag frames, or an AprilTagDetectionArray.")
    ] = None,
    truth: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="For scoring only: PoseStamped, or Odometry from mocap.")
    ] = None,
    mapping: Annotated[
        Path | None, typer.Option(help="A YAML file naming a topic per role (commands, readings, sightings, truth).")
    ] = None,
    receive_times: Annotated[
        bool, typer.Option("--receive-times", help="Time every message by when it was recorded, not its stamp.")
    ] = False,
    dt: Annotated[float | None, typer.Option(help="Step (s); by default the commands' median interval.")] = None,
    scan: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="A 2-D lidar's sensor_msgs/LaserScan (docs/lidar2d.md).")
    ] = None,
    wheels: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="With --scan: the wheels' sensor_msgs/JointState.")
    ] = None,
    wheel_joints: Annotated[
        str | None,
        typer.Option(metavar="LEFT,RIGHT", help="The wheels' joint names in the JointState, when not told by name."),
    ] = None,
    odom: Annotated[
        str | None,
        typer.Option(
            metavar="TOPIC",
            help="The wheel odometry's nav_msgs/Odometry, where the bag has several (an IMU's, a 2-D lidar's or a "
            "car's route).",
        ),
    ] = None,
    imu: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="The IMU's sensor_msgs/Imu (docs/inertial.md).")
    ] = None,
    gnss: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="With an IMU: the GNSS's sensor_msgs/NavSatFix, or none.")
    ] = None,
    vesc: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="A car's vesc_msgs/VescStateStamped (docs/ackermann.md).")
    ] = None,
    servo: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="A car's servo commands, std_msgs/Float64.")
    ] = None,
    drive: Annotated[
        str | None, typer.Option(metavar="TOPIC", help="A car's ackermann_msgs/AckermannDriveStamped.")
    ] = None,
) -> None:
    """Write a ROS bag as a log folder for `sensact learn em` (and `learn bootstrap` for a 1-D robot).

    With no topics named, the bag's types choose them: a Twist (/cmd_vel) is the commands, or an Odometry
    where there is no Twist (wheel odometry used as the command); sensor_msgs/Range topics are a 1-D
    robot's readings; AprilTag transforms on /tf (camera optical frame to tag36h11:ID) or ROS 1's
    apriltag_ros detections are range-and-bearing sightings of the map's landmarks (without --landmarks,
    `learn em` learns where the tags are); a PoseStamped is the
    truth, for scoring only. When a role is ambiguous the topics are listed with a proposal and nothing is
    written: name them with the options or --mapping. Header stamps time the messages (a Twist has none:
    when it was recorded), or --receive-times. Units become sensact's (mm) and the robot's axes REP 103's;
    the camera's position on the robot is left for EM to learn, and what /tf_static says of it is kept in
    meta.json to compare. The tables read from the bag stay in OUT/bag_tables/; a conversion that fails
    leaves nothing it wrote behind.

    A bag with a sensor_msgs/LaserScan (/scan) is a robot with wheel encoders and a 2-D lidar: its
    /joint_states (the wheels' positions), /odom, /cmd_vel and /tf_static's lidar mount become a lidar2d log
    folder, and `sensact learn em OUT` learns the wheels' radii, the axle and the lidar's mount
    (docs/lidar2d.md).

    A bag with a sensor_msgs/Imu is an outdoor robot: its wheel odometry (nav_msgs/Odometry's twist), the
    IMU, GNSS fixes (sensor_msgs/NavSatFix, in east-north-up metres around the first fix, the datum kept in
    meta.json) and /tf_static's IMU and antenna become an odometry-IMU-GNSS log folder, and `sensact learn em
    OUT` learns the odometry's gains, the gyro, the IMU's mount and the antenna (docs/inertial.md).

    A bag with a VESC's vesc_msgs/VescStateStamped or ackermann_msgs/AckermannDriveStamped is a car-like robot
    (F1TENTH, MuSHR): its /scan, /sensors/core (the motor's ERPM), /sensors/servo_position_command, /drive and
    /tf_static become a car log folder, and `sensact learn em OUT` learns vesc.yaml's four numbers, the
    wheelbase, the steering delay and the lidar's mount (docs/ackermann.md). The message definitions come from the
    bag."""
    from sensact.errors import LogFormatError
    from sensact.io.rosbag import (
        Roles,
        bag_topics,
        check_roles,
        no_supported_line,
        open_bag,
        propose_roles,
        read_bag_tables,
        topic_lines,
        write_table,
    )

    given = {
        k: v
        for k, v in {
            "commands": commands,
            "readings": tuple(readings) if readings else None,
            "sightings": sightings,
            "truth": truth,
        }.items()
        if v
    }
    named = {**_mapping(mapping), **given}
    reader = open_bag(bag)
    if getattr(reader, "sensact_note", None):
        console.print(f"[yellow]note:[/] {reader.sensact_note}", highlight=False)
    try:
        topics = bag_topics(reader)
        if not topics:
            raise LogFormatError("the bag holds no topic.", file=bag, fix="record the robot's topics into it.")
        check_roles(bag, Roles(**named), topics)  # a named topic of the wrong type first: naming both types
        from sensact.io.rosbag_car import is_car_bag

        if (vesc or servo or drive or is_car_bag(topics)) and not (readings or sightings):
            named_car = {"scan": scan, "vesc": vesc, "servo": servo, "drive": drive, "odom": odom, "truth": truth}
            _convert_car(bag, out, reader, topics, named_car, receive_times)
            return
        from sensact.io.rosbag_lidar2d import has_laser_scan

        if (scan or has_laser_scan(topics)) and not (readings or sightings):
            named_lidar = {"scan": scan, "joints": wheels, "odom": odom, "commands": commands, "truth": truth}
            _convert_lidar(bag, out, reader, topics, named_lidar, wheel_joints, receive_times)
            return
        from sensact.io.rosbag_inertial import has_imu

        if (imu or has_imu(topics)) and not (readings or sightings):
            _convert_inertial(bag, out, reader, topics, {"odom": odom, "imu": imu, "gnss": gnss}, receive_times)
            return
        proposal, open_roles, unfilled = propose_roles(reader, topics)
    finally:
        reader.close()
    missing = [roles for roles in unfilled if not set(roles) & set(named)]
    if missing:  # no naming can fix this: say what the bag has and what sensact reads
        raise LogFormatError(
            no_supported_line(missing, topics),
            file=bag,
            fix="record the commands (/cmd_vel or wheel odometry) and a sensor_msgs/Range or AprilTag detections.",
        )
    roles = Roles(**{**proposal.__dict__, **named})
    if "readings" in named and "sightings" not in named:
        roles = Roles(roles.commands, roles.readings, None, roles.truth)
    if "sightings" in named and "readings" not in named:
        roles = Roles(roles.commands, (), roles.sightings, roles.truth)
    console.print(f"{bag}:\n  " + "\n  ".join(topic_lines(topics)), highlight=False, soft_wrap=True)
    console.print("roles:\n  " + "\n  ".join(roles.lines()), highlight=False, soft_wrap=True)
    unresolved = [text for settled_by, text in open_roles if not settled_by & set(named)]
    if unresolved or roles.commands is None or not (roles.readings or roles.sightings):
        raise LogFormatError(
            f"cannot tell which topic plays which part ({'; '.join(unresolved) or 'commands or readings missing'}).",
            file=bag,
            fix="name them: --commands TOPIC, --readings TOPIC or --sightings TOPIC, --truth TOPIC (or --mapping).",
        )
    check_roles(bag, roles, topics)
    from sensact.cli.base import progress_bar

    with progress_bar() as progress:
        tables = read_bag_tables(bag, roles, receive_times=receive_times, progress=progress)
    for note in tables.notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    from sensact.io.atomic import nothing_half_written

    with nothing_half_written(out):  # a conversion that fails after reading leaves no tables behind
        src = out / TABLES
        src.mkdir(parents=True, exist_ok=True)
        cmd_csv = src / "commands.csv"
        if tables.sightings is not None:  # without --landmarks (or with some), EM learns the tags' positions
            if landmarks is not None:
                from sensact.io.timed_csv import read_landmarks
                from sensact.io.unit_checks import refuse_map_off_the_ranges_scale

                refuse_map_off_the_ranges_scale(landmarks, read_landmarks(landmarks)[0], tables.sightings["range_m"])
            write_table(cmd_csv, tables.commands)
            write_table(src / "sightings.csv", tables.sightings, ints=("landmark_id",))
            truth_csv = None
            if tables.truth is not None:
                truth_csv = src / "truth.csv"
                write_table(truth_csv, tables.truth)
            convert_csv(
                commands=cmd_csv,
                sightings=src / "sightings.csv",
                landmarks=landmarks,
                truth=truth_csv,
                out=out,
                dt=dt,
                survey=survey,
                learn_unlisted=learn_unlisted,
            )
        else:
            track = dict(t_s=tables.commands["t_s"], v_m_s=tables.commands["v_m_s"])
            table = _stacked([track, tables.readings] + ([_distance(tables.truth, landmarks)] if tables.truth else []))
            if tables.truth is not None and "distance_m" not in table:
                console.print(
                    "[yellow]note:[/] a 1-D robot's truth is scored as the distance to the map's one landmark: "
                    "give --landmarks with one row to score against it."
                )
            write_table(src / "track.csv", table)
            names = [c for c in table if c.endswith("_m") and c != "distance_m"]
            convert_track(
                src / "track.csv",
                out=out,
                command=["v_m_s"],
                reading=names,
                distance="distance_m" if "distance_m" in table else None,
                window=None,
                robust=None,
                dt=dt,
            )
        _record_source(out, bag, roles, tables, receive_times)
        _reads_back(out)


def _convert_lidar(
    bag: Path,
    out: Path,
    reader,
    topics,
    named: dict[str, str | None],
    wheel_joints: str | None,
    receive_times: bool,
) -> None:
    """The wheels-and-2-D-lidar route (docs/lidar2d.md): a lidar2d log folder at ``out``."""
    from sensact.app.lidar2d import convert_lidar_bag
    from sensact.cli.base import progress_bar
    from sensact.errors import ConfigError
    from sensact.io.rosbag import topic_lines
    from sensact.io.rosbag_lidar2d import lidar_roles

    pair = None
    if wheel_joints is not None:
        pair = tuple(j.strip() for j in wheel_joints.split(","))
        if len(pair) != 2 or not all(pair):
            raise ConfigError(
                f"--wheel-joints {wheel_joints!r} is not two names.", field="--wheel-joints", fix="give LEFT,RIGHT."
            )
    roles = lidar_roles(bag, topics, named)
    console.print(f"{bag}:\n  " + "\n  ".join(topic_lines(topics)), highlight=False, soft_wrap=True)
    console.print("roles:\n  " + "\n  ".join(roles.lines()), highlight=False, soft_wrap=True)
    with progress_bar() as progress:
        lb = convert_lidar_bag(
            bag, out, reader, topics, roles, wheel_joints=pair, receive_times=receive_times, progress=progress
        )
    for note in lb.notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    log = lb.log
    console.print(
        f"wrote {out}: {log.scan_t.size} scans of {log.beams} beams, the robot's motion from {log.drive}"
        + ("" if lb.wheel_joints is None else f" ({', '.join(lb.wheel_joints)})")
        + f"; learn with `sensact learn em {out}`"
    )


def _convert_car(bag: Path, out: Path, reader, topics, named: dict, receive_times: bool) -> None:
    """The car's route (docs/ackermann.md): a car log folder at ``out``, read back as `learn em` reads it."""
    from sensact.cli.base import progress_bar
    from sensact.io.atomic import nothing_half_written
    from sensact.io.car_folder import write_car_log
    from sensact.io.rosbag import topic_lines
    from sensact.io.rosbag_car import car_roles, read_car_bag

    roles = car_roles(bag, topics, named)
    console.print(f"{bag}:\n  " + "\n  ".join(topic_lines(topics)), highlight=False, soft_wrap=True)
    console.print("roles:\n  " + "\n  ".join(roles.lines()), highlight=False, soft_wrap=True)
    with progress_bar() as progress:
        log, notes = read_car_bag(bag, reader, topics, roles, receive_times=receive_times, progress=progress)
    for note in notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    with nothing_half_written(out):
        write_car_log(out, log)
        _reads_back(out)
    console.print(
        f"wrote {out}: {log.scan_t.size} scans of {log.beams} beams, {log.erpm_t.size} VESC reports, "
        f"{log.servo_t.size} servo commands, {log.drive_t.size} /drive commands; learn with `sensact learn em {out}`"
    )


def _convert_inertial(bag: Path, out: Path, reader, topics, named: dict, receive_times: bool) -> None:
    """The odometry-IMU-GNSS route (docs/inertial.md): an imu_gnss log folder at ``out``."""
    import dataclasses

    from sensact.cli.base import progress_bar
    from sensact.io.atomic import nothing_half_written
    from sensact.io.inertial_folder import write_inertial_log
    from sensact.io.rosbag import topic_lines
    from sensact.io.rosbag_inertial import inertial_roles, read_inertial_bag

    no_gnss = named.get("gnss") == "none"
    roles = inertial_roles(bag, topics, {**named, "gnss": None if no_gnss else named.get("gnss")})
    if no_gnss:
        roles = dataclasses.replace(roles, gnss=None)
    console.print(f"{bag}:\n  " + "\n  ".join(topic_lines(topics)), highlight=False, soft_wrap=True)
    console.print("roles:\n  " + "\n  ".join(roles.lines()), highlight=False, soft_wrap=True)
    with progress_bar() as progress:
        log, notes = read_inertial_bag(bag, reader, topics, roles, receive_times=receive_times, progress=progress)
    for note in notes:
        console.print(f"[yellow]note:[/] {note}", highlight=False)
    with nothing_half_written(out):
        write_inertial_log(out, log)
    console.print(
        f"wrote {out}: {log.odom_t.size} odometry rows, {log.imu_t.size} IMU readings, {log.gnss_t.size} GNSS fixes"
        f" over {log.seconds:.1f} s; learn with `sensact learn em {out}`"
    )


def _distance(truth, landmarks: Path | None) -> dict:
    """The 1-D truth: the distance from the recorded position to the map's one landmark."""
    import numpy as np

    from sensact.io.timed_csv import read_landmarks

    if landmarks is None or len(xy_mm := read_landmarks(landmarks)[0]) != 1:
        return {"t_s": truth["t_s"][:0]}
    x, y = xy_mm[0] / 1000.0
    return {"t_s": truth["t_s"], "distance_m": np.hypot(x - truth["x_m"], y - truth["y_m"])}


def _stacked(tables: list[dict]) -> dict:
    """Timed tables one under another, each row empty (NaN) in the others' columns."""
    import numpy as np

    names = list(dict.fromkeys(k for t in tables for k in t))
    n = [len(t["t_s"]) for t in tables]
    out = {k: np.full(sum(n), np.nan) for k in names}
    at = 0
    for t, m in zip(tables, n, strict=True):
        for k, v in t.items():
            out[k][at : at + m] = v
        at += m
    return {k: v for k, v in out.items() if k == "t_s" or np.isfinite(v).any()}


def _record_source(out: Path, bag: Path, roles, tables, receive_times: bool) -> None:
    """meta.json's source: the bag, its roles, and where /tf_static puts the camera (to compare with EM's)."""
    from sensact.io.atomic import write_text

    meta_path = out / "meta.json"
    meta = json.loads(meta_path.read_text(encoding="utf-8"))
    source = {
        "bag": str(bag),
        "roles": {k: v for k, v in roles.__dict__.items() if v},
        "times": "receive" if receive_times else "header stamps",
        "tables": meta.get("source", {}),
    }
    if tables.camera_frame:
        source["camera_frame"] = tables.camera_frame
    if tables.mount_from_tf:
        x, y, yaw = tables.mount_from_tf
        source["tf_static_mount"] = {"x_m": x, "y_m": y, "yaw_rad_applied": yaw}
    meta["source"] = source
    write_text(meta_path, json.dumps(meta, indent=2) + "\n")
