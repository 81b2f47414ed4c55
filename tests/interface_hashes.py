"""Interface packages built from their definitions (``interfaces/``): the type hashes their build
generated, and the one a publisher announces on DDS, to compare with a release's."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ament_index_python.packages import get_package_share_directory

from pppbot_common.ros.wait import wait_until


def built_hashes(package: str) -> dict[str, str]:
    """Each type's RIHS01 hash as the build wrote it (its type descriptions), by ``msg/Name`` or
    ``srv/Name[_Request|_Response|_Event]``."""
    share = Path(get_package_share_directory(package))
    return {entry["type_name"].removeprefix(f"{package}/"): entry["hash_string"]
            for path in sorted([*share.glob("msg/*.json"), *share.glob("srv/*.json")])
            for entry in json.loads(path.read_text())["type_hashes"]
            if entry["type_name"].startswith(f"{package}/")}


def announced_hash(node: Any, msg_type: Any, topic: str) -> str:
    """The type hash a publisher of ``msg_type`` on ``topic`` announces, as the graph shows it."""
    publisher = node.create_publisher(msg_type, topic, 1)
    try:
        wait_until(lambda: node.get_publishers_info_by_topic(topic), 10, "the publisher in the graph", node=None)
        (info,) = node.get_publishers_info_by_topic(topic)
        return str(info.topic_type_hash)
    finally:
        node.destroy_publisher(publisher)
