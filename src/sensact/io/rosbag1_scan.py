"""A ROS 1 bag read front to back, its index rebuilt in memory: for the bags rosbags' own reader refuses although
they are whole ROS 1 bags — format 1.2 (ROS before 2010, its index of the old style), a 2.0 bag whose index
records are of an older version or missing (a recording that was never closed: ``rosbag reindex``'s case).

It plays rosbags' ``Reader1`` part inside ``AnyReader`` (``connections``, ``messages``, a context manager), so the
rest of sensact reads such a bag as any other. The record layout is the one the ROS wiki's *Bags/Format/2.0* and
*1.2* pages give: a record is a header (``name=value`` fields, each behind its length) then its data, each behind
a little-endian uint32 length. Messages are not held: each is located (chunk, offset) and read when asked for."""

from __future__ import annotations

import bz2
import mmap
import struct
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import NamedTuple

OP_MSG_DEF, OP_MSG_DATA, OP_FILE_HEADER, OP_INDEX_DATA, OP_CHUNK, OP_CHUNK_INFO, OP_CONNECTION = 1, 2, 3, 4, 5, 6, 7
MAGICS = {b"#ROSBAG V2.0\n": 200, b"#ROSBAG V1.2\n": 102}


class ScanError(Exception):
    """The file is not a ROS 1 bag this scan can read (the caller says so in one line)."""


class _Entry(NamedTuple):
    time_ns: int
    chunk: int  # the chunk's position in the file; -1 for a record outside any chunk (format 1.2)
    offset: int  # where the message's data starts, in the chunk's decompressed bytes or in the file
    size: int
    conn: int


def ros1_version(path: Path) -> int | None:
    """200 or 102 for a ROS 1 bag's first line, else None."""
    try:
        with open(path, "rb") as f:
            return MAGICS.get(f.readline(16))
    except OSError:
        return None


def _fields(header: bytes) -> dict[str, bytes]:
    out, at = {}, 0
    while at + 4 <= len(header):
        (n,) = struct.unpack_from("<I", header, at)
        field = header[at + 4 : at + 4 + n]
        if len(field) != n or b"=" not in field:
            raise ScanError("a record's header is cut or malformed")
        name, value = field.split(b"=", 1)
        out[name.decode("ascii", "replace")] = value
        at += 4 + n
    return out


def _records(buf: bytes | mmap.mmap, start: int = 0) -> Iterator[tuple[dict[str, bytes], int, int]]:
    """Each whole record's header fields, and where its data starts and how long it is; a record cut at the
    end (a recording that stopped mid-write) ends the walk."""
    at, end = start, len(buf)
    while at + 4 <= end:
        (hlen,) = struct.unpack_from("<I", buf, at)
        if at + 8 + hlen > end:
            return
        header = bytes(buf[at + 4 : at + 4 + hlen])
        (dlen,) = struct.unpack_from("<I", buf, at + 4 + hlen)
        data = at + 8 + hlen
        if data + dlen > end:
            return
        yield _fields(header), data, dlen
        at = data + dlen


def _time_ns(raw: bytes) -> int:
    sec, nsec = struct.unpack("<II", raw[:8])
    return sec * 1_000_000_000 + nsec


def _text(fields: dict[str, bytes], name: str, default: str = "") -> str:
    return fields.get(name, default.encode()).decode("utf-8", "replace")


