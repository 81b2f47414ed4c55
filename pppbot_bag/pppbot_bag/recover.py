"""``pppbot bag reindex``: make a bag readable again after its recorder was killed.

A killed recorder leaves its last MCAP file without summary and footer, and
``metadata.yaml`` describing the bag as it was when that file was opened. Every chunk
the recorder had closed (it closes one at least every second) is complete on disk.
Reindexing reads each file as a stream of records up to the first incomplete one,
rewrites an unfinished file as a complete MCAP file (the original is kept next to it
as ``<file>.unfinished``), and writes ``metadata.yaml`` anew from what the files hold,
as ``ros2 bag reindex`` does for rosbag2.
"""
from __future__ import annotations

import errno
import io
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import zstandard
from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import Writer as McapWriter
from rosbags.rosbag2.metadata import parse_qos

from pppbot_bag.errors import BagError
from pppbot_bag.metadata import BagMetadata, FileInfo, Topic
from pppbot_bag.writer import LIBRARY, RECORDING_RECORD, compress_file


@dataclass
class _FileScan:
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    messages: list[Message] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    complete: bool = False


def _scan(stream: IO[bytes], keep_messages: bool) -> _FileScan:
    scan = _FileScan()
    try:
        for record in StreamReader(stream).records:
            if isinstance(record, Schema):
                scan.schemas[record.id] = record
            elif isinstance(record, Channel):
                scan.channels[record.id] = record
            elif isinstance(record, Message):
                scan.messages.append(record if keep_messages else Message(
                    record.channel_id, record.log_time, b"", record.publish_time, record.sequence))
            elif isinstance(record, Metadata):
                scan.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, Footer):
                scan.complete = True
    except (McapError, EOFError, ValueError, zstandard.ZstdError, struct.error):
        scan.complete = False  # the rest of the file was never written
    return scan


def _rewrite(path: Path, scan: _FileScan) -> None:
    tmp = path.with_name(path.name + ".recovering")
    with tmp.open("wb") as out:
        writer = McapWriter(out)
        writer.start(profile="ros2", library=LIBRARY)
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in scan.schemas.items()}
        channel_ids = {cid: writer.register_channel(c.topic, c.message_encoding,
                                                    schema_ids.get(c.schema_id, 0), dict(c.metadata))
                       for cid, c in scan.channels.items()}
        for name, data in scan.metadata.items():
            writer.add_metadata(name, data)
        for m in scan.messages:
            if m.channel_id in channel_ids:
                writer.add_message(channel_ids[m.channel_id], m.log_time, m.data, m.publish_time, m.sequence)
        writer.finish()
    path.rename(path.with_name(path.name + ".unfinished"))
    tmp.rename(path)


#: What ends an MCAP file with no summary section: a DataEnd record (data section CRC 0: not
#: computed), a Footer pointing at no summary, and the closing magic (MCAP's specification).
_SUMMARYLESS_END = (bytes([0x0F]) + struct.pack("<QI", 4, 0) + bytes([0x02]) + struct.pack("<QQQI", 20, 0, 0, 0)
                    + b"\x89MCAP0\r\n")


def seal(path: Path) -> None:
    """End an unfinished MCAP file where its last complete record ends, in place: for a file
    whose writing failed (a full disk), when there is no room for :func:`reindex`'s copy. The
    incomplete tail (at most the chunk being written) goes; the file needs only a few bytes
    more than it already has beyond that, which cutting the tail freed. When the writing failed
    right at a record's end, there is no tail to free: the last record goes too, and so on,
    until the end fits.

    Raises:
        OSError: not even a file cut to its first record could be ended.
    """
    ends = [0]
    with path.open("rb") as stream:
        try:
            for _ in StreamReader(stream).records:
                ends.append(stream.tell())
        except (McapError, EOFError, ValueError, zstandard.ZstdError, struct.error):
            pass
    for good in reversed(ends):  # the last complete record first
        try:
            with path.open("r+b") as out:
                out.truncate(good)
                out.seek(good)
                out.write(_SUMMARYLESS_END)
            return
        except OSError as exc:
            if exc.errno not in (errno.EFBIG, errno.ENOSPC, errno.EDQUOT) or good <= ends[1 if len(ends) > 1 else 0]:
                raise


