"""A ROS bag as the timed tables ``sensact convert csv`` and ``convert track`` read (``sensact convert bag``).

ROS 1 bags and ROS 2 bags (sqlite3 or MCAP) are read with ``rosbags`` (pure Python: no ROS install),
message definitions taken from the bag where it holds them (ROS 1's ``apriltag_ros`` types), else ROS 2
Humble's. Each topic plays one role:

* **commands**: ``geometry_msgs/Twist`` or ``TwistStamped`` (``/cmd_vel``), or a ``nav_msgs/Odometry``'s twist
  (wheel odometry used as the command), as ``v_m_s``, ``omega_rad_s`` and, when the robot side-steps,
  ``v_left_m_s`` (REP 103: x forward, y left);
* **readings** of a 1-D robot: ``sensor_msgs/Range``, a column ``<topic>_m`` each, a reading outside its
  message's ``[min_range, max_range]`` left empty (ROS's way of saying "nothing seen");
* **sightings**: AprilTag detections, as ROS 2 detectors publish them (transforms on ``/tf`` from the
  camera's optical frame to ``tag36h11:ID``) or as ROS 1's ``apriltag_ros/AprilTagDetectionArray``. The
  tag's position is turned into the robot's axes by the rotation ``/tf_static`` gives from the tree's root
  to the camera's frame (the optical frame's standard one, z forward, x right, y down, when it gives none)
  and becomes the range and bearing in the ground plane from the camera. The camera's position on the
  robot is left to EM to learn (``sensor_mount``); what ``/tf_static`` says of it is kept to compare;
* **truth**, for scoring only: ``geometry_msgs/PoseStamped`` (motion capture), or an ``Odometry`` named
  with ``--truth``.

Times are header stamps (a Twist has none: its receive time), or receive times throughout with
``receive_times``. Times are written as ``ns / 1e9``, float32 fields (a ``Range``'s) as their shortest
decimal, so that a bag made from CSVs gives those CSVs' numbers back exactly.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sensact.errors import LogFormatError
from sensact.io.rosbag1_scan import ros1_version
from sensact.progress import Progress

COMMAND_TYPES = ("geometry_msgs/Twist", "geometry_msgs/TwistStamped", "nav_msgs/Odometry")
READING_TYPES = ("sensor_msgs/Range",)
TF_TYPES = ("tf2_msgs/TFMessage", "tf/tfMessage")  # tf/tfMessage: ROS 1 before tf2
DETECTION_TYPES = ("apriltag_ros/AprilTagDetectionArray",)
TRUTH_TYPES = ("geometry_msgs/PoseStamped", "geometry_msgs/PoseWithCovarianceStamped", "nav_msgs/Odometry")
SUPPORTED = {
    "commands": COMMAND_TYPES,
    "readings": READING_TYPES,
    "sightings": TF_TYPES + DETECTION_TYPES,
    "truth": TRUTH_TYPES,
}
TAG_FRAME = re.compile(r"^(?:.*/)?tag[A-Za-z0-9]*[:_](\d+)$")  # tag36h11:3 (ROS 2), tag_3 (ROS 1's default)
# the optical frame's axes (z forward, x right, y down) in the robot's (x forward, y left, z up): REP 103
OPTICAL_TO_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
MOCAP_NAME = re.compile(r"mocap|vicon|optitrack|qualisys|motion_capture|ground_?truth", re.IGNORECASE)
CLOCK_GAP_S = 1.0  # header stamps further than this from the recording clock are on another clock
MOUNT_STEM = "tf_static_mount"


@dataclass(frozen=True)
class Topic:
    name: str
    msgtype: str  # without ROS 2's "/msg/": geometry_msgs/Twist
    count: int


@dataclass(frozen=True)
class Roles:
    """Which topic plays which part; None (or empty) where none does."""

    commands: str | None = None
    readings: tuple[str, ...] = ()
    sightings: str | None = None
    truth: str | None = None

    def lines(self) -> list[str]:
        return [
            f"commands:  {self.commands or '-'}",
            f"readings:  {', '.join(self.readings) or '-'}",
            f"sightings: {self.sightings or '-'}",
            f"truth:     {self.truth or '-'}",
        ]


@dataclass
class BagTables:
    """The bag's roles as columns, each a timed table (``t_s`` first) ready for a CSV."""

    commands: dict[str, np.ndarray]
    readings: dict[str, np.ndarray] | None = None
    sightings: dict[str, np.ndarray] | None = None
    truth: dict[str, np.ndarray] | None = None
    camera_frame: str | None = None
    mount_from_tf: tuple[float, float, float] | None = None  # camera in the root frame (x m, y m, yaw rad)
    notes: list[str] = field(default_factory=list)


