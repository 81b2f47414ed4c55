"""rosbag2's ``metadata.yaml`` (version 9, as Jazzy writes it) and the per-topic record.

QoS profiles are rosbags' ``Qos`` tuples and are written with rosbags' version-9
dumper, so the channel metadata inside the MCAP file and ``metadata.yaml`` agree
byte for byte with what rosbag2 readers (and rosbags) compare.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2.metadata import dump_qos_v9

from pppbot_bag.errors import BagError
from pppbot_common.param_files import load_yaml_file

VERSION = 9
STORAGE_ID = "mcap"
#: Durations rmw calls infinite (RMW_DURATION_INFINITE as sec/nsec).
INFINITE = QosTime(9223372036, 854775807)
UNSPECIFIED = QosTime(0, 0)


def qos(reliability: str = "reliable", durability: str = "volatile", depth: int = 10,
        history: str = "keep_last", deadline: QosTime = INFINITE, lifespan: QosTime = INFINITE,
        liveliness: str = "automatic", lease: QosTime = INFINITE) -> Qos:
    """A QoS profile from rmw's lowercase policy names."""
    return Qos(QosHistory[history.upper()], depth, QosReliability[reliability.upper()],
               QosDurability[durability.upper()], deadline, lifespan,
               QosLiveliness[liveliness.upper()], lease, False)


def qos_yaml(profiles: Sequence[Qos]) -> str:
    """The ``offered_qos_profiles`` string of an MCAP channel (rosbag2's version-9 form)."""
    return yaml.safe_dump(dump_qos_v9(list(profiles)), default_flow_style=False, sort_keys=False).strip()


#: The keys of ``rosbag2_bagfile_information`` a reader needs, with the type each must have.
_REQUIRED_KEYS: dict[str, tuple[type, ...]] = {
    "version": (int,), "storage_identifier": (str,), "relative_file_paths": (list,),
    "topics_with_message_count": (list,), "duration": (dict,), "starting_time": (dict,),
    "message_count": (int,),
}
_TYPE_NAMES = {int: "a whole number", str: "a string", list: "a list", dict: "a mapping"}


