"""Malformed inputs for every format a command reads, and the commands that read them (issue 74).

``base_inputs(dir)`` writes well-formed inputs once: a short simulated planar log folder, a model learned on
it, a Turtlebot-style CSV, a track CSV and a settings file. ``cases()`` lists each mutation of one of them
with the command that reads it; ``run_case`` runs it as a user would (a fresh process, under a timeout) and
``problems`` says what was wrong with how it ended: a traceback, an internal error, an exit code other than
0, 2 or 3 (2 where the input must be refused), more than one line for an error, a temporary file left
behind, an input written over, a file left by a run that failed or written among the inputs (issue 95), over
1 GB of memory, a hang. ``tests/test_fuzz.py`` runs a sample in CI and every case with
``SENSACT_FUZZ=all``.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensact.cli.compiling import MESSAGE as COMPILE_MESSAGE

TIMEOUT_S = 120.0
MEMORY_CAP_BYTES = 1 << 30  # issue 74: never over 1 GB
FIT = ("--set", "max_iterations=25", "--no-report")  # keeps each fit of a mutated log short

Mutation = Callable[[bytes], bytes]


@dataclass(frozen=True)
class Case:
    name: str
    target: str  # the base input mutated (a path under the base folder), or "" for none
    mutate: Mutation | None
    argv: tuple[str, ...]  # {work}: the case's copy of the base inputs; {out}: a fresh output folder
    refuse: bool  # the input is garbage: it must end in exit 2 (or, where noted, 3: written and flagged)
    flagged_ok: bool = False  # a truncated file may still be a shorter well-formed one: exit 3 will do


@dataclass(frozen=True)
class Ended:
    code: int | None  # None: killed by the timeout
    stderr: str
    seconds: float
    peak_rss_bytes: int
    leftovers: tuple[str, ...]  # temporary files left in the work folder
    overwritten: tuple[str, ...] = ()  # inputs changed or removed (issue 95: a command never writes over one)
    left_on_failure: tuple[str, ...] = ()  # files a run that failed (exit 2, 70, ...) wrote and left
    beside_inputs: tuple[str, ...] = ()  # files written among the inputs, not where --out said


# ---- mutations of a CSV ------------------------------------------------------------------------------------


def _rows(data: bytes) -> list[list[str]]:
    return [line.split(",") for line in data.decode("utf-8").splitlines() if line]


def _join(rows: list[list[str]]) -> bytes:
    return ("\n".join(",".join(r) for r in rows) + "\n").encode("utf-8")


def set_cell(column: int, value: str, row: int = 5) -> Mutation:
    def m(data: bytes) -> bytes:
        rows = _rows(data)
        rows[min(row, len(rows) - 1)][column] = value
        return _join(rows)

    return m


def map_column(column: int, scale: float = 1.0, offset: float = 0.0) -> Mutation:
    """Every value of a column times ``scale`` plus ``offset`` (a clock in ms, or on another zero)."""

    def m(data: bytes) -> bytes:
        rows = _rows(data)
        for r in rows[1:]:
            r[column] = repr(float(r[column]) * scale + offset) if r[column] else r[column]
        return _join(rows)

    return m


def reorder(kind: str) -> Mutation:
    def m(data: bytes) -> bytes:
        rows = _rows(data)
        head, body = rows[:1], rows[1:]
        if kind == "reverse":
            body = body[::-1]
        elif kind == "shuffle":
            body = [body[i] for i in np.random.default_rng(0).permutation(len(body))]
        elif kind == "duplicate":
            body = [r for r in body for _ in (0, 1)]
        elif kind == "swap":
            body[3], body[4] = body[4], body[3]
        elif kind == "one_row":
            body = body[:1]
        elif kind == "two_rows":
            body = body[:2]
        elif kind == "header_only":
            body = []
        elif kind == "drop_column":
            head, body = [r[:-1] for r in head], [r[:-1] for r in body]
        elif kind == "extra_cell":
            body[2] = [*body[2], "1"]
        elif kind == "short_row":
            body[2] = body[2][:1]
        elif kind == "last_far":
            body[-1][0] = "1e9"
        elif kind == "constant":
            body = [[r[0], *body[0][1:]] for r in body]
        return _join(head + body)

    return m


def bytes_mutation(kind: str) -> Mutation:
    def m(data: bytes) -> bytes:
        if kind == "truncate":
            return data[: len(data) // 2]
        if kind == "empty":
            return b""
        if kind == "non_utf8":
            return data[:40] + b"\xff\xfe\x80" + data[40:]
        if kind == "binary":
            return bytes(np.random.default_rng(1).integers(0, 256, 4096, dtype=np.uint8))
        if kind == "crlf_bom":
            return b"\xef\xbb\xbf" + data.replace(b"\n", b"\r\n")
        raise ValueError(kind)

    return m


# ---- mutations of a pcap ----------------------------------------------------------------------------------------


def _pcap_records(data: bytes) -> tuple[bytes, list[bytes]]:
    """The global header and each record (its 16-byte header with its data), of a little-endian pcap."""
    import struct

    head, at, records = data[:24], 24, []
    while at + 16 <= len(data):
        n = struct.unpack_from("<I", data, at + 8)[0]
        records.append(data[at : at + 16 + n])
        at += 16 + n
    return head, records


def pcap_mutation(kind: str) -> Mutation:
    def m(data: bytes) -> bytes:
        head, records = _pcap_records(data)
        if kind == "duplicate_packets":  # every tenth packet twice, as a mirrored switch port sends it
            records = [r for i, r in enumerate(records) for _ in range(2 if i % 10 == 0 else 1)]
        elif kind == "reverse_packets":
            records = records[::-1]
        elif kind == "few_packets":
            records = records[:50]
        elif kind == "bad_length":  # a record header claiming 2 GB
            records[5] = records[5][:8] + (2**31).to_bytes(4, "little") + records[5][12:]
        elif kind == "dropped_packets":  # twenty packets lost on the wire, at random
            lost = set(np.random.default_rng(0).choice(len(records), 20, replace=False).tolist())
            records = [r for i, r in enumerate(records) if i not in lost]
        elif kind == "zero_incl_len":  # every record captured with no bytes (a snap length of 0)
            records = [r[:8] + bytes(4) + r[12:16] for r in records]
        elif kind == "zero_time":  # every packet stamped at the epoch's zero
            records = [bytes(8) + r[8:] for r in records]
        elif kind in ("rotation_damaged", "block_id_damaged", "sensor_stamp_damaged", "capture_time_damaged"):
            k, r = len(records) // 3, bytearray(records[len(records) // 3])  # one packet, a third of the way in
            payload = 16 + 42  # the record header, then Ethernet, IPv4 and UDP headers
            if kind == "rotation_damaged":
                r[payload + 2 : payload + 4] = (40000).to_bytes(2, "little")
            elif kind == "block_id_damaged":
                r[payload : payload + 2] = b"\x12\x34"
            elif kind == "sensor_stamp_damaged":  # forty minutes on, by the lidar's clock
                at = payload + 1200
                r[at : at + 4] = (int.from_bytes(r[at : at + 4], "little") + 2_400_000_000).to_bytes(4, "little")
            else:  # a day on, by the capture's clock
                r[0:4] = (int.from_bytes(r[0:4], "little") + 86_400).to_bytes(4, "little")
            records[k] = bytes(r)
        return head + b"".join(records)

    return m


def unit_mutation(kind: str) -> Mutation:
    """One packet a third of the way into a VLP-16's or an OS-1's capture damaged, or a VLP-16's every packet
    marked dual-return."""

    def m(data: bytes) -> bytes:
        head, records = _pcap_records(data)
        payload = 16 + 42
        k = len(records) // 3
        if kind == "dual_return":
            records = [r[: payload + 1204] + bytes([0x39]) + r[payload + 1205 :] for r in records]
        else:
            r = bytearray(records[k])
            if kind == "vlp16_block_id":
                r[payload + 100 : payload + 102] = b"\x12\x34"
            elif kind == "vlp16_rotation":
                r[payload + 202 : payload + 204] = (36500).to_bytes(2, "little")
            elif kind == "os1_encoder":  # the first column's encoder count past a turn
                r[payload + 12 : payload + 16] = (100_000).to_bytes(4, "little")
            records[k] = bytes(r)
        return head + b"".join(records)

    return m


def pcapng_mutation(kind: str) -> Mutation:
    """The capture saved as pcapng (the reader goes by the magic number, not the name), then damaged."""

    def m(data: bytes) -> bytes:
        import io

        import dpkt

        out = io.BytesIO()
        writer = dpkt.pcapng.Writer(out)
        for stamp, frame in dpkt.pcap.Reader(io.BytesIO(data)):
            writer.writepkt(frame, ts=stamp)
        ng = out.getvalue()
        if kind == "as_pcapng":
            return ng
        if kind == "pcapng_truncate":
            return ng[: len(ng) // 2]
        if kind == "pcapng_bad_block_length":  # the tenth block claims 1 GB
            at = 0
            for _ in range(10):
                at += int.from_bytes(ng[at + 4 : at + 8], "little")
            return ng[: at + 4] + (2**30).to_bytes(4, "little") + ng[at + 8 :]
        raise ValueError(kind)

    return m


# ---- mutations of JSON and YAML ------------------------------------------------------------------------------


def json_set(path: tuple[str | int, ...], value: object) -> Mutation:
    def m(data: bytes) -> bytes:
        doc = json.loads(data)
        node = doc
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = value
        return json.dumps(doc).encode()  # NaN and Infinity as Python writes them (not JSON, read by json)

    return m


def json_drop(path: tuple[str | int, ...]) -> Mutation:
    def m(data: bytes) -> bytes:
        doc = json.loads(data)
        node = doc
        for key in path[:-1]:
            node = node[key]
        del node[path[-1]]
        return json.dumps(doc).encode()

    return m


def deep_json(data: bytes) -> bytes:
    return b'{"a": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"


def deep_yaml(data: bytes) -> bytes:
    return b"a: " + b"[" * 20_000 + b"]" * 20_000 + b"\n"


def yaml_line(text: str) -> Mutation:
    return lambda data: data + ("\n" + text + "\n").encode()


# ---- mutations of a ROS 1 bag ----------------------------------------------------------------------------------

# edit(topic, receive ns, message, k: the message's index on its topic) -> the (receive ns, message)s in its place
BagEdit = Callable[[str, int, object, int], list[tuple[int, object]]]


def bag_rewrite(edit: BagEdit) -> Mutation:
    """A ROS 1 bag with each message replaced by what ``edit`` gives (message-level garbage, as a broken
    driver or a merged recording writes it), rewritten with rosbags' own writer."""

    def m(data: bytes) -> bytes:
        import tempfile

        from rosbags.rosbag1 import Reader, Writer

        from sensact.io.rosbag_write import typestore

        ts = typestore("ros1")
        with tempfile.TemporaryDirectory() as d:
            src, dst = Path(d) / "in.bag", Path(d) / "out.bag"
            src.write_bytes(data)
            out, seen = [], {}
            with Reader(src) as r:
                for c, t, raw in r.messages():
                    k = seen[c.topic] = seen.get(c.topic, -1) + 1
                    msg = ts.deserialize_ros1(raw, c.msgtype)
                    out += [(c.topic, c.msgtype, t2, m2) for t2, m2 in edit(c.topic, t, msg, k)]
            with Writer(dst) as w:
                conns = {}
                for topic, msgtype, t, msg in out:
                    if topic not in conns:
                        conns[topic] = w.add_connection(topic, msgtype, typestore=ts)
                    w.write(conns[topic], int(t), ts.serialize_ros1(msg, msgtype))
            return dst.read_bytes()

    return m