def _short(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


def open_bag(path: Path):  # -> rosbags.highlevel.AnyReader, opened
    """The bag at ``path`` (a ROS 1 ``.bag``, or a ROS 2 bag folder or its ``.db3``/``.mcap`` file), open.

    Where rosbags refuses a bag that is whole, it is opened again another way, and ``reader.sensact_note``
    says how: a message definition rosbags cannot parse is replaced by ROS's standard one (ROS 2 Humble's,
    ROS 1 Noetic's), and a ROS 1 bag whose index rosbags cannot read is read record by record
    (``sensact.io.rosbag1_scan``)."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise LogFormatError(
            "reading a ROS bag needs the rosbags package.", file=path, fix="pip install 'sensact[ros]'"
        ) from None
    path = Path(path)
    if not path.exists():
        raise LogFormatError("no such file or folder.", file=path, fix="give the bag's path.")
    if path.is_file() and path.suffix in (".db3", ".mcap") and (path.parent / "metadata.yaml").is_file():
        path = path.parent
    reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    try:
        reader.open()
        return reader
    except Exception as err:  # rosbags raises its own per format; each means "not as it stands"
        why = _first_line(err)
    ros1 = path.is_file() and ros1_version(path) is not None
    failed = why
    for inner, standard, note in _other_ways(path, ros1):
        try:
            return _reopen(path, inner(), Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE, standard, note(why))
        except Exception as err:  # this way fails too: the next, and the last one's reason is the one said
            failed = _first_line(err)
    if ros1:
        raise LogFormatError(
            f"a ROS 1 bag that rosbags cannot read ({why}), and reading it record by record failed too ({failed}).",
            file=path,
            fix=f"rebuild its index with ROS 1's `rosbag reindex {path.name}` (or `rosbag fix` for format 1.2), "
            "then convert the .bag it writes.",
        )
    raise LogFormatError(
        f"not a ROS bag rosbags can read ({why}).",
        file=path,
        fix="give a ROS 1 .bag file, or a ROS 2 bag folder (with metadata.yaml) or its .mcap file.",
    )


def _first_line(err: BaseException) -> str:
    return str(err).splitlines()[0] if str(err) else type(err).__name__


def _other_ways(path: Path, ros1: bool) -> list[tuple[Callable[[], object], bool, Callable[[str], str]]]:
    """How else to open a bag rosbags refused: (its reader, whether with ROS's standard definitions, the note)."""
    from sensact.io.rosbag1_scan import Rosbag1Scan

    standard = "its message definitions do not parse ({}): ROS's standard definitions are used".format
    scanned = "rosbags cannot read its index ({}): the bag is read record by record".format
    if not ros1:
        from rosbags.rosbag2 import Reader as Reader2

        return [(lambda: Reader2(path), True, standard)]
    from rosbags.rosbag1 import Reader as Reader1

    return [
        (lambda: Reader1(path), True, standard),
        (lambda: Rosbag1Scan(path), False, scanned),
        (lambda: Rosbag1Scan(path), True, lambda why: scanned(why) + ", with ROS's standard definitions"),
    ]


def _reopen(path: Path, inner: object, store: object, standard: bool, note: str):  # -> AnyReader, opened
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import get_typestore

    reader = AnyReader([path], default_typestore=get_typestore(store))
    reader.readers = [_StandardTypes(inner) if standard else inner]
    reader.open()
    reader.sensact_note = note
    return reader


class _StandardTypes:
    """A rosbags reader whose connections claim no message definition of their own, so that ``AnyReader``
    deserializes with its default typestore (ROS's standard types): for a bag whose own definitions rosbags
    cannot parse. Messages are the inner reader's, handed back on these connections."""

    def __init__(self, inner: object) -> None:
        self.inner = inner
        self.connections: list = []

    def __enter__(self) -> _StandardTypes:
        from rosbags.interfaces import MessageDefinition, MessageDefinitionFormat

        self.inner.__enter__()
        none = MessageDefinition(MessageDefinitionFormat.NONE, "")
        self.connections = [c._replace(msgdef=none, digest="", owner=self) for c in self.inner.connections]
        return self

    def __exit__(self, *exc: object) -> None:
        self.inner.__exit__(*exc)

    def messages(self, connections=(), start=None, stop=None):
        ours = {c.id: c for c in self.connections}
        wanted = {c.id for c in connections} or set(ours)
        inner = [c for c in self.inner.connections if c.id in wanted]
        for c, t, raw in self.inner.messages(connections=inner, start=start, stop=stop):
            yield ours[c.id], t, raw


def bag_topics(reader) -> list[Topic]:
    counts: dict[tuple[str, str], int] = {}
    for c in reader.connections:
        key = (c.topic, _short(c.msgtype))
        counts[key] = counts.get(key, 0) + c.msgcount
    return [Topic(t, m, n) for (t, m), n in sorted(counts.items())]


def topic_lines(topics: list[Topic]) -> list[str]:
    width = max((len(t.name) for t in topics), default=0)
    return [f"{t.name:<{width}}  {t.msgtype}  ({t.count} messages)" for t in topics]


def _messages(reader, topic: str) -> Iterator[tuple[int, object]]:
    """``topic``'s messages, deserialized, with when each was recorded (ns). A bag whose index opened but whose
    messages do not read (damaged on disk, cut mid-chunk) is one line, whatever rosbags raised."""
    conns = [c for c in reader.connections if c.topic == topic]
    k = 0
    try:
        for c, t, raw in reader.messages(connections=conns):
            yield t, reader.deserialize(raw, c.msgtype)
            k += 1
    except Exception as err:  # rosbags raises its own per format, and struct's, numpy's or an assertion
        what = str(err).splitlines()[0] if str(err) else type(err).__name__
        unknown = [c.msgtype for c in conns if isinstance(err, KeyError) and c.msgtype in str(err)]
        if unknown:  # no definition in the bag, and none of ROS's standard types by that name
            raise LogFormatError(
                f"{topic}: its type {unknown[0]} is not one rosbags can resolve (the bag holds no definition of it, "
                "and ROS's standard types have none by that name).",
                file=(getattr(reader, "paths", None) or [None])[0],
                fix="record the topic as a standard type (a ROS 2 type is named pkg/msg/Type), or name another "
                "topic for this role.",
            ) from None
        raise LogFormatError(
            f"{topic}: message {k + 1} cannot be read ({type(err).__name__}: {what}): the bag is damaged.",
            file=(getattr(reader, "paths", None) or [None])[0],
            fix="copy the bag again, or cut it before the damage (rosbag filter, ros2 bag convert).",
        ) from None


def _tag_topics(reader, topics: list[Topic]) -> list[str]:
    """The /tf-like topics that carry a transform to a tag frame (read until the first one)."""
    found = []
    for t in topics:
        if t.msgtype not in TF_TYPES or t.name.endswith("tf_static"):
            continue
        for _, msg in _messages(reader, t.name):
            if any(TAG_FRAME.match(tr.child_frame_id) for tr in msg.transforms):
                found.append(t.name)
                break
    return found


def propose_roles(reader, topics: list[Topic]) -> tuple[Roles, list[tuple[frozenset[str], str]], list[tuple[str, ...]]]:
    """The roles a bag's types suggest, why any role is left open (ambiguous), and the roles no topic's type
    can play: with exactly one command source, one kind of reading and at most one truth the proposal is
    complete.

    Twists are the commands; an Odometry is one only where no Twist is (a robot that logs its wheel
    odometry, not what it was told); a PoseStamped is the truth (of several, the one named as motion capture's),
    an Odometry never is unless named. Each open
    role comes with the roles whose naming settles it."""
    open_roles: list[tuple[frozenset[str], str]] = []
    either = frozenset(("readings", "sightings"))
    twists = [t.name for t in topics if t.msgtype in COMMAND_TYPES[:2] and t.count]
    odoms = [t.name for t in topics if t.msgtype == "nav_msgs/Odometry" and t.count]
    commands = twists or odoms
    unfilled: list[tuple[str, ...]] = []  # roles no topic's type can play: no naming fixes those
    if not commands:
        unfilled.append(("commands",))
    if len(commands) > 1:
        open_roles.append((frozenset(("commands",)), f"commands: one of {', '.join(commands)}"))
    ranges = [t.name for t in topics if t.msgtype in READING_TYPES and t.count]
    sightings = _tag_topics(reader, topics) + [t.name for t in topics if t.msgtype in DETECTION_TYPES and t.count]
    if len(sightings) > 1:
        open_roles.append((either, f"sightings: one of {', '.join(sightings)}"))
    if not ranges and not sightings:
        unfilled.append(("readings", "sightings"))
    if ranges and sightings:
        open_roles.append((either, f"readings {', '.join(ranges)} or sightings {', '.join(sightings)}: not both"))
    truths = [t.name for t in topics if t.msgtype in TRUTH_TYPES[:2] and t.count]
    named = [t for t in truths if MOCAP_NAME.search(t)]
    if len(truths) > 1 and len(named) == 1:  # a goal or a detector's pose beside the motion capture's
        truths = named
    if len(truths) > 1:
        open_roles.append((frozenset(("truth",)), f"truth: one of {', '.join(truths)}"))
    roles = Roles(
        commands[0] if len(commands) == 1 else None,
        tuple(ranges) if not sightings else (),
        sightings[0] if len(sightings) == 1 and not ranges else None,
        truths[0] if len(truths) == 1 else None,
    )
    return roles, open_roles, unfilled


# types a landmark robot's bag often holds that its route does not read, and what reads them
NOT_READ = {
    "sensor_msgs/JointState": "wheel encoders: read with a 2-D lidar's sensor_msgs/LaserScan (docs/lidar2d.md)",
    "sensor_msgs/NavSatFix": "GNSS fixes: read with an IMU's sensor_msgs/Imu and wheel odometry (docs/inertial.md)",
}


# robot_localization's and navsat_transform's outputs share the sensors' types (a Husky's bag records both): a
# role taken by type passes them over for the sensor's own topic
FUSED_NAME = re.compile(r"filtered|ekf|fuse", re.IGNORECASE)
NOT_WHEELS = re.compile(r"gps|navsat|visual|vio|icp|lidar|laser", re.IGNORECASE)
WHEELS = re.compile(r"wheel|controller|^/?odom$", re.IGNORECASE)


def sensor_topics(topics: list[Topic], msgtype: str, drop: re.Pattern | None, prefer: re.Pattern | None) -> list[Topic]:
    """The topics of ``msgtype`` a sensor itself published: a fusion's output (and a name ``drop`` matches) is
    passed over and, of several left, the one whose name ``prefer`` matches is kept (else all stay, and the user
    names one)."""
    found = [t for t in topics if t.msgtype == msgtype and t.count and not MOCAP_NAME.search(t.name)]
    if len(found) > 1:
        sensors = [t for t in found if not FUSED_NAME.search(t.name) and not (drop and drop.search(t.name))]
        found = sensors or found
    if len(found) > 1 and prefer is not None:
        said = [t for t in found if prefer.search(t.name)]
        found = said if len(said) == 1 else found
    return found


# every route `convert bag` takes, and what each needs: a refusal names them all
ROUTES = (
    "landmarks (commands from Twist or Odometry, and sensor_msgs/Range readings or AprilTag sightings)",
    "wheels and a 2-D lidar (sensor_msgs/LaserScan, with JointState, Odometry or Twist; docs/lidar2d.md)",
    "wheel odometry, an IMU and GNSS (nav_msgs/Odometry and sensor_msgs/Imu, NavSatFix optional; docs/inertial.md)",
)
# the types that choose a route other than the landmarks'
ROUTE_TYPES = ("sensor_msgs/LaserScan", "sensor_msgs/Imu")


def routes_line() -> str:
    return "sensact's routes: " + "; ".join(ROUTES)


def empty_route_topics(topics: list[Topic]) -> list[str]:
    """The topics of a route's own type that hold no message (a TurtleBot3's /scan recorded with its lidar off)."""
    return [t.name for t in topics if t.msgtype in ROUTE_TYPES and not t.count]


def no_supported_line(missing: list[tuple[str, ...]], topics: list[Topic]) -> str:
    """Why no topic can play ``missing`` (each: roles any one of which would do; no naming can fill them): the
    types the bag has, the types sensact reads for each role, and what would add the others."""
    tag_free_tf = [t.name for t in topics if t.msgtype in TF_TYPES and not t.name.endswith("tf_static")]
    if ("readings", "sightings") not in missing:
        tag_free_tf = []
    found = sorted({t.msgtype for t in topics if t.msgtype not in NOT_READ})
    planned = sorted({t.msgtype for t in topics if t.msgtype in NOT_READ})
    reads = "; ".join(
        f"{role} from {', '.join(types)}" + (" (transforms to AprilTag frames)" if role == "sightings" else "")
        for role, types in SUPPORTED.items()
    )
    line = (
        f"no topic of a type sensact reads plays the {' or the '.join(' or '.join(m) for m in missing)}: the bag has "
        f"{', '.join(found + planned) or 'no typed topic'}"
    )
    if tag_free_tf:
        line += f" ({', '.join(tag_free_tf)} without AprilTag frames)"
    line += f". sensact reads {reads}"
    if planned:
        line += "; " + "; ".join(f"{t} is {NOT_READ[t]}" for t in planned)
    others = [t for t in found if not any(t in types for types in SUPPORTED.values()) and t not in ROUTE_TYPES]
    if others:
        line += f"; {', '.join(others)} {'is' if len(others) == 1 else 'are'} not read by sensact"
    empty = empty_route_topics(topics)
    if empty:  # the route the bag was recorded for, had its topic held anything: the cause comes first
        line = f"{', '.join(empty)} {'has' if len(empty) == 1 else 'have'} no messages; " + line
    return line + ". " + routes_line() + "."


def check_roles(path: Path, roles: Roles, topics: list[Topic]) -> None:
    """One line for a role on a topic the bag lacks, of a type that cannot play it, or with no message."""
    by_name = {t.name: t for t in topics}
    listing = ", ".join(f"{t.name} ({t.msgtype})" for t in topics)
    named = [("commands", roles.commands), ("sightings", roles.sightings), ("truth", roles.truth)]
    for role, name in named + [("readings", r) for r in roles.readings]:
        if name is None:
            continue
        if name not in by_name:
            raise LogFormatError(f"no topic {name} ({role}); the bag has {listing}.", file=path, fix=f"--{role} TOPIC")
        t = by_name[name]
        if t.msgtype not in SUPPORTED[role]:
            raise LogFormatError(
                f"{name} is a {t.msgtype}, which sensact cannot read as {role}.",
                file=path,
                field=role,
                fix=f"give a topic of type {' or '.join(SUPPORTED[role])}.",
            )
        if not t.count:
            raise LogFormatError(f"{name} ({role}) has no messages.", file=path, fix=f"give another --{role} TOPIC.")


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _seconds(ns: np.ndarray) -> np.ndarray:
    """Integer nanoseconds as seconds, correctly rounded (Python's int division is; a float64 holds an epoch
    time's nanoseconds only to 256 ns): a decimal time of 9 places or fewer comes back exactly."""
    return np.array([n / 1_000_000_000 for n in np.asarray(ns, dtype=np.int64).tolist()], dtype=np.float64)


def _shortest(values: np.ndarray) -> np.ndarray:
    """float32 fields as the shortest decimal that reads back as them (what the publisher meant to say)."""
    v = np.asarray(values, dtype=np.float32)
    return v.astype(str).astype(np.float64)


def _received(msgs: list[tuple[int, object]]) -> np.ndarray:
    return np.array([t for t, _ in msgs], dtype=np.int64)


def _read(reader, topic: str, progress: Progress | None = None) -> list[tuple[int, object]]:
    """``topic``'s messages, deserialized, with when each was recorded (ns); ``progress`` told every 2,000."""
    total = sum(c.msgcount for c in reader.connections if c.topic == topic)
    out = []
    for t, msg in _messages(reader, topic):
        out.append((t, msg))
        if progress is not None and len(out) % 2000 == 0:
            progress(f"reading {topic}", len(out), total)
    if progress is not None:
        progress(f"reading {topic}", len(out), total)
    if not out and not total:
        raise LogFormatError(
            f"{topic} has no messages.",
            file=(getattr(reader, "paths", None) or [None])[0],
            fix="record it with its driver running, or name another topic for its role.",
        )
    if not out:  # the index (a ROS 2 bag's metadata.yaml) counts messages the storage does not hold
        raise LogFormatError(
            f"{topic}: no message could be read, though the bag's index lists {total}.",
            file=(getattr(reader, "paths", None) or [None])[0],
            fix="record the topic again, or name another one for its role.",
        )
    return out


def _times(path: Path, topic: str, msgs: list[tuple[int, object]], stamped: bool, receive_times: bool) -> np.ndarray:
    """Each message's time in ns: its header stamp, or when it was recorded. Refuses stamps that go back."""
    recv = _received(msgs)
    if receive_times or not stamped:
        return recv
    ns = np.array([_stamp_ns(m.header) for _, m in msgs], dtype=np.int64)
    if not ns.any():
        raise LogFormatError(
            f"{topic}'s header stamps are all zero (its publisher does not stamp).",
            file=path,
            fix="pass --receive-times to use when each message was recorded.",
        )
    _refuse_going_back(path, topic, ns, "message", 0)
    return ns


def _refuse_going_back(path: Path, topic: str, ns: np.ndarray, what: str, slack_ns: int) -> None:
    """One line for stamps that go back, in the order recorded, by more than ``slack_ns``."""
    back = np.flatnonzero(np.diff(ns) < -slack_ns)
    if back.size:
        i = int(back[0]) + 1
        raise LogFormatError(
            f"{topic}'s clock goes backwards: {what} {i}'s header stamp is {(ns[i - 1] - ns[i]) / 1e9:.6g} s "
            "before the one recorded before it.",
            file=path,
            fix="record on one clock (use_sim_time set alike for every node), or pass --receive-times.",
        )


def _refuse_non_finite(path: Path, topic: str, what: str, values, first: int = 0) -> None:
    """One line for a NaN or infinite number in a message (a driver's garbage: no row of sensact's may hold one).
    ``values``: one row per message, the first being message ``first`` (from 0)."""
    bad = np.flatnonzero(~np.isfinite(np.asarray(values, dtype=np.float64)).reshape(len(values), -1).all(axis=1))
    if bad.size:
        raise LogFormatError(
            f"{topic}: message {first + int(bad[0]) + 1}'s {what} is not a finite number ({bad.size} such messages).",
            file=path,
            fix="fix the publisher, or cut the bag to the span it published numbers (ros2 bag convert, rosbag filter).",
        )


def _commands(
    path: Path, reader, topic: str, receive_times: bool, clocks: dict, progress: Progress | None = None
) -> tuple[dict[str, np.ndarray], bool]:
    """The commands' table, and whether their times are stamps (a TwistStamped's, an Odometry's)."""
    msgs = _read(reader, topic, progress)
    kind = _short(msgs[0][1].__msgtype__)

    def twist(m):
        return (
            m if kind == "geometry_msgs/Twist" else m.twist if kind == "geometry_msgs/TwistStamped" else m.twist.twist
        )

    ns = _times(path, topic, msgs, kind != "geometry_msgs/Twist", receive_times)
    clocks[topic] = (ns, _received(msgs))
    tw = [twist(m) for _, m in msgs]
    v = np.array([t.linear.x for t in tw])
    side = np.array([t.linear.y for t in tw])
    omega = np.array([t.angular.z for t in tw])
    _refuse_non_finite(path, topic, "twist", np.column_stack([v, side, omega]))
    table = {"t_s": _seconds(ns), "v_m_s": v}
    if np.any(side != 0):  # a robot that side-steps: its sideways command too
        table["v_left_m_s"] = side
    table["omega_rad_s"] = omega
    return table, kind != "geometry_msgs/Twist"


def _column_of(topic: str) -> str:
    name = re.sub(r"[^A-Za-z0-9]+", "_", topic).strip("_") or "range"
    return f"{name}_m"


def _ranges(
    path: Path, reader, topics: tuple[str, ...], receive_times: bool, clocks: dict, progress: Progress | None = None
) -> dict[str, np.ndarray]:
    """Every Range topic's readings, one row per message that holds one (REP 117: NaN, +-inf or a range outside
    the message's span is none), the other columns empty (NaN) on it."""
    times, cols = [], {}
    for topic in topics:
        msgs = _read(reader, topic, progress)
        ns = _times(path, topic, msgs, True, receive_times)
        clocks[topic] = (ns, _received(msgs))
        r = _shortest(np.array([m.range for _, m in msgs]))
        lo = _shortest(np.array([m.min_range for _, m in msgs]))
        hi = _shortest(np.array([m.max_range for _, m in msgs]))
        r = np.where(np.isfinite(r) & (r >= lo) & (r <= hi), r, np.nan)  # REP 117: outside the span is no reading
        if np.isfinite(r).sum() < 2:  # a sensor's model is learned from two readings at the least
            raise LogFormatError(
                f"{topic}: {int(np.isfinite(r).sum())} of its {r.size} ranges lie within their message's "
                "[min_range, max_range] (outside it, nothing was seen: REP 117): too few to learn from.",
                file=path,
                fix="check the sensor's min_range and max_range, or give another --readings TOPIC.",
            )
        seen = np.isfinite(r)  # a message with no reading is no row: two sensors' empty rows would repeat
        times.append(ns[seen])
        cols[topic] = r[seen]
    ns_all = np.concatenate(times)
    table: dict[str, np.ndarray] = {"t_s": _seconds(ns_all)}
    at = 0
    for topic, ns in zip(topics, times, strict=True):
        col = np.full(ns_all.size, np.nan)
        col[at : at + ns.size] = cols[topic]
        table[_column_of(topic)] = col
        at += ns.size
    order = np.argsort(ns_all, kind="stable")
    return {k: v[order] for k, v in table.items()}


QUATERNION_TOLERANCE = 0.01  # tf2 refuses a transform whose quaternion's squared norm is further than this from 1


def _unit_quaternion(path: Path, topic: str, k: int, q) -> None:
    norm2 = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w
    if not np.isfinite(norm2) or abs(norm2 - 1.0) > QUATERNION_TOLERANCE:
        raise LogFormatError(
            f"{topic}: message {k + 1}'s orientation ({q.x:g}, {q.y:g}, {q.z:g}, {q.w:g}) is not a unit quaternion "
            "(tf2 refuses it too).",
            file=path,
            fix="fix the publisher to normalize its quaternions.",
        )


def _quat_matrix(q) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    m = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    snapped = np.round(m)
    return np.where(np.abs(m - snapped) < 1e-9, snapped, m)  # an axis permutation (an optical frame) kept exact


def _yaw(q) -> float:
    return float(np.arctan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z)))


