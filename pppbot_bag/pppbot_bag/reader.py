"""Reading bags back (rosbags' reader: rosbag2 directories, single MCAP files, split,
file- and message-compressed) and ``ros2 bag info``'s summary."""
from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from rosbags.interfaces import Connection
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.errors import ReaderError

from pppbot_bag.errors import BagError
from pppbot_bag.metadata import check_metadata_file

#: What rosbags raises for a damaged container is whatever its decoders raise: ReaderError for
#: checksums and records, ZstdError or lz4's RuntimeError for a chunk, struct.error, EOFError,
#: OverflowError or MemoryError for a record length beyond any file. Inside rosbags' calls
#: (nothing of pppbot runs there) every one of them means a damaged file.
_DAMAGED = Exception


@contextmanager
def open_bag(path: Path | str) -> Iterator[Reader]:
    """An open reader for a bag directory or one ``.mcap`` file.

    Raises:
        BagError: no such path, no ``metadata.yaml`` (with how to recover), a ``metadata.yaml``
            that is not rosbag2 metadata (naming it and what is wrong), or unreadable.
    """
    path = Path(path)
    if not path.exists():
        raise BagError(f"bag '{path}' does not exist")
    if path.is_dir() and not (path / "metadata.yaml").is_file():
        hint = (f"; if the recorder was killed, `pppbot bag reindex {path}` rebuilds it"
                if any(path.glob("*.mcap")) else "")
        raise BagError(f"'{path}' is not a bag: it has no metadata.yaml{hint}")
    if path.is_dir():
        check_metadata_file(path / "metadata.yaml")
    try:
        reader = Reader(path)
        reader.open()
    except _DAMAGED as exc:
        hint = (f" (if its recorder was killed, `pppbot bag reindex {path}` recovers it)"
                if path.is_dir() else "")
        raise BagError(f"cannot read bag '{path}': {_what(exc)}{hint}") from exc
    try:
        yield reader
    finally:
        reader.close()




def _what(exc: Exception) -> str:
    return str(exc) if isinstance(exc, (ReaderError, OSError, BagError)) else f"{type(exc).__name__}: {exc}"


def bag_messages(reader: Reader, connections: Sequence[Connection] = (),
                 start: int | None = None) -> Iterator[tuple[Connection, int, bytes]]:
    """``reader.messages(...)``, in log time order; a file damaged past its index ends the
    iteration with a :class:`BagError` naming the bag and the last good time (what came before
    was read).

    Raises:
        BagError: a damaged chunk or record.
    """
    last = None
    try:
        for connection, stamp, data in reader.messages(connections, start=start):
            last = stamp
            yield connection, stamp, data
    except _DAMAGED as exc:
        after = f" after t = {_stamp(last)}" if last is not None else ""
        raise BagError(f"bag '{reader.path}' is damaged{after}: {_what(exc)} (if its recorder was killed, "
                       f"`pppbot bag reindex {reader.path}` recovers what it can)") from exc


@dataclass(frozen=True)
class TopicSummary:
    name: str
    type: str
    count: int
    serialization_format: str


@dataclass(frozen=True)
class BagSummary:
    """What ``bag info`` prints."""

    path: Path
    files: list[str]
    size_bytes: int
    storage_id: str
    ros_distro: str
    start_ns: int
    end_ns: int
    message_count: int
    compression_mode: str
    compression_format: str
    topics: list[TopicSummary]

    @property
    def duration_ns(self) -> int:
        return max(0, self.end_ns - self.start_ns)


def summarize(path: Path | str) -> BagSummary:
    path = Path(path)
    with open_bag(path) as reader:
        files = [f["path"] for f in getattr(reader.storage, "files", [])] or [path.name]
        counts: dict[str, int] = {}
        conns: dict[str, Connection] = {}
        for conn in reader.connections:
            counts[conn.topic] = counts.get(conn.topic, 0) + conn.msgcount
            conns.setdefault(conn.topic, conn)
        topics = [TopicSummary(name, c.msgtype, counts[name],
                               getattr(c.ext, "serialization_format", "cdr")) for name, c in conns.items()]
        size = (sum((path / f).stat().st_size for f in files if (path / f).is_file())
                if path.is_dir() else path.stat().st_size)
        count = reader.message_count
        return BagSummary(
            path=path, files=files, size_bytes=size, storage_id="mcap" if path.suffix != ".db3" else "sqlite3",
            ros_distro=reader.ros_distro or "", start_ns=reader.start_time if count else 0,
            end_ns=reader.end_time if count else 0, message_count=count,
            compression_mode=reader.compression_mode or "", compression_format=reader.compression_format or "",
            topics=topics)


def human_size(size: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if size < 1024 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    raise AssertionError("unreachable")


def _stamp(ns: int) -> str:
    seconds = ns / 1e9
    text = time.strftime("%b %e %Y %H:%M:%S", time.localtime(seconds))
    return f"{text}.{ns % 1_000_000_000 // 1_000_000:03d} ({seconds:.3f})"


def format_info(s: BagSummary) -> str:
    """``ros2 bag info``'s layout."""
    label = "{:<19}".format
    lines = [label("Files:") + s.files[0] if s.files else label("Files:")]
    lines += [" " * 19 + f for f in s.files[1:]]
    lines += [
        label("Bag size:") + human_size(s.size_bytes),
        label("Storage id:") + s.storage_id,
        label("ROS Distro:") + s.ros_distro,
        label("Duration:") + f"{s.duration_ns / 1e9:.3f}s",
        label("Start:") + _stamp(s.start_ns),
        label("End:") + _stamp(s.end_ns),
        label("Messages:") + str(s.message_count),
    ]
    if s.compression_mode:
        lines.append(label("Compression:") + f"{s.compression_mode} ({s.compression_format})")
    width = max((len(t.name) for t in s.topics), default=0)
    rows = [f"Topic: {t.name:<{width}} | Type: {t.type} | Count: {t.count} | "
            f"Serialization Format: {t.serialization_format}" for t in s.topics]
    lines.append(label("Topic information:") + (rows[0] if rows else ""))
    lines += [" " * 19 + r for r in rows[1:]]
    lines.append(label("Service:") + "0")
    lines.append(label("Service information:"))
    return "\n".join(lines)