def _stamp(msg) -> object:
    return msg.header.stamp if hasattr(msg, "header") else msg.transforms[0].header.stamp


def on(topic: str, change: Callable[[object], None], which: Callable[[int], bool] = lambda k: k == 20) -> Mutation:
    """``change`` (in place) of the messages of ``topic`` whose index ``which`` picks (by default the 21st)."""

    def edit(t_topic: str, t: int, msg: object, k: int) -> list[tuple[int, object]]:
        if t_topic == topic and which(k):
            change(msg)
        return [(t, msg)]

    return bag_rewrite(edit)


def _set(path: str, value: float) -> Callable[[object], None]:
    """Set a dotted field of a message (``transforms.0.transform.translation.x``) to ``value``."""

    def change(msg: object) -> None:
        *parents, last = path.split(".")
        node = msg
        for p in parents:
            node = node[int(p)] if p.isdigit() else getattr(node, p)
        setattr(node, last, value)

    return change


def _shift_stamp(seconds: float) -> Callable[[object], None]:
    def change(msg: object) -> None:
        for st in [tr.header.stamp for tr in getattr(msg, "transforms", [])] or [msg.header.stamp]:
            ns = st.sec * 10**9 + st.nanosec + int(seconds * 1e9)
            st.sec, st.nanosec = ns // 10**9, ns % 10**9

    return change


def every(k: int) -> bool:
    return True


def bag_keep(topic: str, which: Callable[[int], bool]) -> Mutation:
    """Only the messages of ``topic`` whose index ``which`` picks (the others' all)."""
    return bag_rewrite(lambda tp, t, msg, k: [(t, msg)] if tp != topic or which(k) else [])


def bag_twice(topic: str) -> Mutation:
    """Every message of ``topic`` recorded twice (two recorders merged)."""
    return bag_rewrite(lambda tp, t, msg, k: [(t, msg)] * (2 if tp == topic else 1))


def bag_late(topic: str, seconds: float) -> Mutation:
    """One message of ``topic`` recorded ``seconds`` after it was (a recording clock that jumped)."""
    return bag_rewrite(lambda tp, t, msg, k: [(t + int(seconds * 1e9) if tp == topic and k == 20 else t, msg)])


# ---- the base inputs --------------------------------------------------------------------------------------------


# the child's own peak resident memory, VmHWM: getrusage's ru_maxrss survives fork and exec on Linux, so it
# would report the parent's (pytest's, 1.2 GB late in a suite) for every case
CHILD = """
import atexit, os, sys
rss = os.environ.get("SENSACT_FUZZ_RSS")

def peak():
    kb = next(int(ln.split()[1]) for ln in open("/proc/self/status") if ln.startswith("VmHWM:"))
    open(rss, "w").write(str(kb * 1024))

if rss:
    atexit.register(peak)
from sensact.cli import main
sys.argv[0] = "sensact"
main()
"""


def sensact_argv(*args: str) -> list[str]:
    return [sys.executable, "-c", CHILD, *args]