def _static_tree(path: Path, reader, topics: list[Topic]) -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """child frame -> (parent, rotation, translation) from every /tf_static message."""
    tree: dict[str, tuple[str, np.ndarray, np.ndarray]] = {}
    for t in topics:
        if t.msgtype in TF_TYPES and t.name.endswith("tf_static"):
            for k, (_, msg) in enumerate(_read(reader, t.name)):
                for tr in msg.transforms:
                    tl = tr.transform.translation
                    _refuse_non_finite(path, t.name, f"translation to {tr.child_frame_id}", [[tl.x, tl.y, tl.z]], k)
                    _unit_quaternion(path, t.name, k, tr.transform.rotation)
                    tree[tr.child_frame_id.lstrip("/")] = (
                        tr.header.frame_id.lstrip("/"),
                        _quat_matrix(tr.transform.rotation),
                        np.array([tl.x, tl.y, tl.z]),
                    )
    return tree


def _camera_pose(path: Path, tree, frame: str) -> tuple[np.ndarray, np.ndarray, bool]:
    """The camera frame's rotation and position in the static tree's root, and whether the tree had it."""
    rot, pos, found = np.eye(3), np.zeros(3), False
    seen = [frame]
    while frame in tree:
        if tree[frame][0] in seen:
            raise LogFormatError(
                f"/tf_static's frames form a loop ({' -> '.join([*seen, tree[frame][0]])}): no frame is the robot's.",
                file=path,
                fix="publish each frame's parent once, from the robot's base_link down.",
            )
        seen.append(tree[frame][0])
        parent, r, p = tree[frame]
        rot, pos, found = r @ rot, r @ pos + p, True
        frame = parent
    return rot, pos, found