def check_metadata_file(path: Path) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` mapping of a bag's ``metadata.yaml``, checked.

    Raises:
        BagError: naming the file and what is wrong: unreadable, not UTF-8 text, not valid YAML
            (with line and column), not a mapping with ``rosbag2_bagfile_information``, a missing
            key or one of the wrong type, a version newer than :data:`VERSION`.
    """
    document = load_yaml_file(path, BagError)
    info = document.get("rosbag2_bagfile_information") if isinstance(document, dict) else None
    if not isinstance(info, dict):
        found = ("it is empty" if document is None else f"it holds {document!r:.40}, not a mapping") \
            if not isinstance(document, dict) else "'rosbag2_bagfile_information' is missing or not a mapping"
        raise BagError(f"{path}: not rosbag2 metadata ({found}); the file is a mapping with one key, "
                       "'rosbag2_bagfile_information'")
    for key, types in _REQUIRED_KEYS.items():
        if key not in info:
            raise BagError(f"{path}: rosbag2_bagfile_information has no '{key}'")
        value = info[key]
        if isinstance(value, bool) or not isinstance(value, types):
            raise BagError(f"{path}: rosbag2_bagfile_information.{key} must be {_TYPE_NAMES[types[0]]}, "
                           f"not {value!r:.60}")
    if not 1 <= info["version"] <= VERSION:
        raise BagError(f"{path}: rosbag2 metadata version {info['version']} is not supported (1 to {VERSION})")
    for i, topic in enumerate(info["topics_with_message_count"]):
        meta = topic.get("topic_metadata") if isinstance(topic, dict) else None
        if not isinstance(meta, dict) or not all(isinstance(meta.get(k), str) for k in ("name", "type")) \
                or not isinstance(topic.get("message_count"), int):
            raise BagError(f"{path}: rosbag2_bagfile_information.topics_with_message_count[{i}] must be "
                           f"{{topic_metadata: {{name, type, serialization_format, ...}}, message_count}}, "
                           f"not {topic!r:.80}")
    if not all(isinstance(name, str) for name in info["relative_file_paths"]):
        raise BagError(f"{path}: rosbag2_bagfile_information.relative_file_paths must be a list of file names, "
                       f"not {info['relative_file_paths']!r:.80}")
    files = info.get("files") or []  # optional (version 5 and later)
    for i, file in enumerate(files if isinstance(files, list) else [files]):
        if not isinstance(file, dict) or not isinstance(file.get("path"), str):
            where = f"[{i}]" if isinstance(files, list) else ""
            raise BagError(f"{path}: rosbag2_bagfile_information.files{where} must be {{path, starting_time, "
                           f"duration, message_count}}, not {file!r:.80}")
    return info


@dataclass
class Topic:
    """One recorded topic: its metadata and how many messages it has."""

    name: str
    type: str
    offered_qos_profiles: list[Qos]
    type_description_hash: str = ""
    serialization_format: str = "cdr"
    message_count: int = 0

    def as_yaml_dict(self) -> dict[str, Any]:
        return {
            "topic_metadata": {
                "name": self.name,
                "type": self.type,
                "serialization_format": self.serialization_format,
                "offered_qos_profiles": dump_qos_v9(list(self.offered_qos_profiles)),
                "type_description_hash": self.type_description_hash,
            },
            "message_count": self.message_count,
        }


@dataclass
class FileInfo:
    """One storage file of a (possibly split) bag."""

    path: str
    start_ns: int = 0
    end_ns: int = 0
    message_count: int = 0

    def add(self, stamp_ns: int) -> None:
        if self.message_count == 0:
            self.start_ns = self.end_ns = stamp_ns
        else:
            self.start_ns = min(self.start_ns, stamp_ns)
            self.end_ns = max(self.end_ns, stamp_ns)
        self.message_count += 1

    def as_yaml_dict(self) -> dict[str, Any]:
        return {"path": self.path,
                "starting_time": {"nanoseconds_since_epoch": self.start_ns},
                "duration": {"nanoseconds": self.end_ns - self.start_ns},
                "message_count": self.message_count}


@dataclass
class BagMetadata:
    """What ``metadata.yaml`` says about a bag."""

    topics: list[Topic] = field(default_factory=list)
    files: list[FileInfo] = field(default_factory=list)
    compression_mode: str = ""
    compression_format: str = ""
    ros_distro: str = "jazzy"
    custom_data: dict[str, str] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        return sum(f.message_count for f in self.files)

    def as_yaml_dict(self, files: Sequence[FileInfo] | None = None,
                     topics: Sequence[Topic] | None = None) -> dict[str, Any]:
        """The ``rosbag2_bagfile_information`` mapping, for all files or just ``files``."""
        files = list(self.files if files is None else files)
        topics = list(self.topics if topics is None else topics)
        stamps = [f for f in files if f.message_count]
        start = min((f.start_ns for f in stamps), default=0)
        end = max((f.end_ns for f in stamps), default=0)
        return {
            "version": VERSION,
            "storage_identifier": STORAGE_ID,
            "duration": {"nanoseconds": end - start},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.message_count for f in files),
            "topics_with_message_count": [t.as_yaml_dict() for t in topics],
            "compression_format": self.compression_format,
            "compression_mode": self.compression_mode,
            "relative_file_paths": [f.path for f in files],
            "files": [f.as_yaml_dict() for f in files],
            "custom_data": dict(self.custom_data) or None,
            "ros_distro": self.ros_distro,
        }

    def write(self, bag_dir: Path) -> None:
        """Write ``bag_dir/metadata.yaml`` atomically (a crash leaves the old one)."""
        text = yaml.safe_dump({"rosbag2_bagfile_information": self.as_yaml_dict()},
                              default_flow_style=False, sort_keys=False)
        tmp = bag_dir / "metadata.yaml.tmp"
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(bag_dir / "metadata.yaml")