def base_inputs(base: Path) -> Path:
    """Write the well-formed inputs under ``base`` (once): log/ (a 40-s simulated planar log), model.json
    (learned on it), tb.csv (a Turtlebot-style 1-D log) and track.csv (a 1-D track log for `convert track`)."""
    if (base / "done").exists():
        _surfaces(base)  # a base written before issue 95's surfaces gains them
        return base
    base.mkdir(parents=True, exist_ok=True)
    subprocess.run(sensact_argv("simulate", "diffdrive", "--out", str(base / "log"), "--seconds", "40"), check=True)
    subprocess.run(
        sensact_argv("learn", "em", str(base / "log"), "--out", str(base / "model.json"), *FIT),
        check=False,  # 3: flagged (max_iterations) is a model all the same
    )
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 0.1)
    cmd = np.where((t // 6) % 2 == 0, 0.15, -0.15)
    pos = 1.0 + np.cumsum(cmd) * 0.1
    lines = ["time,range,velocity_command,sonar1,raw_ir1"]
    for ti, ci, pi in zip(t, cmd, pos, strict=True):
        sonar = pi + rng.normal(0, 0.02)
        ir = 400.0 / pi + rng.normal(0, 3)
        lines.append(f"{ti:.2f},{pi:.4f},{ci:.3f},{sonar:.4f},{ir:.2f}")
    (base / "tb.csv").write_text("\n".join(lines) + "\n")
    track = ["t_s,v_mm_s,distance_mm,sonar_mm"]
    for ti, ci, pi in zip(t, cmd, pos, strict=True):
        track.append(f"{ti:.2f},{ci * 1000:.1f},{pi * 1000:.1f},{1000 * pi + rng.normal(0, 20):.1f}")
    (base / "track.csv").write_text("\n".join(track) + "\n")
    _mrclam(base / "mrclam", rng)
    subprocess.run(sensact_argv("simulate", "car", "--out", str(base / "car"), "--seconds", "20"), check=True)
    for folder, lidar in (("car16", "VLP-16"), ("os1", "OS-1")):  # other units' short captures
        argv = ("simulate", "car", "--out", str(base / folder), "--seconds", "6", "--set", f"lidar={lidar}")
        subprocess.run(sensact_argv(*argv), check=True)
    shutil.copy(base / "car" / "calibration_true.yaml", base / "calib.yaml")  # a factory calibration to mutate
    import yaml

    # what `export --format velodyne` reads of a `learn car` model (learning one would take 17 s here)
    cal = yaml.safe_load((base / "calib.yaml").read_text())
    (base / "car_model.json").write_text(json.dumps({"velodyne_calibration": cal}))
    _timed(base / "log", base / "timed")
    _bags(base, t, cmd, pos, rng)
    _lidar(base)
    _surfaces(base)
    (base / "settings.yaml").write_text("max_iterations: 20\n")
    (base / "done").write_text("")
    return base


def _lidar(base: Path) -> None:
    """A wheels-and-2-D-lidar robot (issue 93): lidar/ (its log folder, 40 s), lidarbag/robot.bag (ROS 1) and
    lidarbag2/robot (MCAP) of it, and lidar_model.json learned on it."""
    for folder, bag in (("lidar", "lidarbag/robot.bag"), ("lidar_mcap", "lidarbag2/robot")):
        argv = ("simulate", "diffdrive", "--out", str(base / folder), "--set", "sensor=lidar2d", "--seconds", "40")
        subprocess.run(sensact_argv(*argv, "--bag", str(base / bag)), check=True)
    shutil.rmtree(base / "lidar_mcap")
    subprocess.run(
        sensact_argv("learn", "em", str(base / "lidar"), "--out", str(base / "lidar_model.json")), check=True
    )


def _surfaces(base: Path) -> None:
    """Issue 95's surfaces: bag3/robot and lidarbag3/robot (ROS 2 sqlite3), other/log (a second log named
    log, for a fleet) and tb_model.json (a model of the Turtlebot-style log, to localize and monitor)."""
    if (base / "surfaces").exists():
        return
    for folder, extra in (("bag3", ()), ("lidarbag3", ("--set", "sensor=lidar2d"))):
        sim = base / f"{folder}_sim"
        shutil.rmtree(sim, ignore_errors=True)
        shutil.rmtree(base / folder, ignore_errors=True)
        argv = ("simulate", "diffdrive", "--out", str(sim), "--seconds", "40", *extra)
        subprocess.run(
            sensact_argv(*argv, "--bag", str(base / folder / "robot"), "--bag-format", "sqlite3"), check=True
        )
        shutil.rmtree(sim)
    shutil.rmtree(base / "other", ignore_errors=True)
    shutil.copytree(base / "log", base / "other" / "log")
    tb = ("learn", "em", str(base / "tb.csv"), "--out", str(base / "tb_model.json"), *FIT)
    subprocess.run(sensact_argv(*tb), check=False)  # 3: flagged (max_iterations) is a model all the same
    (base / "surfaces").write_text("")


def _timed(log: Path, folder: Path) -> None:
    """The planar log as a robot's own timed CSVs (`convert csv`): the same rows, the map as its own file."""
    folder.mkdir()
    shutil.copy(log / "actions.csv", folder / "commands.csv")
    shutil.copy(log / "observations.csv", folder / "sightings.csv")
    shutil.copy(log / "groundtruth.csv", folder / "truth.csv")
    marks = json.loads((log / "meta.json").read_text())["landmarks"]
    rows = [f"{m['id']},{m['x_mm']},{m['y_mm']}" for m in marks]
    (folder / "landmarks.csv").write_text("\n".join(["id,x_mm,y_mm", *rows]) + "\n")


def _bags(base: Path, t: np.ndarray, cmd: np.ndarray, pos: np.ndarray, rng: np.random.Generator) -> None:
    """bag/robot.bag (ROS 1: /cmd_vel, tags on /tf, /tf_static, /mocap/pose) with bag/map.csv, the same robot's
    ROS 2 MCAP bag folder bag2/robot/ (with bag2/map.csv), and bag1d.bag: the Turtlebot-style robot's /cmd_vel and
    one sonar as sensor_msgs/Range."""
    from sensact.io.rosbag_write import Msgs, write_bag

    for folder, fmt, name in (("bag", "ros1", "robot.bag"), ("bag2", "mcap", "robot")):
        sim = base / f"{folder}_sim"
        bag_args = ("--bag", str(base / folder / name), "--bag-format", "mcap") if fmt == "mcap" else ()
        bag_args = bag_args or ("--bag", str(base / folder / name))
        argv = sensact_argv("simulate", "diffdrive", "--out", str(sim), "--seconds", "40", *bag_args)
        subprocess.run(argv, check=True)
        shutil.rmtree(sim)
    m = Msgs("ros1")
    msgs = []
    for ti, ci, pi in zip(t, cmd, pos, strict=True):
        ns = 1_700_000_000 * 10**9 + round(ti * 1e9)
        msgs.append(("/cmd_vel", "geometry_msgs/msg/Twist", ns, m.twist(ci, 0.0)))
        msgs.append(("/sonar", "sensor_msgs/msg/Range", ns + 1_000_000, m.range(ns, pi + rng.normal(0, 0.02))))
    write_bag(base / "bag1d.bag", "ros1", msgs, m)


def _mrclam(folder: Path, rng: np.random.Generator) -> None:
    """A minute of a made-up MRCLAM robot 1 (the dataset's five files, its column layout and units): it
    circles among 15 landmarks and sees each within 4 m ahead of it."""
    folder.mkdir()
    t = 1248272262.0 + np.arange(0.0, 60.0, 0.02)
    v, w = np.full(t.size, 0.2), np.full(t.size, 0.1)
    th = np.cumsum(w) * 0.02
    x, y = np.cumsum(v * np.cos(th)) * 0.02, np.cumsum(v * np.sin(th)) * 0.02
    marks = rng.uniform(-4, 4, (15, 2))

    def dat(name: str, rows: np.ndarray) -> None:
        (folder / name).write_text(
            "# made up for the fuzz suite\n" + "\n".join(" ".join(f"{v:.6f}" for v in r) for r in rows) + "\n"
        )

    dat("Robot1_Odometry.dat", np.column_stack([t, v, w]))
    dat("Robot1_Groundtruth.dat", np.column_stack([t, x, y, th]))
    dat("Barcodes.dat", np.column_stack([np.arange(1, 21), 100 + np.arange(1, 21)]))
    dat("Landmark_Groundtruth.dat", np.column_stack([np.arange(6, 21), marks, np.full((15, 2), 0.001)]))
    seen = []
    for k in range(0, t.size, 25):
        for j, (mx, my) in enumerate(marks):
            r = float(np.hypot(mx - x[k], my - y[k]))
            b = float(np.angle(np.exp(1j * (np.arctan2(my - y[k], mx - x[k]) - th[k]))))
            if 0.3 < r < 4.0 and abs(b) < 0.6:
                seen.append((t[k], 106 + j, r + rng.normal(0, 0.03), b + rng.normal(0, 0.01)))
    dat("Robot1_Measurement.dat", np.array(seen))


# ---- the cases --------------------------------------------------------------------------------------------------

CSV_BYTES = ("truncate", "empty", "non_utf8", "binary")
CSV_ROWS_REFUSED = ("reverse", "shuffle", "duplicate", "swap", "one_row", "header_only", "drop_column", "extra_cell")
CSV_ROWS_REFUSED += ("short_row", "last_far")
CELLS_REFUSED = ("nan", "inf", "-inf", "1e308", "-1e308", "abc", "0x1F", "1e400")


def _csv_cases(
    target: str,
    argv: tuple[str, ...],
    columns: int,
    time_column: bool = True,
    fine: tuple[str, ...] = (),
    names: tuple[int, ...] = (),
) -> list[Case]:
    """``fine``: row mutations that leave a well-formed file of this kind (a truth without its heading);
    ``names``: columns of names, where any text is a name (a landmark called "nan" is one)."""
    # a CSV cut at a row's end is a shorter well-formed one: any clean ending will do
    out = [Case(f"{target}:{k}", target, bytes_mutation(k), argv, k != "truncate") for k in CSV_BYTES]
    out.append(Case(f"{target}:crlf_bom", target, bytes_mutation("crlf_bom"), argv, False))
    out += [Case(f"{target}:{k}", target, reorder(k), argv, k not in fine) for k in CSV_ROWS_REFUSED]
    for c in range(columns):
        if c not in names:
            out += [Case(f"{target}:col{c}={v}", target, set_cell(c, v), argv, True) for v in CELLS_REFUSED]
    if time_column:
        out.append(Case(f"{target}:time_in_ms", target, map_column(0, scale=1000.0), argv, "time_in_ms" not in fine))
        out.append(
            Case(f"{target}:clock_shifted", target, map_column(0, offset=1e5), argv, "clock_shifted" not in fine)
        )
    return out


def cases() -> list[Case]:
    em = ("learn", "em", "{work}/log", "--out", "{out}/m.json", *FIT)
    out: list[Case] = []
    out += _csv_cases("log/actions.csv", em, 3)
    # a sighting outside the commands' span is dropped, as one before the first command is
    out += _csv_cases("log/observations.csv", em, 4, fine=("last_far",))
    out.append(Case("log/observations.csv:constant", "log/observations.csv", reorder("constant"), em, False))
    # a truth may lack its heading, and one row past the end is never read
    out += _csv_cases("log/groundtruth.csv", em, 4, fine=("drop_column", "last_far"))
    meta = "log/meta.json"
    for field, values in {
        "dt_s": ["abc", 0, -1, 1e-9, 1e9, None, [1], float("nan"), float("inf")],
        "geometry": ["sideways", 3, None],
        "version": [99, "x"],
    }.items():
        out += [Case(f"{meta}:{field}={v!r}", meta, json_set((field,), v), em, True) for v in values]
    for k, v in (("x_mm", float("nan")), ("y_mm", float("inf")), ("x_mm", "abc"), ("id", None)):
        out.append(Case(f"{meta}:landmark {k}={v!r}", meta, json_set(("landmarks", 0, k), v), em, True))
    out.append(Case(f"{meta}:no landmarks", meta, json_set(("landmarks",), []), em, True))
    out.append(Case(f"{meta}:no observations", meta, json_drop(("observations",)), em, True))
    out += [Case(f"{meta}:{k}", meta, bytes_mutation(k), em, True) for k in ("truncate", "empty", "non_utf8", "binary")]
    out.append(Case(f"{meta}:deep", meta, deep_json, em, True))
    cfg = "log/em_config.yaml"
    out += [Case(f"{cfg}:{k}", cfg, bytes_mutation(k), em, True) for k in ("non_utf8", "binary")]
    out.append(Case(f"{cfg}:deep", cfg, deep_yaml, em, True))
    for line in ("max_iterations: 1e12", "max_iterations: -1", "max_iterations: abc", "bogus_field: 1", "seed: -1"):
        out.append(Case(f"{cfg}:{line}", cfg, yaml_line(line), em, True))
    model_cmds = {
        "localize": ("localize", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/p.json"),
        "monitor": ("monitor", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/mon.json"),
        "export": ("export", "{work}/model.json", "--format", "robot-localization", "--out", "{out}/rl.yaml"),
    }
    model_mutations: dict[str, Mutation] = {
        "truncate": bytes_mutation("truncate"),
        "non_utf8": bytes_mutation("non_utf8"),
        "deep": deep_json,
        "dt_s=abc": json_set(("dt_s",), "abc"),
        "dt_s=0": json_set(("dt_s",), 0),
        "no model": json_drop(("model",)),
        "prior_cov not PD": json_set(("model", "prior_cov"), [[1, 2, 0], [2, 1, 0], [0, 0, 1]]),
        "prior_mean NaN": json_set(("model", "prior_mean"), [float("nan"), 0, 0]),
        "motion_sd negative": json_set(("model", "motion_sd"), [[-1, 1, 0.01]]),
        "sigma NaN": json_set(("model", "sensor", "channels", 0, "sigma"), float("nan")),
        "sigma 0": json_set(("model", "sensor", "channels", 0, "sigma"), 0),
        "delay 1e9": json_set(("model", "action", "delay_steps"), 1e9),
        "coefficients NaN": json_set(("model", "action", "coefficients", 0, 0), float("nan")),
        "coefficients short": json_set(("model", "action", "coefficients"), [[1.0]]),
    }
    model_cmds |= {
        "evaluate log": ("evaluate", "log", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/e.json"),
        "evaluate fleet": ("evaluate", "fleet", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/f.json"),
        "export tum": ("export", "{work}/model.json", "--format", "tum", "--out", "{out}/m.tum"),
    }
    for cname, argv in model_cmds.items():
        out += [Case(f"model.json:{k} ({cname})", "model.json", m, argv, True) for k, m in model_mutations.items()]
    out += _other_commands()
    tb = ("learn", "em", "{work}/tb.csv", "--out", "{out}/m.json", *FIT)
    # a Turtlebot CSV without one IR column, or on another clock's zero (one file: no other clock to meet)
    out += _csv_cases("tb.csv", tb, 5, fine=("drop_column", "clock_shifted"))
    out.append(Case("tb.csv:never moves", "tb.csv", set_all(2, "0"), tb, False))
    track = ("convert", "track", "{work}/track.csv", "--out", "{out}/trk")
    # a robot's own CSV may come out of order (its threads log so): sorted by time, it is the same log
    out += _csv_cases("track.csv", track, 4, fine=("clock_shifted", "reverse", "shuffle", "swap"))
    timed = (
        "convert", "csv", "--commands", "{work}/timed/commands.csv", "--sightings", "{work}/timed/sightings.csv",
        "--landmarks", "{work}/timed/landmarks.csv", "--truth", "{work}/timed/truth.csv", "--out", "{out}/t",
    )  # fmt: skip
    # a robot's own CSVs may come out of order (its threads log so): sorted by time, they are the same log
    in_any_order = ("reverse", "shuffle", "swap", "last_far")
    out += _csv_cases("timed/commands.csv", timed, 3, fine=(*in_any_order, "one_row", "drop_column"))
    # a sighting of a landmark not on the map is dropped and counted, as `convert csv` documents
    out += _csv_cases("timed/sightings.csv", timed, 4, fine=(*in_any_order, "one_row", "drop_column"), names=(1,))
    out += _csv_cases(
        "timed/landmarks.csv", timed, 3, time_column=False, fine=("reverse", "shuffle", "swap", "last_far"), names=(0,)
    )
    mrclam = ("convert", "mrclam", "{work}/mrclam", "--robot", "1", "--out", "{out}/m")
    for name in ("Robot1_Odometry.dat", "Robot1_Measurement.dat", "Robot1_Groundtruth.dat", "Landmark_Groundtruth.dat"):
        target = f"mrclam/{name}"
        out += [
            Case(f"{target}:{k}", target, bytes_mutation(k), mrclam, True, k == "truncate")
            for k in ("truncate", "empty", "non_utf8", "binary")
        ]
        out += [Case(f"{target}:{v}", target, dat_cell(1, v), mrclam, True) for v in ("nan", "inf", "abc")]
    out.append(Case("mrclam/odometry:late row", "mrclam/Robot1_Odometry.dat", dat_late_row, mrclam, True))
    out.append(
        Case("mrclam/measurement:negative range", "mrclam/Robot1_Measurement.dat", dat_cell(2, "-1"), mrclam, True)
    )
    calib = ("learn", "car", "{work}/car", "--factory-calibration", "{work}/calib.yaml", "--out", "{out}/c.json")
    for k, m in {
        "num_lasers=1e8": lambda d: d.replace(b"num_lasers: 64", b"num_lasers: 100000000"),
        "non_utf8": bytes_mutation("non_utf8"),
        "deep": deep_yaml,
        "rot nan": lambda d: re.sub(rb"rot_correction: [-0-9.e]+", b"rot_correction: .nan", d, count=1),
        "no lasers": lambda d: b"num_lasers: 64\ndistance_resolution: 0.002\n",
    }.items():
        out.append(Case(f"calib.yaml:{k}", "calib.yaml", m, calib, True))
    car = ("learn", "car", "{work}/car", "--out", "{out}/car.json", "--no-report")
    out += [
        Case(f"car/actions.csv:{k}", "car/actions.csv", bytes_mutation(k), car, True, k == "truncate")
        for k in ("truncate", "empty", "non_utf8")
    ]
    out += [
        Case(f"car/actions.csv:{k}", "car/actions.csv", reorder(k), car, True)
        for k in ("reverse", "duplicate", "one_row", "drop_column")
    ]
    out += [
        Case(f"car/actions.csv:col1={v}", "car/actions.csv", set_cell(1, v), car, True) for v in ("nan", "1e308", "x")
    ]
    # one control row long after the capture is left out, as a row before it is
    out.append(Case("car/actions.csv:last_far", "car/actions.csv", reorder("last_far"), car, False))
    out.append(Case("car/actions.csv:time_in_ms", "car/actions.csv", map_column(0, scale=1000.0), car, True))
    out.append(Case("car/actions.csv:clock_shifted", "car/actions.csv", map_column(0, offset=1e5), car, True))
    out.append(Case("car/groundtruth.csv:reverse", "car/groundtruth.csv", reorder("reverse"), car, True))
    damaged = ("rotation_damaged", "block_id_damaged", "sensor_stamp_damaged", "capture_time_damaged")
    for k in (
        "duplicate_packets",
        "reverse_packets",
        "few_packets",
        "bad_length",
        "zero_time",
        "zero_incl_len",
        *damaged,
    ):
        # a packet captured twice is read once: the same capture, the same result
        out.append(Case(f"car/velodyne.pcap:{k}", "car/velodyne.pcap", pcap_mutation(k), car, k != "duplicate_packets"))
    # a capture with dropped packets is well formed: learned (exit 0), or flagged (exit 3) where the scan
    # matching fails across the empty firings, which depends on the town the lasers see
    out.append(
        Case("car/velodyne.pcap:dropped_packets", "car/velodyne.pcap", pcap_mutation("dropped_packets"), car, False)
    )
    out += [
        Case(f"car/velodyne.pcap:{k}", "car/velodyne.pcap", bytes_mutation(k), car, True, k == "truncate")
        for k in ("truncate", "empty", "binary")
    ]
    out += [
        Case(f"car/velodyne.pcap:{k}", "car/velodyne.pcap", pcapng_mutation(k), car, k != "as_pcapng")
        for k in ("as_pcapng", "pcapng_truncate", "pcapng_bad_block_length")
    ]
    for folder, kinds in (("car16", ("vlp16_block_id", "vlp16_rotation", "dual_return")), ("os1", ("os1_encoder",))):
        unit_car = ("learn", "car", "{work}/" + folder, "--out", "{out}/car.json", "--no-report")
        for k in kinds:
            out.append(Case(f"{folder}/velodyne.pcap:{k}", f"{folder}/velodyne.pcap", unit_mutation(k), unit_car, True))
    # an OS-1's capture without the metadata that gives its beams' altitudes
    os1 = ("learn", "car", "{work}/os1", "--out", "{out}/car.json", "--no-report")
    out.append(Case("os1/meta.json:no_altitudes", "os1/meta.json", json_drop(("lidar", "vertical_deg")), os1, True))
    for field, v in (("time_origin_s", float("nan")), ("firing_hz", 0), ("rpm", "abc"), ("vertical_deg", [])):
        out.append(
            Case(f"car/meta.json:lidar.{field}={v!r}", "car/meta.json", json_set(("lidar", field), v), car, True)
        )
    out.append(Case("car/meta.json:deep", "car/meta.json", deep_json, car, True))
    out += _bag_cases()
    out += _lidar_cases()
    out += _issue95_cases()
    out += _surface_cases()
    for sub in ("diffdrive", "track1d", "field2d"):
        for arg, v in (("--seconds", "nan"), ("--seconds", "inf"), ("--seconds", "-1"), ("--seconds", "1e12")):
            out.append(Case(f"simulate {sub} {arg} {v}", "", None, ("simulate", sub, "--out", "{out}/s", arg, v), True))
        out.append(
            Case(f"simulate {sub} --seed -1", "", None, ("simulate", sub, "--out", "{out}/s", "--seed", "-1"), True)
        )
    for name, path in (("a device", "/dev/full"), ("a folder", "{out}"), ("a figure's name", "{out}/m.png")):
        out.append(Case(f"learn em --out {name}", "", None, ("learn", "em", "{work}/log", "--out", path, *FIT), True))
    out.append(
        Case(
            "monitor --out and --relearn the same",
            "",
            None,
            (*model_cmds["monitor"][:4], "--out", "{out}/x.json", "--relearn", "{out}/x.json"),
            True,
        )
    )
    return out


def _other_commands() -> list[Case]:
    """The log mutations a model is scored or a path smoothed on, the Turtlebot CSV's through Algorithm 1, a
    fleet with one bad log among good ones, and wrong arguments (click's usage errors, reproduce's)."""
    out = []
    model = "{work}/model.json"
    readers = {
        "evaluate log": ("evaluate", "log", "{work}/log", "--model", model, "--out", "{out}/e.json"),
        "localize": ("localize", "{work}/log", "--model", model, "--out", "{out}/p.json"),
        "monitor": ("monitor", "{work}/log", "--model", model, "--out", "{out}/mon.json"),
    }
    log_mutations: dict[str, tuple[str, Mutation]] = {
        "actions nan": ("log/actions.csv", set_cell(1, "nan")),
        "actions reversed": ("log/actions.csv", reorder("reverse")),
        "actions late row": ("log/actions.csv", reorder("last_far")),
        "observations inf": ("log/observations.csv", set_cell(2, "inf")),
        "meta dt_s 1e-9": ("log/meta.json", json_set(("dt_s",), 1e-9)),
    }
    for cname, argv in readers.items():
        for k, (target, m) in log_mutations.items():
            out.append(Case(f"{target}:{k} ({cname})", target, m, argv, True))
    # the issue's "all-NaN or shuffled ground truth is scored as valid"
    truth = "log/groundtruth.csv"
    for k, m in {"shuffled": reorder("shuffle"), "all nan": set_all(1, "nan"), "reversed": reorder("reverse")}.items():
        out.append(Case(f"{truth}:{k} (evaluate log)", truth, m, readers["evaluate log"], True))
    boot = ("learn", "bootstrap", "{work}/tb.csv", "--out", "{out}/b.json", "--no-report")
    for k, m in {
        "time 1e9": reorder("last_far"),
        "sonar nan": set_cell(3, "nan"),
        "sonar 1e308": set_cell(3, "1e308"),
        "reversed": reorder("reverse"),
        "one row": reorder("one_row"),
        "truncate": bytes_mutation("truncate"),
    }.items():
        out.append(Case(f"tb.csv:{k} (learn bootstrap)", "tb.csv", m, boot, k != "truncate"))
    out.append(Case("tb.csv:never moves (learn bootstrap)", "tb.csv", set_all(2, "0"), boot, False))
    out.append(Case("tb.csv:sonar constant (learn bootstrap)", "tb.csv", set_all(3, "1.0"), boot, False))
    fleet = ("fleet", "learn", "{work}/log", "{work}/tb.csv", "--out", "{out}/fl", "--workers", "1", *FIT)
    fleet += ("--no-cross-scores",)
    # one bad log among good ones: the others are learned, the bad one named (exit 3: some failed)
    for target, m in (("log/actions.csv", set_cell(1, "nan")), ("tb.csv", reorder("last_far"))):
        out.append(Case(f"{target}:bad log in a fleet", target, m, fleet, True, flagged_ok=True))
    alone = ("fleet", "learn", "{work}/log", "--out", "{out}/fl", "--workers", "1", *FIT)  # every log bad: exit 2
    out.append(Case("log/actions.csv:a fleet of one bad log", "log/actions.csv", reorder("reverse"), alone, True))
    args = {
        "learn em --bins abc": ("learn", "em", "{work}/tb.csv", "--bins", "abc"),
        "learn em --bogus": ("learn", "em", "{work}/log", "--bogus", "1"),
        "learn em no log": ("learn", "em"),
        "learn em --set nonsense": ("learn", "em", "{work}/log", "--set", "nonsense"),
        "localize --start nan,0,0": ("localize", "{work}/log", "--model", model, "--start", "nan,0,0"),
        "localize --start 1,2,3,4": ("localize", "{work}/log", "--model", model, "--start", "1,2,3,4"),
        "reproduce --trials abc": ("reproduce", "track1d", "--out", "{out}/r", "--trials", "abc"),
        "reproduce --trials -1": ("reproduce", "track1d", "--out", "{out}/r", "--trials", "-1"),
        "reproduce --trials 1e9": ("reproduce", "track1d", "--out", "{out}/r", "--trials", "1000000000"),
        "reproduce nonsense": ("reproduce", "nonsense", "--out", "{out}/r"),
        "reproduce --data missing": ("reproduce", "real", "--out", "{out}/r", "--data", "{out}/none"),
        "fleet learn --workers 0": ("fleet", "learn", "{work}/log", "--out", "{out}/fl", "--workers", "0"),
        "evaluate fleet no model": ("evaluate", "fleet", "{work}/log"),
        "export --format bogus": ("export", model, "--format", "bogus", "--out", "{out}/x"),
        "export velodyne of an EM model": ("export", model, "--format", "velodyne", "--out", "{out}/x.yaml"),
        "convert bag --dt nan": ("convert", "bag", "{work}/bag/robot.bag", "--landmarks", "{work}/bag/map.csv",
                                 "--out", "{out}/b", "--dt", "nan"),
        "convert bag --commands /nope": ("convert", "bag", "{work}/bag/robot.bag", "--landmarks",
                                         "{work}/bag/map.csv", "--out", "{out}/b", "--commands", "/nope"),
        "convert bag --readings /tf": ("convert", "bag", "{work}/bag/robot.bag", "--out", "{out}/b",
                                       "--readings", "/tf"),
        "unknown command": ("calibrate-everything",),
    }  # fmt: skip
    out += [Case(name, "", None, argv, True) for name, argv in args.items()]
    velodyne = ("export", "{work}/car_model.json", "--format", "velodyne", "--out", "{out}/v.yaml")
    out.append(Case("car_model.json: as written (export velodyne)", "", None, velodyne, False))
    for k, m in {
        "num_lasers 1e8": json_set(("velodyne_calibration", "num_lasers"), 100_000_000),
        "rot nan": json_set(("velodyne_calibration", "lasers", 3, "rot_correction"), float("nan")),
        "rot abc": json_set(("velodyne_calibration", "lasers", 3, "rot_correction"), "abc"),
        "lasers not a list": json_set(("velodyne_calibration", "lasers"), {"a": 1}),
        "distance_resolution -1": json_set(("velodyne_calibration", "distance_resolution"), -1),
        "no calibration": json_drop(("velodyne_calibration",)),
    }.items():
        out.append(Case(f"car_model.json:{k} (export velodyne)", "car_model.json", m, velodyne, True))
    tum = ("export", model, "--format", "tum", "--out", "{out}/m.tum")
    for k, m in {
        "truncate": bytes_mutation("truncate"),
        "binary": bytes_mutation("binary"),
        "empty": bytes_mutation("empty"),
        "a pose nan": npz_set("mean", (5, 0), float("nan")),
        "times reversed": npz_map("time_s", lambda a: a[::-1].copy()),
        "a pose short": npz_map("mean", lambda a: a[:-1]),
    }.items():
        out.append(Case(f"model.path.npz:{k} (export tum)", "model.path.npz", m, tum, True))
    out.append(
        Case("reproduce --seed -1", "", None, ("reproduce", "track1d", "--out", "{out}/r", "--seed", "-1"), True)
    )
    return out


def _npz_edit(edit: Callable[[dict[str, np.ndarray]], None]) -> Mutation:
    def m(data: bytes) -> bytes:
        import io

        with np.load(io.BytesIO(data)) as z:
            arrays = {k: z[k] for k in z.files}
        edit(arrays)
        buf = io.BytesIO()
        np.savez(buf, **arrays)
        return buf.getvalue()

    return m


def npz_set(key: str, index: tuple[int, ...], value: float) -> Mutation:
    def edit(a: dict[str, np.ndarray]) -> None:
        a[key] = a[key].astype(np.float64)
        a[key][index] = value

    return _npz_edit(edit)


def npz_map(key: str, f: Callable[[np.ndarray], np.ndarray]) -> Mutation:
    def edit(a: dict[str, np.ndarray]) -> None:
        a[key] = f(a[key])

    return _npz_edit(edit)


OPTICAL = "camera_color_optical_frame"  # rosbag_write's camera frame


def _bag_cases() -> list[Case]:
    bag = ("convert", "bag", "{work}/bag/robot.bag", "--landmarks", "{work}/bag/map.csv", "--out", "{out}/b")
    mcap = ("convert", "bag", "{work}/bag2/robot", "--landmarks", "{work}/bag2/map.csv", "--out", "{out}/b")
    bag1d = ("convert", "bag", "{work}/bag1d.bag", "--out", "{out}/b")
    nan, inf = float("nan"), float("inf")
    tag_x, tag_frame = "transforms.0.transform.translation.x", "transforms.0.child_frame_id"
    static = "transforms.1.transform"  # the camera link to its optical frame
    out = [
        Case(f"bag/robot.bag:{k}", "bag/robot.bag", bytes_mutation(k), bag, True, k == "truncate")
        for k in ("truncate", "empty", "binary")
    ]
    out.append(Case("bag/robot.bag:bytes flipped", "bag/robot.bag", flip_bytes, bag, True, True))
    out += [
        Case(f"bag2/robot/robot.mcap:{k}", "bag2/robot/robot.mcap", bytes_mutation(k), mcap, True, k == "truncate")
        for k in ("truncate", "empty", "binary")
    ]
    out.append(Case("bag2/robot/robot.mcap:bytes flipped", "bag2/robot/robot.mcap", flip_bytes, mcap, True, True))
    # a few bytes damaged inside the messages, past an index that still opens: refused where rosbags cannot
    # read a message or a number is absurd, read where the damage left plausible numbers (no check can tell)
    for seed in range(4):
        for target, argv in (("bag/robot.bag", bag), ("bag2/robot/robot.mcap", mcap)):
            out.append(Case(f"{target}:damaged inside ({seed})", target, damage(seed), argv, False))
    meta = "bag2/robot/metadata.yaml"
    out += [Case(f"{meta}:{k}", meta, bytes_mutation(k), mcap, True) for k in ("truncate", "empty", "non_utf8")]
    out.append(Case(f"{meta}:deep", meta, deep_yaml, mcap, True))
    edits: dict[str, tuple[Mutation, bool]] = {  # name: (mutation, refuse)
        "cmd v=nan": (on("/cmd_vel", _set("linear.x", nan)), True),
        "cmd v=inf": (on("/cmd_vel", _set("linear.x", inf)), True),
        "cmd v=1e308": (on("/cmd_vel", _set("linear.x", 1e308)), True),
        "cmd omega=nan everywhere": (on("/cmd_vel", _set("angular.z", nan), every), True),
        "cmd recorded twice": (bag_twice("/cmd_vel"), True),
        "cmd one message": (bag_keep("/cmd_vel", lambda k: k == 0), True),
        "cmd first tenth only": (bag_keep("/cmd_vel", lambda k: k < 12), True),
        "cmd recorded 1e9 s late": (bag_late("/cmd_vel", 1e9), True),
        "cmd recorded a day early": (bag_late("/cmd_vel", -86400.0), True),
        "tag x=nan": (on("/tf", _set(tag_x, nan)), True),
        "tag x=inf": (on("/tf", _set(tag_x, inf)), True),
        "tag x=1e308": (on("/tf", _set(tag_x, 1e308)), True),
        "tag quaternion zero": (on("/tf", _set("transforms.0.transform.rotation.w", 0.0)), False),
        "tag stamped 10 s back": (on("/tf", _shift_stamp(-10.0)), True),
        "tag stamped 1e8 s on": (on("/tf", _shift_stamp(1e8)), True),
        "tags stamped zero": (on("/tf", _shift_stamp(-1.7e9), every), True),
        "tags on another clock": (on("/tf", _shift_stamp(1e5), every), True),
        "tag named tag36h11:99999999999": (on("/tf", _set(f"{tag_frame}", "tag36h11:99999999999")), False),
        "no tags": (bag_keep("/tf", lambda k: False), True),
        "static quaternion zero": (on("/tf_static", _set(f"{static}.rotation.w", 0.0), every), True),
        "static quaternion nan": (on("/tf_static", _set(f"{static}.rotation.x", nan), every), True),
        "static translation inf": (on("/tf_static", _set("transforms.0.transform.translation.z", inf), every), True),
        "static tree a loop": (on("/tf_static", _set("transforms.0.header.frame_id", OPTICAL), every), True),
        "mocap x=nan": (on("/mocap/pose", _set("pose.position.x", nan)), True),
        "mocap x=1e308": (on("/mocap/pose", _set("pose.position.x", 1e308)), True),
        "mocap quaternion zero": (on("/mocap/pose", _set("pose.orientation.w", 0.0)), True),
        "mocap stamped 1e8 s on": (on("/mocap/pose", _shift_stamp(1e8)), True),
        "mocap stamped 10 s back": (on("/mocap/pose", _shift_stamp(-10.0)), True),
    }  # fmt: skip
    out += [Case(f"bag/robot.bag:{k}", "bag/robot.bag", m, bag, r) for k, (m, r) in edits.items()]
    # a tag's id is a name here too: a map row of a tag never seen is left out
    out += _csv_cases(
        "bag/map.csv", bag, 3, time_column=False, fine=("reverse", "shuffle", "swap", "last_far"), names=(0,)
    )
    range_edits: dict[str, tuple[Mutation, bool]] = {
        # REP 117: a range outside [min_range, max_range] (inf, nan too) is "nothing seen", no garbage
        "range=nan": (on("/sonar", _set("range", nan)), False),
        "range=inf": (on("/sonar", _set("range", inf)), False),
        "range=-1": (on("/sonar", _set("range", -1.0)), False),
        "max_range=nan everywhere": (on("/sonar", _set("max_range", nan), every), True),
        "range constant": (on("/sonar", _set("range", 1.5), every), False),
        "cmd v=nan": (on("/cmd_vel", _set("linear.x", nan)), True),
        "sonar stamped back 10 s": (on("/sonar", _shift_stamp(-10.0)), True),
        # stamps on sim time, recorded on the wall's clock: the Twist is moved onto the stamps' clock
        "sonar stamps from zero": (on("/sonar", _shift_stamp(-1.7e9), every), False),
        "sonar one message": (bag_keep("/sonar", lambda k: k == 0), True),
        "sonar recorded twice": (bag_twice("/sonar"), True),
    }
    out += [Case(f"bag1d.bag:{k}", "bag1d.bag", m, bag1d, r) for k, (m, r) in range_edits.items()]
    return out


def damage(seed: int) -> Mutation:
    """One to seven bytes overwritten at random, from a tenth of the way in (a bad sector, a broken copy)."""

    def m(data: bytes) -> bytes:
        rng = np.random.default_rng(seed)
        b = bytearray(data)
        at = int(rng.integers(len(b) // 10, len(b) - 100))
        for j in range(int(rng.integers(1, 8))):
            b[at + j] = int(rng.integers(0, 256))
        return bytes(b)

    return m


def flip_bytes(data: bytes) -> bytes:
    """Every 997th byte from the middle on inverted (a bad disk or a broken copy)."""
    b = bytearray(data)
    for i in range(len(b) // 2, len(b), 997):
        b[i] ^= 0xFF
    return bytes(b)


def dat_cell(column: int, value: str, row: int = 5) -> Mutation:
    """A whitespace-separated .dat file with one cell replaced (its comment lines kept)."""

    def m(data: bytes) -> bytes:
        lines = data.decode().splitlines()
        cells = lines[row].split()
        cells[column] = value
        lines[row] = " ".join(cells)
        return ("\n".join(lines) + "\n").encode()

    return m


def dat_late_row(data: bytes) -> bytes:
    """One odometry row a year after the rest (a clock that jumped)."""
    lines = data.decode().splitlines()
    cells = lines[-1].split()
    cells[0] = f"{float(cells[0]) + 3.15e7:.6f}"
    return ("\n".join([*lines, " ".join(cells)]) + "\n").encode()


def set_all(column: int, value: str) -> Mutation:
    def m(data: bytes) -> bytes:
        rows = _rows(data)
        for r in rows[1:]:
            r[column] = value
        return _join(rows)

    return m


# ---- running one ----------------------------------------------------------------------------------------------


def _lidar_cases() -> list[Case]:
    """Issue 93's surfaces: the wheels-and-lidar folder's files, its bags (ROS 1 and MCAP) and its model's
    exports."""
    learn = ("learn", "em", "{work}/lidar", "--out", "{out}/m.json", "--no-report")
    out: list[Case] = []
    out += _csv_cases("lidar/wheels.csv", learn, 3)
    # scans: a cut file is a shorter log; the beams' cells (a range beyond range_max is no return, but not 1e308)
    out += _csv_cases("lidar/scans.csv", learn, 3, fine=("drop_column",))  # a scan of one beam fewer is a scan
    for v in ("-5", "2e6"):
        out.append(Case(f"lidar/scans.csv:col1={v}", "lidar/scans.csv", set_cell(1, v), learn, True))
    out.append(Case("lidar/scans.csv:every range empty", "lidar/scans.csv", _blank_ranges, learn, True))
    meta = "lidar/meta.json"
    for path, values in {
        ("scan", "angle_increment_rad"): [0, -0.0, 1.5, "abc", None, float("nan"), 1e9],
        ("scan", "angle_min_rad"): [1e9, None, "x"],
        ("scan", "time_increment_s"): [-1, 1.0, float("inf")],
        ("scan", "range_min_mm"): [-1, 1e9, None],
        ("scan", "range_max_mm"): [0, 100, 1e12],
        ("urdf", "wheel_radius_mm"): [-33, 0, "33", 1e300],
        ("urdf", "axle_mm"): [-160, float("nan")],
        ("urdf", "lidar_mount", "yaw_rad"): [1e9, "x"],
        ("urdf",): ["a string", [1, 2]],
        ("truth",): ["a string", {"drive": [1, 2]}],
        ("kind",): ["planar", None],
    }.items():
        out += [Case(f"{meta}:{'.'.join(path)}={v!r}", meta, json_set(path, v), learn, True) for v in values]
    out.append(Case(f"{meta}:no scan", meta, json_drop(("scan",)), learn, True))
    out += [Case(f"{meta}:{k}", meta, bytes_mutation(k), learn, True) for k in ("truncate", "empty", "binary")]
    # the bags
    bag = ("convert", "bag", "{work}/lidarbag/robot.bag", "--out", "{out}/b")
    mcap = ("convert", "bag", "{work}/lidarbag2/robot", "--out", "{out}/b")
    nan, inf = float("nan"), float("inf")
    edits: dict[str, tuple[Mutation, bool]] = {
        "scan angle_increment=0": (on("/scan", _set("angle_increment", 0.0), every), True),
        "scan angle_increment=nan": (on("/scan", _set("angle_increment", nan), every), True),
        "scan angle_increment=1": (on("/scan", _set("angle_increment", 1.0), every), True),
        "scan angle_min=inf": (on("/scan", _set("angle_min", inf), every), True),
        "scan time_increment=nan": (on("/scan", _set("time_increment", nan), every), True),
        "scan time_increment=1": (on("/scan", _set("time_increment", 1.0), every), True),
        "scan range_max=nan": (on("/scan", _set("range_max", nan), every), True),
        "scan range_max below range_min": (on("/scan", _set("range_max", 0.01), every), True),
        "scan ranges all nan": (on("/scan", _set_ranges(nan), every), True),
        "scan ranges all inf": (on("/scan", _set_ranges(inf), every), True),
        "scan ranges negative": (on("/scan", _set_ranges(-1.0), every), True),
        "scan ranges nan in one": (on("/scan", _set_ranges(nan)), False),
        "scan with fewer beams": (on("/scan", _drop_beams), True),
        "scan stamped 10 s back": (on("/scan", _shift_stamp(-10.0)), True),
        "scan stamped 1e8 s on": (on("/scan", _shift_stamp(1e8)), True),
        "scans stamped zero": (on("/scan", _shift_stamp(-1.7e9), every), True),
        "scan recorded twice": (bag_twice("/scan"), True),
        "scan one message": (bag_keep("/scan", lambda k: k == 0), True),
        "no scans": (bag_keep("/scan", lambda k: False), True),
        "wheel position nan in one": (on("/joint_states", _set_positions(nan)), False),
        "wheel position 1e308": (on("/joint_states", _set_positions(1e308)), True),
        "wheel positions nan everywhere": (on("/joint_states", _set_positions(nan), every), False),
        "wheel joints unnamed": (on("/joint_states", _set("name", ["a", "b"]), every), True),
        "wheel joints stamped 1e8 s on": (on("/joint_states", _shift_stamp(1e8)), True),
        "no joint states": (bag_keep("/joint_states", lambda k: False), False),
        "no joint states nor odom": (_keep_only(("/scan", "/cmd_vel", "/tf_static")), False),
        "only scans": (_keep_only(("/scan",)), True),
        "odom x=nan": (on("/odom", _set("pose.pose.position.x", nan)), True),
        "odom x=1e308": (on("/odom", _set("pose.pose.position.x", 1e308)), True),
        "cmd v=nan": (on("/cmd_vel", _set("linear.x", nan)), True),
        "static lidar x=inf": (on("/tf_static", _set("transforms.1.transform.translation.x", inf), every), True),
        "static quaternion zero": (on("/tf_static", _set("transforms.1.transform.rotation.w", 0.0), every), True),
        "static upside down": (on("/tf_static", _flip_lidar, every), False),
        "truth x=nan": (on("/ground_truth/pose", _set("pose.position.x", nan)), False),
    }  # fmt: skip
    out += [Case(f"lidarbag/robot.bag:{k}", "lidarbag/robot.bag", m, bag, r) for k, (m, r) in edits.items()]
    for k in ("truncate", "empty", "binary"):
        out.append(Case(f"lidarbag/robot.bag:{k}", "lidarbag/robot.bag", bytes_mutation(k), bag, True, k == "truncate"))
        out.append(
            Case(
                f"lidarbag2/robot/robot.mcap:{k}",
                "lidarbag2/robot/robot.mcap",
                bytes_mutation(k),
                mcap,
                True,
                k == "truncate",
            )
        )
    for seed in range(3):
        out.append(Case(f"lidarbag/robot.bag:damaged inside ({seed})", "lidarbag/robot.bag", damage(seed), bag, False))
    for args, refuse in (
        (("--scan", "/odom"), True),
        (("--scan", "/nothing"), True),
        (("--wheels", "/scan"), True),
        (("--wheel-joints", "left"), True),
        (("--wheel-joints", "a,b"), True),
        (("--wheel-joints", "wheel_right_joint,wheel_left_joint"), False),  # read the other way round, with a note
        (("--receive-times",), False),
    ):
        out.append(Case(f"convert bag lidar {' '.join(args)}", "", None, (*bag, *args), refuse))
    # the model's exports
    model = "lidar_model.json"
    for fmt in ("urdf", "robot-localization"):
        export = ("export", "{work}/" + model, "--format", fmt, "--out", "{out}/e")
        for path, v in (
            (("lidar", "mount", "forward_mm"), float("nan")),
            (("lidar", "mount", "forward_mm"), 1e300),
            (("lidar", "mount", "yaw_rad"), 1e9),
            (("lidar", "mount", "left_mm"), "x"),
            (("drive", "axle_mm"), 0),
            (("drive", "wheel_radius_left_mm"), -33.0),
            (("drive", "noise", "variance_per_mm"), [1, 2]),
            (("drive", "noise", "variance_per_mm"), [-1, 0, 0]),
            (("drive", "noise"), "x"),
            (("fit", "speed_mm_s"), float("inf")),
            (("lidar",), None),
            (("drive",), [1]),
        ):
            garbage = fmt == "robot-localization" or "noise" not in path  # the URDF holds no noise
            out.append(Case(f"{model}:{fmt}:{'.'.join(path)}={v!r}", model, json_set(path, v), export, garbage))
        out += [Case(f"{model}:{fmt}:{k}", model, bytes_mutation(k), export, True) for k in ("truncate", "empty")]
    for fmt in ("tum", "velodyne", "landmarks"):
        out.append(
            Case(
                f"{model}:as {fmt}", "", None, ("export", "{work}/" + model, "--format", fmt, "--out", "{out}/e"), True
            )
        )
    for cmd in (
        ("localize", "{work}/lidar", "--model", "{work}/" + model),
        ("monitor", "{work}/lidar", "--model", "{work}/" + model),
    ):
        out.append(Case(f"{cmd[0]} with a lidar model", "", None, cmd, True))
    out.append(
        Case(
            "learn em lidar --out its own scans",
            "",
            None,
            ("learn", "em", "{work}/lidar", "--out", "{work}/lidar/scans.csv"),
            True,
        )
    )
    out.append(Case("learn em lidar --halves", "", None, (*learn, "--halves"), True))
    return out


def _issue95_cases() -> list[Case]:
    """Issue 95's held-out list for the older readers, each as a case: units a column does not say, steps no
    sensor logs at, settings out of range, models a newer sensact wrote, a map of one point, an alias bomb."""
    tb = ("learn", "em", "{work}/tb.csv", "--out", "{out}/m.json", *FIT)
    boot = ("learn", "bootstrap", "{work}/tb.csv", "--out", "{out}/b.json", "--no-report")
    track = ("convert", "track", "{work}/track.csv", "--out", "{out}/trk")
    mrclam = ("convert", "mrclam", "{work}/mrclam", "--robot", "1", "--out", "{out}/m")
    car = ("learn", "car", "{work}/car", "--out", "{out}/car.json", "--no-report")
    evaluate = ("evaluate", "log", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/e.json")
    em = ("learn", "em", "{work}/log", "--out", "{out}/m.json", *FIT)
    out: list[Case] = []
    for argv, what in ((tb, "learn em"), (boot, "learn bootstrap")):
        for name, m in (
            ("sonar in mm", map_column(3, scale=1000.0)),
            ("sonar negative", map_column(3, scale=-1.0)),
            ("time in microseconds as seconds", map_column(0, scale=1e-6)),
            ("command in mm/s", map_column(2, scale=1000.0)),
        ):
            out.append(Case(f"tb.csv:{name} ({what})", "tb.csv", m, argv, True))
    for setting in ("sensor_degree=50", "action_degree=-1", "t_start_s=1e9", "degree_max=99"):
        out.append(Case(f"learn bootstrap --set {setting}", "", None, (*boot, "--set", setting), True))
    out.append(Case("track.csv:sonar in um", "track.csv", map_column(3, scale=1000.0), track, True))
    out.append(Case("track.csv:sonar empty", "track.csv", set_all(3, ""), track, True))
    out.append(Case("mrclam/odometry:one line", "mrclam/Robot1_Odometry.dat", _first_rows(1), mrclam, True))
    for dt in ("inf", "1e9", "1e-12"):
        out.append(Case(f"convert mrclam --dt {dt}", "", None, (*mrclam, "--dt", dt), True))
    for setting in ("max_iterations=-1", "max_iterations=0", "dt_s=0", "dt_s=-1", "voxel_m=0", "voxel_m=-1",
                    "min_pairs=0", "outlier_m=-1", "tolerance=0"):  # fmt: skip
        out.append(Case(f"learn car --set {setting}", "", None, (*car, "--set", setting), True))
    for path, v in (
        (("model", "action", "delay_steps"), 2.5),
        (("sensact_version",), "99.0.0"),
        (("sensact_version",), "not a version"),
        (("summary", "config", "bogus_field"), 1),
        (("summary", "config"), "a string"),
    ):
        out.append(
            Case(f"model.json:{'.'.join(path)}={v!r} (evaluate log)", "model.json", json_set(path, v), evaluate, True)
        )
    out.append(Case("log/meta.json:all landmarks at one point", "log/meta.json", _one_point_map, em, True))
    out.append(
        Case(
            "settings.yaml:billion laughs",
            "settings.yaml",
            lambda d: LAUGHS,
            (*em, "--config", "{work}/settings.yaml"),
            True,
        )
    )
    out.append(
        Case(
            "settings.yaml:nested list",
            "settings.yaml",
            lambda d: b"max_iterations: [[1, 2], [3]]\n",
            (*em, "--config", "{work}/settings.yaml"),
            True,
        )
    )
    return out


def _surface_cases() -> list[Case]:
    """Issue 95's new surfaces: ROS 2 sqlite3 bags, `--uncertainty`, `fleet learn`, `monitor`, `localize`, every
    export format, and the other lidars' calibrations, each with what must never happen: an input written
    over, two outputs on one path, a fleet's outputs outside its --out, an option unbounded before allocating."""
    nan, inf = float("nan"), float("inf")
    out: list[Case] = []
    bag3 = ("convert", "bag", "{work}/bag3/robot", "--landmarks", "{work}/bag3/map.csv", "--out", "{out}/b")
    db3 = "bag3/robot/robot.db3"
    out.append(Case("bag3/robot: as recorded (sqlite3)", "", None, bag3, False))
    out += [
        Case(f"{db3}:{k}", db3, bytes_mutation(k), bag3, True, k == "truncate") for k in ("truncate", "empty", "binary")
    ]
    out.append(Case(f"{db3}:bytes flipped", db3, flip_bytes, bag3, True, True))
    out += [Case(f"{db3}:damaged inside ({seed})", db3, damage(seed), bag3, False) for seed in range(3)]
    for k, sql, refuse in (
        ("cmd typed as ROS 1's name", "UPDATE topics SET type='geometry_msgs/Twist' WHERE name='/cmd_vel'", True),
        ("cmd typed as a custom type", "UPDATE topics SET type='my_msgs/msg/Drive' WHERE name='/cmd_vel'", True),
        ("no cmd messages", "DELETE FROM messages WHERE topic_id=(SELECT id FROM topics WHERE name='/cmd_vel')", True),
        ("every stamp equal", "UPDATE messages SET timestamp=1700000000000000000", True),
        ("cmd payloads cut", "UPDATE messages SET data=substr(data, 1, 8) WHERE topic_id="
         "(SELECT id FROM topics WHERE name='/cmd_vel')", True),
    ):  # fmt: skip
        out.append(Case(f"{db3}:{k}", db3, sqlite_edit(sql), bag3, refuse))
    meta3 = "bag3/robot/metadata.yaml"
    out += [Case(f"{meta3}:{k}", meta3, bytes_mutation(k), bag3, True) for k in ("truncate", "empty", "non_utf8")]
    out.append(Case(f"{meta3}:deep", meta3, deep_yaml, bag3, True))
    out.append(Case(f"{meta3}:billion laughs", meta3, lambda d: LAUGHS, bag3, True))
    # a map in millimetres (the issue's 1.22 GiB grid): refused by its unit, before any allocation
    for col in (1, 2):
        out.append(Case(f"bag3/map.csv:col{col} in mm", "bag3/map.csv", map_column(col, scale=1000.0), bag3, True))
    # a camera sees nothing behind it: detections there are dropped, a bag of mostly such refused
    bag = ("convert", "bag", "{work}/bag/robot.bag", "--landmarks", "{work}/bag/map.csv", "--out", "{out}/b")
    behind = on("/tf", _set("transforms.0.transform.translation.z", -1.0), every)
    out.append(Case("bag/robot.bag:every tag behind the camera", "bag/robot.bag", behind, bag, True))
    mapping = ("--mapping", "{work}/settings.yaml")
    for k, text in (("nested list", b"commands: [[/cmd_vel]]\n"), ("a number", b"readings: 7\n"),
                    ("unknown role", b"sonar: /cmd_vel\n"), ("no such topic", b"commands: /nope\n")):  # fmt: skip
        out.append(
            Case(f"settings.yaml:bag mapping {k}", "settings.yaml", lambda d, t=text: t, (*bag3, *mapping), True)
        )
    lidar3 = ("convert", "bag", "{work}/lidarbag3/robot", "--out", "{out}/l")
    ldb3 = "lidarbag3/robot/robot.db3"
    out.append(Case("lidarbag3/robot: as recorded (sqlite3)", "", None, lidar3, False))
    out += [Case(f"{ldb3}:{k}", ldb3, bytes_mutation(k), lidar3, True, k == "truncate") for k in ("truncate", "empty")]
    for k, sql in (
        ("no scans", "DELETE FROM messages WHERE topic_id=(SELECT id FROM topics WHERE name='/scan')"),
        ("no wheels", "DELETE FROM messages WHERE topic_id=(SELECT id FROM topics WHERE name='/joint_states')"),
        ("scan typed as a custom type", "UPDATE topics SET type='my_msgs/msg/Scan' WHERE name='/scan'"),
    ):
        out.append(Case(f"{ldb3}:{k}", ldb3, sqlite_edit(sql), lidar3, True))
    # --uncertainty: bounded before allocating, a scheduler that is no address refused before any work
    um = ("learn", "em", "{work}/log", "--out", "{out}/m.json", *FIT, "--uncertainty")
    for v in ("0", "-1", "1000000000", "99999999999999999999", "abc", "nan", "2.5"):
        out.append(Case(f"learn em --uncertainty {v}", "", None, (*um, v), True))
    out.append(
        Case("learn em --uncertainty 2 --scheduler bogus", "", None, (*um, "2", "--scheduler", "not an address"), True)
    )
    out.append(Case("learn em --uncertainty 2 --workers 0", "", None, (*um, "2", "--workers", "0"), True))
    still = ("log/actions.csv", set_all(1, "0"))
    # a robot that never moves: flagged (exit 3, command_constant) or refused, never a division by zero
    out.append(Case("log/actions.csv:never moves (--uncertainty 2)", still[0], still[1], (*um, "2"), True, True))
    # fleets: every output under --out, one folder per log though two logs share a name
    fleet = ("fleet", "learn", "--workers", "1", *FIT, "--no-cross-scores")
    out.append(
        Case(
            "fleet learn: two logs named log",
            "",
            None,
            (*fleet, "{work}/log", "{work}/other/log", "--out", "{out}/fl"),
            False,
        )
    )
    out.append(
        Case(
            "fleet learn --out an input log",
            "",
            None,
            (*fleet, "{work}/log", "{work}/other/log", "--out", "{work}/log"),
            True,
        )
    )
    out.append(
        Case(
            "fleet learn --scheduler bogus",
            "",
            None,
            ("fleet", "learn", "{work}/log", "--out", "{out}/fl", "--scheduler", "not an address"),
            True,
        )
    )
    for v in ("-1", "1000000000", "abc"):
        out.append(
            Case(
                f"fleet learn --workers {v}",
                "",
                None,
                ("fleet", "learn", "{work}/log", "--out", "{out}/fl", "--workers", v),
                True,
            )
        )
    out.append(
        Case(
            "fleet learn --uncertainty 1e9",
            "",
            None,
            (*fleet, "{work}/log", "--out", "{out}/fl", "--uncertainty", "1000000000"),
            True,
        )
    )
    out.append(
        Case(
            "fleet learn: a lidar folder among logs",
            "",
            None,
            (*fleet, "{work}/log", "{work}/lidar", "--out", "{out}/fl"),
            True,
            True,
        )
    )
    # monitor: bins bounded, probabilities in (0, 1), never an output over its inputs
    mon = ("monitor", "{work}/log", "--model", "{work}/model.json")
    for opt, v in (("--bin-s", "1e-9"), ("--bin-s", "0"), ("--bin-s", "-1"), ("--bin-s", "nan"), ("--bin-s", "inf"),
                   ("--bin-s", "1e12"), ("--false-alarm", "0"), ("--false-alarm", "1"), ("--false-alarm", "2"),
                   ("--false-alarm", "nan"), ("--bins", "0"), ("--bins", "1000000000")):  # fmt: skip
        out.append(Case(f"monitor {opt} {v}", "", None, (*mon, "--out", "{out}/mon.json", opt, v), True))
    for name, path in (("the model", "{work}/model.json"), ("a log file", "{work}/log/actions.csv"),
                       ("the log folder", "{work}/log"), ("a device", "/dev/full")):  # fmt: skip
        out.append(Case(f"monitor --out {name}", "", None, (*mon, "--out", path), True))
        out.append(
            Case(f"monitor --relearn {name}", "", None, (*mon, "--out", "{out}/mon.json", "--relearn", path), True)
        )
    for k, m in (("sigma 1e-300", json_set(("model", "sensor", "channels", 0, "sigma"), 1e-300)),
                 ("sigma 1e300", json_set(("model", "sensor", "channels", 0, "sigma"), 1e300)),
                 ("motion_sd 1e300", json_set(("model", "motion_sd"), [[1e300, 1, 0.01]])),
                 ("no sensor", json_drop(("model", "sensor")))):  # fmt: skip
        out.append(Case(f"model.json:{k} (monitor)", "model.json", m, (*mon, "--out", "{out}/mon.json"), True))
    out.append(
        Case(
            "monitor a lidar folder",
            "",
            None,
            ("monitor", "{work}/lidar", "--model", "{work}/lidar_model.json", "--out", "{out}/mon.json"),
            True,
        )
    )
    # localize: its --out never over an input; a start no map or track holds is refused
    loc = ("localize", "{work}/log", "--model", "{work}/model.json")
    for name, path in (("the model", "{work}/model.json"), ("the log's meta.json", "{work}/log/meta.json"),
                       ("a device", "/dev/full"), ("the log folder", "{work}/log")):  # fmt: skip
        out.append(Case(f"localize --out {name}", "", None, (*loc, "--out", path), True))
    tbloc = ("localize", "{work}/tb.csv", "--model", "{work}/tb_model.json", "--out", "{out}/p.json")
    out.append(Case("localize tb.csv: as written", "", None, tbloc, False))
    for v in ("1e9", "-1e9", "nan", "inf"):
        out.append(Case(f"localize tb.csv --start {v}", "", None, (*tbloc, "--start", v), True))
    out.append(
        Case(
            "localize tb.csv with the planar model",
            "",
            None,
            ("localize", "{work}/tb.csv", "--model", "{work}/model.json", "--out", "{out}/p.json"),
            True,
        )
    )
    out.append(
        Case(
            "localize a lidar folder",
            "",
            None,
            ("localize", "{work}/lidar", "--model", "{work}/lidar_model.json", "--out", "{out}/p.json"),
            True,
        )
    )
    # a model run on a log whose ranges are in another unit, or signed (issue 95: scored with exit 0)
    obs = "log/observations.csv"
    scored = ("evaluate", "log", "{work}/log", "--model", "{work}/model.json", "--out", "{out}/e.json")
    for cname, argv in (("evaluate log", scored), ("localize", (*loc, "--out", "{out}/p.json"))):
        out.append(Case(f"{obs}:ranges in metres ({cname})", obs, map_column(2, scale=1e-3), argv, True))
        out.append(Case(f"{obs}:ranges negative ({cname})", obs, map_column(2, scale=-1.0), argv, True))
    # exports: every format bounded and finite, never over the model, never two outputs on one path
    rl = ("export", "{work}/model.json", "--format", "robot-localization", "--out", "{out}/rl.yaml")
    for k, m in (("motion_sd missing", json_drop(("model", "motion_sd"))),
                 ("motion_sd 1e300", json_set(("model", "motion_sd"), [[1e300, 1, 0.01]])),
                 ("mount missing", json_drop(("model", "sensor", "mount"))),
                 ("mount yaw 1e9", json_set(("model", "sensor", "mount", "yaw_rad"), 1e9)),
                 ("dt_s 1e-300", json_set(("dt_s",), 1e-300)),
                 ("dt_s 1e300", json_set(("dt_s",), 1e300)),
                 ("motion_sd inf", json_set(("model", "motion_sd", 0, 0), inf))):  # fmt: skip
        out.append(Case(f"model.json:{k} (export robot-localization)", "model.json", m, rl, True))
    for fmt in ("robot-localization", "tum", "landmarks"):
        argv = ("export", "{work}/model.json", "--format", fmt)
        out.append(Case(f"export {fmt} --out the model", "", None, (*argv, "--out", "{work}/model.json"), True))
        out.append(Case(f"export {fmt} --out a device", "", None, (*argv, "--out", "/dev/full"), True))
        out.append(Case(f"export {fmt} --out a folder", "", None, (*argv, "--out", "{out}"), True))
    tum = ("export", "{work}/model.json", "--format", "tum", "--out", "{out}/m.tum")
    out.append(Case("export tum --truth-out its --out", "", None, (*tum, "--truth-out", "{out}/m.tum"), True))
    out.append(Case("export tum --truth-out the model", "", None, (*tum, "--truth-out", "{work}/model.json"), True))
    out.append(Case("export tum --truth-out the path", "", None, (*tum, "--truth-out", "{work}/model.path.npz"), True))
    urdf = ("export", "{work}/lidar_model.json", "--format", "urdf")
    out.append(Case("export urdf --out the model", "", None, (*urdf, "--out", "{work}/lidar_model.json"), True))
    out.append(
        Case(
            "export urdf of a landmark model",
            "",
            None,
            ("export", "{work}/model.json", "--format", "urdf", "--out", "{out}/u.xacro"),
            True,
        )
    )
    out.append(
        Case(
            "export landmarks of a lidar model",
            "",
            None,
            ("export", "{work}/lidar_model.json", "--format", "landmarks", "--out", "{out}/l.csv"),
            True,
        )
    )
    vel = ("export", "{work}/car_model.json", "--format", "velodyne")
    out.append(Case("export velodyne --out the model", "", None, (*vel, "--out", "{work}/car_model.json"), True))
    out.append(Case("export velodyne --out a device", "", None, (*vel, "--out", "/dev/full"), True))
    # the other lidars' factory calibrations in the wrong unit
    c16 = ("learn", "car", "{work}/car16", "--out", "{out}/car.json", "--no-report", "--factory-calibration")
    cal16 = "car16/calibration_true.yaml"
    out.append(Case("car16: VLP-16 calibration as written", "", None, (*c16, "{work}/" + cal16), False))
    vert_deg = yaml_scale("vert_correction", 180.0 / np.pi)
    out.append(Case(f"{cal16}:vert_correction in degrees", cal16, vert_deg, (*c16, "{work}/" + cal16), True))
    # a VLP-16's rot_correction is zero (its lasers fire in one column): a 64-laser unit's, in degrees
    calib = ("learn", "car", "{work}/car", "--factory-calibration", "{work}/calib.yaml", "--out", "{out}/c.json")
    rot_deg = yaml_scale("rot_correction", 180.0 / np.pi)
    out.append(Case("calib.yaml:rot_correction in degrees", "calib.yaml", rot_deg, (*calib, "--no-report"), True))
    os1 = ("learn", "car", "{work}/os1", "--out", "{out}/car.json", "--no-report", "--factory-calibration")
    md = "os1/metadata_true.json"
    for k, m in (("azimuth 1e6", json_set(("beam_azimuth_angles", 0), 1e6)),
                 ("altitude 1e3", json_set(("beam_altitude_angles", 0), 1e3)),
                 ("azimuths in radians x 1e3", json_map(("beam_azimuth_angles",), lambda v: [x * 1e3 for x in v])),
                 ("one altitude short", json_map(("beam_altitude_angles",), lambda v: v[:-1])),
                 ("altitude nan", json_set(("beam_altitude_angles", 3), nan))):  # fmt: skip
        out.append(Case(f"{md}:{k}", md, m, (*os1, "{work}/" + md), True))
    out.append(Case(f"{md}: as written", "", None, (*os1, "{work}/" + md), False))
    return out


def sqlite_edit(sql: str) -> Mutation:
    """A ROS 2 sqlite3 bag's database with ``sql`` run on it (what a broken recorder or a hand edit leaves)."""

    def m(data: bytes) -> bytes:
        import sqlite3
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            db = Path(d) / "bag.db3"
            db.write_bytes(data)
            con = sqlite3.connect(db)
            con.executescript(sql + ";")
            con.commit()
            con.close()
            return db.read_bytes()

    return m


def yaml_scale(field: str, scale: float) -> Mutation:
    """Every ``field: value`` of a YAML file times ``scale``."""

    def m(data: bytes) -> bytes:
        pattern = re.compile(rb"(" + field.encode() + rb": )([-0-9.e]+)")
        return pattern.sub(lambda g: g.group(1) + repr(float(g.group(2)) * scale).encode(), data)

    return m


def json_map(path: tuple[str | int, ...], f: Callable[[object], object]) -> Mutation:
    def m(data: bytes) -> bytes:
        doc = json.loads(data)
        node = doc
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = f(node[path[-1]])
        return json.dumps(doc).encode()

    return m


LAUGHS = (
    b"a: &a [x, x, x, x, x, x, x, x, x]\n"
    + b"".join(f"{n}: &{n} [{', '.join([f'*{p}'] * 9)}]\n".encode() for p, n in zip("abcdefg", "bcdefgh", strict=True))
    + b"max_iterations: *h\n"
)


def _first_rows(n: int) -> Mutation:
    def m(data: bytes) -> bytes:
        lines = data.decode().splitlines()
        head = [ln for ln in lines if ln.startswith("#")]
        return ("\n".join(head + [ln for ln in lines if not ln.startswith("#")][:n]) + "\n").encode()

    return m


def _one_point_map(data: bytes) -> bytes:
    meta = json.loads(data)
    for mark in meta["landmarks"]:
        mark["x_mm"], mark["y_mm"] = 100.0, 200.0
    return json.dumps(meta).encode()


def _blank_ranges(data: bytes) -> bytes:
    rows = _rows(data)
    return _join(rows[:1] + [[r[0], *([""] * (len(r) - 1))] for r in rows[1:]])


def _set_ranges(value: float) -> Callable[[object], None]:
    def change(msg: object) -> None:
        msg.ranges = np.full(len(msg.ranges), value, dtype=np.float32)

    return change


def _drop_beams(msg: object) -> None:
    msg.ranges = msg.ranges[:-10]


def _set_positions(value: float) -> Callable[[object], None]:
    def change(msg: object) -> None:
        msg.position = np.full(len(msg.position), value)

    return change


def _flip_lidar(msg: object) -> None:
    msg.transforms[1].transform.rotation.x, msg.transforms[1].transform.rotation.w = 1.0, 0.0


def _keep_only(topics: tuple[str, ...]) -> Mutation:
    return bag_rewrite(lambda tp, t, msg, k: [(t, msg)] if tp in topics else [])


def run_case(case: Case, base: Path, scratch: Path) -> Ended:
    """The case in ``scratch`` (a copy of the base inputs with its mutation), in a fresh process."""
    work, out = scratch / "work", scratch / "out"
    # the captures (33 MB for car/) only where they are read
    skip = [c for c in ("car", "car16", "os1") if not any(a.split("/")[:2] == ["{work}", c] for a in case.argv)]
    shutil.copytree(base, work, ignore=shutil.ignore_patterns("done", *skip))
    out.mkdir()
    if case.target:
        target = work / case.target
        assert case.mutate is not None
        target.write_bytes(case.mutate(target.read_bytes()))
    argv = [a.replace("{work}", str(work)).replace("{out}", str(out)) for a in case.argv]
    before = _fingerprints(work)
    rss_file = scratch / "rss"
    env = os.environ | {"COLUMNS": "200", "SENSACT_FUZZ_RSS": str(rss_file)}
    t0 = time.perf_counter()
    proc = subprocess.Popen(sensact_argv(*argv), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    code: int | None
    try:
        _, stderr = proc.communicate(timeout=TIMEOUT_S)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        proc.kill()
        _, stderr = proc.communicate()
        code = None
    seconds = time.perf_counter() - t0
    rss = int(rss_file.read_text() or 0) if rss_file.exists() else 0
    leftovers = tuple(str(p) for p in scratch.rglob("*.tmp"))
    after = _fingerprints(work)
    overwritten = tuple(sorted(k for k, v in before.items() if after.get(k) != v))
    written = [*(k for k in after if k not in before), *(str(p.relative_to(scratch)) for p in out.rglob("*"))]
    failed = code not in (0, 3)
    return Ended(
        code,
        stderr.decode("utf-8", "replace"),
        seconds,
        rss,
        leftovers,
        overwritten,
        tuple(sorted(written)) if failed else (),
        tuple(sorted(k for k in after if k not in before)),
    )


def _fingerprints(folder: Path) -> dict[str, tuple[int, str]]:
    """Each file under ``folder`` (its path there) by its size and content hash."""
    import hashlib

    out = {}
    for p in folder.rglob("*"):
        if p.is_file() and not p.is_symlink():
            out[str(p.relative_to(folder.parent))] = (p.stat().st_size, hashlib.sha1(p.read_bytes()).hexdigest())
    return out


def problems(case: Case, ended: Ended) -> list[str]:
    """What was wrong with how ``case`` ended (empty: it ended as issue 74 requires)."""
    out = []
    err = ended.stderr
    if ended.code is None:
        out.append(f"hung (killed after {TIMEOUT_S:.0f} s)")
    elif ended.code not in (0, 2, 3):
        out.append(f"exit code {ended.code}")
    elif case.refuse and ended.code != 2 and not (case.flagged_ok and ended.code == 3):
        out.append(f"garbage accepted: exit {ended.code}, not 2")
    if "Traceback" in err:
        out.append("a traceback")
    if "internal error" in err:
        out.append("an internal error")
    if ended.code == 2:
        # the first run's compile notice is progress, not part of the error
        lines = [ln for ln in err.splitlines() if ln.strip() and ln.strip() != COMPILE_MESSAGE]
        if len(lines) != 1 or not re.match(r"^error: ", lines[0]):
            out.append(f"not one error line: {lines[:3]}")
    if ended.leftovers:
        out.append(f"temporary files left: {ended.leftovers}")
    if ended.overwritten:
        out.append(f"inputs overwritten: {ended.overwritten[:3]}")
    if ended.left_on_failure:
        out.append(f"a failing run left files: {ended.left_on_failure[:3]}")
    if ended.beside_inputs:
        out.append(f"wrote among its inputs: {ended.beside_inputs[:3]}")
    if ended.peak_rss_bytes > MEMORY_CAP_BYTES:
        out.append(f"peak memory {ended.peak_rss_bytes / 2**20:.0f} MiB")
    return out