def _sightings(
    path: Path,
    reader,
    topic: str,
    topics: list[Topic],
    receive_times: bool,
    clocks: dict,
    progress: Progress | None = None,
) -> tuple[dict[str, np.ndarray], str, tuple[float, float, float] | None, list[str]]:
    """Tag detections as t_s, landmark_id, range_m, bearing_rad from the camera, in the robot's axes."""
    msgs = _read(reader, topic, progress)
    rows: list[tuple[int, int, str, float, float, float]] = []  # ns, id, frame, x, y, z (in the camera frame)
    recvs: list[int] = []
    for recv, msg in msgs:
        before = len(rows)
        if hasattr(msg, "transforms"):
            for tr in msg.transforms:
                m = TAG_FRAME.match(tr.child_frame_id)
                if m:
                    tl = tr.transform.translation
                    ns = recv if receive_times else _stamp_ns(tr.header)
                    rows.append((ns, int(m.group(1)), tr.header.frame_id.lstrip("/"), tl.x, tl.y, tl.z))
        else:
            for det in msg.detections:
                if len(det.id) != 1:  # a tag bundle: its pose is the bundle's, not one landmark's
                    continue
                p = det.pose.pose.pose.position
                ns = recv if receive_times else _stamp_ns(det.pose.header)
                rows.append((ns, int(det.id[0]), det.pose.header.frame_id.lstrip("/"), p.x, p.y, p.z))
        recvs += [recv] * (len(rows) - before)
    if not rows:
        raise LogFormatError(f"{topic} holds no tag detection.", file=path, fix="give another --sightings TOPIC.")
    frames = sorted({r[2] for r in rows})
    if len(frames) > 1:
        raise LogFormatError(
            f"{topic} has tags seen from {len(frames)} cameras ({', '.join(frames)}); EM learns one sensor's mount.",
            file=path,
            fix="record one camera's detections, or split the bag by camera.",
        )
    raw = np.array([r[3:] for r in rows], dtype=float)
    _refuse_non_finite(path, topic, "tag position", raw)
    behind = raw[:, 2] <= 0.0  # an optical frame looks along +z: a camera sees nothing at or behind its plane
    if behind.mean() > 0.5:
        raise LogFormatError(
            f"{topic}: {int(behind.sum())} of {len(rows)} tag detections are at or behind the camera (z <= 0 in "
            f"{frames[0]}): not an optical frame's positions (z forward, x right, y down).",
            file=path,
            fix="give the detections in the camera's optical frame, as apriltag_ros and the /tf tag frames are.",
        )
    kept_note = []
    if behind.any():
        kept_note.append(f"{int(behind.sum())} tag detections at or behind the camera (z <= 0) are dropped")
        rows = [r for r, b in zip(rows, behind, strict=True) if not b]
        recvs = [v for v, b in zip(recvs, behind, strict=True) if not b]
    ns = np.array([r[0] for r in rows], dtype=np.int64)
    # a detector may publish a frame's tags after the next frame's: only a second back is another clock
    _refuse_going_back(path, topic, ns, "detection", int(CLOCK_GAP_S * 1e9))
    clocks[topic] = (ns, np.array(recvs, dtype=np.int64))
    tree = _static_tree(path, reader, topics)
    rot, pos, found = _camera_pose(path, tree, frames[0])
    notes = kept_note
    if not found:
        rot = OPTICAL_TO_BODY
        notes.append(
            f"/tf_static does not place {frames[0]}: read as an optical frame (z forward, x right, y down) facing "
            "the robot's forward"
        )
    xyz = np.array([r[3:] for r in rows]) @ rot.T  # the tag in the robot's axes, from the camera
    table = {
        "t_s": _seconds(ns),
        "landmark_id": np.array([r[1] for r in rows], dtype=np.float64),
        "range_m": np.hypot(xyz[:, 0], xyz[:, 1]),  # in the ground plane: the map is 2-D
        "bearing_rad": np.arctan2(xyz[:, 1], xyz[:, 0]),
    }
    forward = rot @ np.array([0.0, 0.0, 1.0])  # where the optical axis looks, in the robot's axes
    mount = (float(pos[0]), float(pos[1]), float(np.arctan2(forward[1], forward[0]))) if found else None
    return table, frames[0], mount, notes