def salvage(bag: Path) -> str:
    """After writing ``bag`` failed: :func:`seal` its unfinished MCAP files in place, then
    :func:`reindex` it (which then copies nothing); returns reindex's report.

    Raises:
        BagError: not a bag directory, or no MCAP file in it.
        OSError: not even the few bytes that end a file could be written.
    """
    return salvaged(bag)[1]


def salvaged(bag: Path) -> tuple[BagMetadata, str]:
    """:func:`salvage`, with the bag's metadata as written."""
    if not bag.is_dir():
        raise BagError(f"'{bag}' is not a bag directory")
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as stream:
            if not _scan(stream, keep_messages=False).complete:
                seal(path)
    return reindexed(bag)


def _index(name: str) -> tuple[int, str]:
    match = re.search(r"_(\d+)\.mcap(\.zstd)?$", name)
    return (int(match[1]) if match else 1 << 30, name)


def reindex(bag: Path) -> str:
    """Rebuild ``bag/metadata.yaml`` (and finish unfinished files); returns a report.

    Raises:
        BagError: not a directory, or no MCAP file in it.
    """
    return reindexed(bag)[1]


def reindexed(bag: Path) -> tuple[BagMetadata, str]:
    """:func:`reindex`, with the bag's metadata as written."""
    if not bag.is_dir():
        raise BagError(f"'{bag}' is not a bag directory")
    names = {p.name for p in bag.iterdir()}
    # x.mcap next to x.mcap.zstd: killed while compressing x; the .zstd is complete.
    files = sorted((bag / n for n in names if n.endswith(".mcap.zstd")
                    or (n.endswith(".mcap") and n + ".zstd" not in names)), key=lambda p: _index(p.name))
    if not files:
        raise BagError(f"'{bag}' holds no .mcap files to reindex")
    metadata = BagMetadata()
    topics: dict[str, Topic] = {}
    notes: list[str] = []
    for path in files:
        compressed = path.name.endswith(".zstd")
        with path.open("rb") as raw:
            stream: IO[bytes] = (io.BufferedReader(zstandard.ZstdDecompressor().stream_reader(raw))
                                 if compressed else raw)
            scan = _scan(stream, keep_messages=False)
        if not scan.complete and not compressed:
            with path.open("rb") as raw:
                scan = _scan(raw, keep_messages=True)
            _rewrite(path, scan)
            notes.append(f"finished the unfinished file {path.name} ({len(scan.messages)} messages kept; "
                         f"the original is {path.name}.unfinished)")
        recording = scan.metadata.get(RECORDING_RECORD, {})
        if compressed:
            metadata.compression_mode, metadata.compression_format = "file", "zstd"
        elif recording.get("compression_mode") == "message":
            metadata.compression_mode, metadata.compression_format = "message", recording.get(
                "compression_format", "zstd")
        metadata.ros_distro = recording.get("ros_distro", metadata.ros_distro)
        info = FileInfo(path.name)
        for m in scan.messages:
            channel = scan.channels.get(m.channel_id)
            if channel is None:
                continue
            info.add(m.log_time)
            topic = topics.get(channel.topic)
            if topic is None:
                schema = scan.schemas.get(channel.schema_id)
                topic = topics[channel.topic] = Topic(
                    channel.topic, schema.name if schema else "",
                    parse_qos(channel.metadata.get("offered_qos_profiles", "")) if
                    channel.metadata.get("offered_qos_profiles") else [],
                    channel.metadata.get("topic_type_hash", ""), channel.message_encoding)
            topic.message_count += 1
        metadata.files.append(info)
    if metadata.compression_mode == "file":
        # The files finished before the kill are compressed; compress the others alike,
        # since a bag has one compression mode.
        for info in metadata.files:
            if not info.path.endswith(".zstd"):
                compress_file(bag / info.path)
                info.path += ".zstd"
                notes.append(f"compressed {info.path} like the bag's other files")
    metadata.topics = list(topics.values())
    metadata.write(bag)
    lines = [f"reindexed '{bag}': {len(files)} file(s), {metadata.message_count} messages, "
             f"{len(topics)} topic(s)", *notes]
    return metadata, "\n".join(lines)