class Rosbag1Scan:
    """rosbags' ``Reader1`` interface over a bag scanned record by record (see the module's docstring)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.connections: list = []
        self._entries: dict[int, list[_Entry]] = {}
        self._chunks: dict[int, tuple[str, int, int]] = {}  # position -> (compression, data start, data size)
        self._data: bytes | mmap.mmap = b""
        self._cached: tuple[int, bytes] = (-2, b"")

    def __enter__(self) -> Rosbag1Scan:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        with open(self.path, "rb") as f:  # mapped, not read: a bag of camera images is gigabytes
            self._data = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) if f.seek(0, 2) else b""
        try:
            self._scan()
        except BaseException:
            self.close()
            raise

    def _scan(self) -> None:
        from rosbags.interfaces import Connection, ConnectionExtRosbag1, MessageDefinition, MessageDefinitionFormat
        from rosbags.typesys.msg import normalize_msgtype

        version = MAGICS.get(bytes(self._data[:13]))
        if version is None:
            raise ScanError("its first line is not #ROSBAG V2.0 or V1.2")
        conns: dict[int, tuple[str, dict[str, bytes]]] = {}
        entries: dict[int, list[_Entry]] = {}
        by_topic: dict[str, int] = {}  # format 1.2 names connections by topic

        def connection(fields: dict[str, bytes], info: dict[str, bytes]) -> None:
            cid = struct.unpack("<I", fields["conn"][:4])[0]
            conns.setdefault(cid, (_text(fields, "topic"), info))

        for fields, start, size in _records(self._data, 13):
            op = fields.get("op", b"\x00")[0]
            if op == OP_CHUNK:
                compression = _text(fields, "compression", "none")
                self._chunks[start] = (compression, start, size)
                inner = self._chunk_bytes(start)
                for f, s, n in _records(inner):
                    iop = f.get("op", b"\x00")[0]
                    if iop == OP_CONNECTION:
                        connection(f, _info(inner, s, n))
                    elif iop == OP_MSG_DATA and "conn" in f and "time" in f:
                        cid = struct.unpack("<I", f["conn"][:4])[0]
                        entries.setdefault(cid, []).append(_Entry(_time_ns(f["time"]), start, s, n, cid))
            elif op == OP_CONNECTION:
                connection(fields, _info(self._data, start, size))
            elif op == OP_MSG_DEF and version == 102:
                topic = _text(fields, "topic")
                if topic not in by_topic:
                    by_topic[topic] = len(by_topic)
                    info = {"type": fields.get("type", b""), "md5sum": fields.get("md5", b"")}
                    info["message_definition"] = fields.get("def", b"")
                    conns[by_topic[topic]] = (topic, info)
            elif op == OP_MSG_DATA and version == 102 and "time" in fields:
                cid = by_topic.get(_text(fields, "topic"))
                if cid is not None:
                    entries.setdefault(cid, []).append(_Entry(_time_ns(fields["time"]), -1, start, size, cid))
        if not conns:
            raise ScanError("no connection record was found in it")
        self._entries = {cid: sorted(entries.get(cid, [])) for cid in conns}
        self.connections = [
            Connection(
                cid,
                topic,
                normalize_msgtype(_text(info, "type")),
                MessageDefinition(MessageDefinitionFormat.MSG, _text(info, "message_definition")),
                "",  # no md5 check: old rosbag tools hashed some definitions otherwise; the bag's own is read
                len(self._entries[cid]),
                ConnectionExtRosbag1(_text(info, "callerid") or None, None),
                self,
            )
            for cid, (topic, info) in sorted(conns.items())
        ]

    def close(self) -> None:
        self.connections = []
        self._entries = {}
        self._chunks = {}
        if isinstance(self._data, mmap.mmap):
            self._data.close()
        self._data = b""
        self._cached = (-2, b"")

    def _chunk_bytes(self, position: int) -> bytes:
        if self._cached[0] == position:
            return self._cached[1]
        compression, start, size = self._chunks[position]
        raw = self._data[start : start + size]
        if compression == "none":
            data = raw
        elif compression == "bz2":
            data = bz2.decompress(raw)
        elif compression == "lz4":
            import lz4.frame  # rosbags' own dependency

            data = lz4.frame.decompress(raw)
        else:
            raise ScanError(f"a chunk is compressed with {compression!r}, which ROS 1 never wrote")
        self._cached = (position, data)
        return data

    def messages(
        self, connections: Collection = (), start: int | None = None, stop: int | None = None
    ) -> Iterator[tuple[object, int, bytes]]:
        import heapq

        wanted = list(connections) or self.connections
        by_id = {c.id: c for c in self.connections}
        for e in heapq.merge(*(self._entries[c.id] for c in wanted)):
            if (start is not None and e.time_ns < start) or (stop is not None and e.time_ns >= stop):
                continue
            buf = self._data if e.chunk < 0 else self._chunk_bytes(e.chunk)
            yield by_id[e.conn], e.time_ns, bytes(buf[e.offset : e.offset + e.size])


def _info(buf: bytes, start: int, size: int) -> dict[str, bytes]:
    """A connection record's data: a header of its own (type, md5sum, message_definition, callerid)."""
    return _fields(bytes(buf[start : start + size]))