def _truth(
    path: Path, reader, topic: str, receive_times: bool, clocks: dict, progress: Progress | None = None
) -> dict[str, np.ndarray]:
    msgs = _read(reader, topic, progress)
    ns = _times(path, topic, msgs, True, receive_times)
    clocks[topic] = (ns, _received(msgs))

    def pose(m):
        p = m.pose
        return p.pose if hasattr(p, "pose") else p

    poses = [pose(m) for _, m in msgs]
    _refuse_non_finite(path, topic, "pose", [[p.position.x, p.position.y, p.position.z] for p in poses])
    for k, p in enumerate(poses):
        _unit_quaternion(path, topic, k, p.orientation)
    return {
        "t_s": _seconds(ns),
        "x_m": np.array([p.position.x for p in poses]),
        "y_m": np.array([p.position.y for p in poses]),
        "theta_rad": np.array([_yaw(p.orientation) for p in poses]),
    }


def _one_clock(path: Path, clocks: dict[str, tuple[np.ndarray, np.ndarray]], unstamped: str | None) -> int:
    """The shift (ns) that puts ``unstamped`` (a Twist's topic, timed when it was recorded) on the stamps'
    clock: 0 when the stamps are on the recording clock (within CLOCK_GAP_S), else their median gap from it
    (a bag of sim-time stamps recorded on the wall's clock). Stamped topics on two clocks are refused.
    ``clocks``: topic -> (the times used, when each was recorded), in ns."""
    gaps = {t: int(np.median(ns - recv)) for t, (ns, recv) in clocks.items() if ns.size and t != unstamped}
    if not gaps:
        return 0
    lo, hi = min(gaps, key=gaps.__getitem__), max(gaps, key=gaps.__getitem__)
    if (gaps[hi] - gaps[lo]) / 1e9 > CLOCK_GAP_S:
        raise LogFormatError(
            f"{hi}'s stamps are {(gaps[hi] - gaps[lo]) / 1e9:.6g} s later against the recording clock than {lo}'s: "
            "they are on two clocks.",
            file=path,
            fix="pass --receive-times to put every topic on the recording clock.",
        )
    shift = int(np.median(list(gaps.values())))
    return shift if unstamped is not None and abs(shift) / 1e9 > CLOCK_GAP_S else 0


