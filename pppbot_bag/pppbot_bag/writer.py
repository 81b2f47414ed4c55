"""Writing rosbag2 bags: MCAP files (the ``mcap`` library) plus ``metadata.yaml``.

What rosbag2 does, and pppbot's recorder relies on:

- a bag is a directory ``<name>/`` holding ``<name>_0.mcap``, ``<name>_1.mcap`` … and
  ``metadata.yaml``; a new file starts when the current one reaches ``max_bag_size``
  bytes or spans ``max_bag_duration`` of message time;
- every file is a complete MCAP file with profile ``ros2``: one schema per type (the
  complete ``ros2msg`` definition), one channel per topic carrying
  ``offered_qos_profiles`` and ``topic_type_hash``, messages with log time (reception)
  and publish time, and a ``rosbag2`` metadata record describing that file;
- storage presets (``none``, ``fastwrite``, ``zstd_fast``, ``zstd_small``) choose
  chunking and chunk compression as rosbag2_storage_mcap's presets do;
- compression mode ``file`` compresses each finished file to ``.mcap.zstd``;
  ``message`` compresses each message's bytes with zstd.

Chunks are also closed whenever :meth:`BagWriter.flush` is called, so a recorder that
flushes every second loses at most about a second of data if it is killed; the file
can then be recovered with :func:`pppbot_bag.recover.reindex`.
"""
from __future__ import annotations

import enum
import re
from collections.abc import Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import yaml
import zstandard
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import Qos

from pppbot_bag.definitions import TypeDefinition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import BagMetadata, FileInfo, Topic, qos_yaml

#: rosbag2_storage_mcap refuses smaller split sizes.
MIN_SPLIT_SIZE = 1024
LIBRARY = "pppbot (mcap-python)"
#: Written at the start of every file, so a file that never got its closing
#: ``rosbag2`` record still says how its messages are compressed (see recover.py).
RECORDING_RECORD = "pppbot_recording"


class CompressionMode(enum.Enum):
    NONE = "none"
    FILE = "file"
    MESSAGE = "message"


@dataclass(frozen=True)
class StoragePreset:
    chunked: bool
    chunk_size: int
    compression: CompressionType
    chunk_crcs: bool


#: rosbag2_storage_mcap's presets; ``none`` is its default writer options.
STORAGE_PRESETS: dict[str, StoragePreset] = {
    "none": StoragePreset(True, 768 * 1024, CompressionType.ZSTD, True),
    "fastwrite": StoragePreset(False, 768 * 1024, CompressionType.NONE, False),
    "zstd_fast": StoragePreset(True, 768 * 1024, CompressionType.ZSTD, False),
    "zstd_small": StoragePreset(True, 4 * 1024 * 1024, CompressionType.ZSTD, True),
}
COMPRESSION_FORMATS = ("zstd",)


@dataclass(frozen=True)
class WriterOptions:
    """How to write: splitting (0 = never), compression and the MCAP storage preset."""

    max_bag_size: int = 0
    max_bag_duration_s: float = 0.0
    compression_mode: CompressionMode = CompressionMode.NONE
    compression_format: str = "zstd"
    storage_preset: str = "none"

    def validate(self) -> None:
        """Raises: BagError naming the bad option and what is allowed."""
        if self.max_bag_size < 0 or 0 < self.max_bag_size < MIN_SPLIT_SIZE:
            raise BagError(f"max_bag_size {self.max_bag_size} is invalid: use 0 (no splitting) "
                           f"or at least {MIN_SPLIT_SIZE} bytes")
        if not self.max_bag_duration_s >= 0:  # also NaN
            raise BagError(f"max_bag_duration {self.max_bag_duration_s} is invalid: use 0 (no splitting) "
                           "or a positive number of seconds")
        if self.compression_format not in COMPRESSION_FORMATS:
            raise BagError(f"compression format '{self.compression_format}' is not supported; "
                           f"allowed: {', '.join(COMPRESSION_FORMATS)}")
        if self.storage_preset not in STORAGE_PRESETS:
            raise BagError(f"storage preset profile '{self.storage_preset}' is unknown; "
                           f"allowed: {', '.join(STORAGE_PRESETS)}")