def read_bag_tables(
    path: Path, roles: Roles, *, receive_times: bool = False, progress: Progress | None = None
) -> BagTables:
    """The tables of ``roles``' topics; ``progress(description, done, total)`` as each topic is read."""
    reader = open_bag(path)
    try:
        topics = bag_topics(reader)
        check_roles(path, roles, topics)
        if roles.commands is None:
            raise LogFormatError("no topic holds the commands.", file=path, fix="--commands TOPIC")
        clocks: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        commands, stamped = _commands(path, reader, roles.commands, receive_times, clocks, progress)
        out = BagTables(commands)
        if roles.readings:
            out.readings = _ranges(path, reader, roles.readings, receive_times, clocks, progress)
        if roles.sightings:
            out.sightings, out.camera_frame, out.mount_from_tf, notes = _sightings(
                path, reader, roles.sightings, topics, receive_times, clocks, progress
            )
            out.notes += notes
        if roles.truth:
            out.truth = _truth(path, reader, roles.truth, receive_times, clocks, progress)
        shift = _one_clock(path, clocks, None if stamped or receive_times else roles.commands)
        if shift:
            out.commands["t_s"] = _seconds(clocks[roles.commands][0] + shift)
            out.notes.append(
                f"the stamps are {shift / 1e9:.6g} s from the recording clock, on which {roles.commands} (a Twist, "
                "with no stamp) was recorded: its times are moved onto the stamps' clock by that much"
            )
        return out
    finally:
        reader.close()


def write_table(path: Path, table: dict[str, np.ndarray], ints: tuple[str, ...] = ()) -> None:
    """A timed table as CSV, every float as its shortest round-tripping repr and NaN as an empty cell."""
    from sensact.io.atomic import write_text

    names = list(table)
    cols = [table[n] for n in names]
    lines = [",".join(names)]
    for i in range(len(cols[0])):
        cells = []
        for n, c in zip(names, cols, strict=True):
            v = float(c[i])
            cells.append("" if not np.isfinite(v) else str(int(v)) if n in ints else repr(v))
        lines.append(",".join(cells))
    write_text(path, "\n".join(lines) + "\n")