class _OpenFile:
    """The MCAP file being written, with what its ``rosbag2`` record will say."""

    def __init__(self, path: Path, preset: StoragePreset) -> None:
        self.path = path
        self.stream: IO[bytes] = path.open("xb")
        self.mcap = McapWriter(self.stream, chunk_size=preset.chunk_size, compression=preset.compression,
                               use_chunking=preset.chunked, enable_crcs=preset.chunk_crcs)
        self.mcap.start(profile="ros2", library=LIBRARY)
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.info = FileInfo(path.name)
        self.topic_counts: dict[str, int] = {}
        self._tell = 0
        self._pending = 0

    def size(self) -> int:
        """Bytes on disk plus (uncompressed) bytes written since the last chunk reached it."""
        tell = self.stream.tell()
        if tell != self._tell:
            self._tell, self._pending = tell, 0
        return tell + self._pending

    def account(self, size: int) -> None:
        self._pending += size


class BagWriter:
    """Writes one bag directory. Not thread-safe: one thread writes.

    ``continuing``: the metadata of the finished bag at ``path`` (as
    :func:`pppbot_bag.recover.salvaged` reads it back) that this writer records on into, as
    its next files; its topics keep their counts and are written again once added again.

    Raises:
        BagError: the directory exists (bags are never overwritten) and is not continued, a
            continued bag's compression differs from ``options``', or an option is bad.
    """

    def __init__(self, path: Path | str, options: WriterOptions = WriterOptions(),
                 ros_distro: str = "jazzy", continuing: BagMetadata | None = None) -> None:
        options.validate()
        self.path = Path(path)
        mode = options.compression_mode
        self.metadata = BagMetadata(
            compression_mode="" if mode is CompressionMode.NONE else mode.value,
            compression_format="" if mode is CompressionMode.NONE else options.compression_format,
            ros_distro=ros_distro)
        self._topics: dict[str, Topic] = {}
        self._next_file = 0  # the number of the next file: <bag>_<number>.mcap
        if continuing is not None:
            if (continuing.compression_mode or "none") != mode.value and continuing.message_count:
                raise BagError(f"'{self.path}' was recorded with compression mode "
                               f"'{continuing.compression_mode or 'none'}'; recording on into it needs the same "
                               f"(--compression-mode {continuing.compression_mode or 'none'})")
            self.metadata.files = list(continuing.files)
            self._topics = {topic.name: topic for topic in continuing.topics}
            numbers = [re.search(r"_(\d+)\.mcap", f.path) for f in continuing.files]
            self._next_file = max((int(n[1]) + 1 for n in numbers if n), default=len(continuing.files))
        elif self.path.exists():
            raise BagError(f"output '{self.path}' exists already; pppbot never overwrites a bag "
                           "(choose another name with -o)")
        else:
            try:
                self.path.mkdir(parents=True)
            except OSError as exc:
                raise BagError(f"cannot create bag directory '{self.path}': {exc.strerror}") from exc
        self.options = options
        self.preset = STORAGE_PRESETS[options.storage_preset]
        self._definitions: dict[str, TypeDefinition] = {}
        self._message_compressor = zstandard.ZstdCompressor(level=1)
        self._compressing: list[Future[None]] = []
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="bag-compress")
        self._file: _OpenFile | None = None
        self._closed = False
        self._open_file()

    # -- topics and messages -------------------------------------------------------------

    @property
    def topics(self) -> dict[str, Topic]:
        return dict(self._topics)

    def add_topic(self, name: str, definition: TypeDefinition, offered_qos_profiles: Sequence[Qos],
                  type_hash: str = "") -> None:
        """Register a topic (once; a second registration of the same name is refused)."""
        self._check_open()
        topic = self._topics.get(name)
        if topic is not None and (name in self._definitions or topic.type != definition.name):
            raise BagError(f"topic '{name}' is already in the bag" + (
                "" if topic.type == definition.name else f" as {topic.type}, not {definition.name}"))
        if topic is None:  # else a continued bag's topic, written again from now on
            topic = Topic(name, definition.name, list(offered_qos_profiles), type_hash or definition.type_hash)
            self._topics[name] = topic
        self._definitions[name] = definition
        assert self._file is not None
        self._register(self._file, topic)

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None,
              sequence: int = 0) -> None:
        """Append one serialized message, received at ``log_time_ns``."""
        self._check_open()
        if topic not in self._topics:
            raise BagError(f"topic '{topic}' was not added to the bag before writing to it")
        if self.options.compression_mode is CompressionMode.MESSAGE:
            data = self._message_compressor.compress(data)
        file = self._file
        assert file is not None
        if self._split_due(file, log_time_ns, len(data)):
            self._close_file()
            file = self._open_file()
        file.mcap.add_message(file.channels[topic], log_time=log_time_ns, data=data,
                              publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
                              sequence=sequence & 0xFFFFFFFF)
        file.account(len(data))
        file.info.add(log_time_ns)
        file.topic_counts[topic] = file.topic_counts.get(topic, 0) + 1
        self._topics[topic].message_count += 1

    def flush(self) -> None:
        """Close the open chunk and push everything to the OS (bounds loss if killed)."""
        if self._file is not None:
            self._file.mcap.flush()

    def close(self) -> BagMetadata:
        """Finish the last file, wait for file compression, write ``metadata.yaml``."""
        if self._closed:
            return self.metadata
        self._closed = True
        try:
            self._close_file()
            for job in self._compressing:
                job.result()
        except OSError as exc:
            raise BagError(f"finishing bag '{self.path}' failed: {exc}") from exc
        finally:
            self._pool.shutdown()
            self._write_metadata()
        return self.metadata

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- files ---------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f"bag '{self.path}' is closed")

    def _split_due(self, file: _OpenFile, stamp_ns: int, size: int) -> bool:
        if file.info.message_count == 0:
            return False
        o = self.options
        if o.max_bag_duration_s > 0 and stamp_ns - file.info.start_ns >= o.max_bag_duration_s * 1e9:
            return True
        return bool(o.max_bag_size) and file.size() + size > o.max_bag_size

    def _register(self, file: _OpenFile, topic: Topic) -> None:
        definition = self._definitions[topic.name]
        if topic.type not in file.schemas:
            file.schemas[topic.type] = file.mcap.register_schema(
                topic.type, definition.encoding, definition.text.encode())
        file.channels[topic.name] = file.mcap.register_channel(
            topic.name, topic.serialization_format, file.schemas[topic.type],
            {"offered_qos_profiles": qos_yaml(topic.offered_qos_profiles),
             "topic_type_hash": topic.type_description_hash})

    def _open_file(self) -> _OpenFile:
        path = self.path / f"{self.path.name}_{self._next_file}.mcap"
        self._next_file += 1
        try:
            file = _OpenFile(path, self.preset)
        except OSError as exc:
            raise BagError(f"cannot create '{path}': {exc.strerror}") from exc
        file.mcap.add_metadata(RECORDING_RECORD, {
            "compression_mode": self.metadata.compression_mode,
            "compression_format": self.metadata.compression_format,
            "ros_distro": self.metadata.ros_distro})
        for topic in self._topics.values():
            if topic.name in self._definitions:  # a continued bag's other topics: once added again
                self._register(file, topic)
        self._file = file
        self.metadata.files.append(file.info)
        self._write_metadata()
        return file

    def _close_file(self) -> None:
        file, self._file = self._file, None
        if file is None:
            return
        topics = [Topic(t.name, t.type, t.offered_qos_profiles, t.type_description_hash,
                        message_count=file.topic_counts.get(t.name, 0)) for t in self._topics.values()]
        record = self.metadata.as_yaml_dict(files=[file.info], topics=topics)
        file.mcap.add_metadata("rosbag2", {
            "serialized_metadata": yaml.safe_dump(record, default_flow_style=False, sort_keys=False),
            "ros_distro": self.metadata.ros_distro})
        file.mcap.finish()
        file.stream.close()
        if self.options.compression_mode is CompressionMode.FILE:
            file.info.path = f"{file.path.name}.{self.options.compression_format}"
            self._compressing.append(self._pool.submit(compress_file, file.path))
        self._write_metadata()

    def _write_metadata(self) -> None:
        self.metadata.topics = list(self._topics.values())
        self.metadata.write(self.path)


def compress_file(path: Path) -> None:
    """``x.mcap`` → ``x.mcap.zstd`` (one zstd frame), then remove ``x.mcap``."""
    target = path.with_name(path.name + ".zstd")
    tmp = path.with_name(path.name + ".zstd.tmp")
    with path.open("rb") as src, tmp.open("wb") as dst:
        zstandard.ZstdCompressor(level=3).copy_stream(src, dst)
    tmp.replace(target)
    path.unlink()
