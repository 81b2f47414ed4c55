"""Message definitions and type hashes of installed interface types, for bags.

rosbag2 stores, per type, the complete definition in ``ros2msg`` form: the type's
``.msg`` text first, then each type it refers to (transitively), each after a line of
80 ``=`` and a ``MSG: pkg/msg/Name`` line. The referenced types and the RIHS01 hash
come from the type description (``share/<pkg>/msg/<Name>.json``) that rosidl installs
next to the ``.msg``, so nothing here parses message syntax.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from pppbot_common.type_names import split_type_name

DELIMITER = "=" * 80


@dataclass(frozen=True)
class TypeDefinition:
    """What a bag records about a type. ``encoding`` is ``ros2msg``, ``ros2idl`` or
    ``''`` when no definition is installed (the bag still plays; decoders need it)."""

    name: str
    encoding: str
    text: str
    type_hash: str


def _prefixes() -> list[Path]:
    return [Path(p) for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]


def interface_file(type_name: str, suffix: str) -> Path | None:
    """``share/<pkg>/<kind>/<Name><suffix>`` in the first prefix that has it."""
    pkg, kind, name = split_type_name(type_name)
    for prefix in _prefixes():
        path = prefix / "share" / pkg / kind / f"{name}{suffix}"
        if path.is_file():
            return path
    return None


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8")


@cache
def type_definition(type_name: str) -> TypeDefinition:
    """The complete definition and hash of an installed type (cached).

    Raises:
        MessageTypeError: ``type_name`` is not a type name.
    """
    pkg, kind, name = split_type_name(type_name)
    full = f"{pkg}/{kind}/{name}"
    description = interface_file(full, ".json")
    referenced: list[str] = []
    type_hash = ""
    if description is not None:
        try:
            data = json.loads(_read(description))
            referenced = [ref["type_name"] for ref in
                          data["type_description_msg"]["referenced_type_descriptions"]]
            type_hash = next((h["hash_string"] for h in data.get("type_hashes", [])
                              if h["type_name"] == full), "")
        except (ValueError, KeyError, TypeError):
            referenced, type_hash = [], ""
    msg_file = interface_file(full, ".msg")
    if msg_file is not None:
        parts = [_read(msg_file).rstrip("\n")]
        for ref in referenced:
            ref_file = interface_file(ref, ".msg")
            if ref_file is None:
                break
            parts.append(f"{DELIMITER}\nMSG: {ref}\n{_read(ref_file).rstrip(chr(10))}")
        else:
            return TypeDefinition(full, "ros2msg", "\n".join(parts) + "\n", type_hash)
    idl_file = interface_file(full, ".idl")
    if idl_file is not None:
        parts = [f"{DELIMITER}\nIDL: {full}\n{_read(idl_file)}"]
        for ref in referenced:
            ref_file = interface_file(ref, ".idl")
            if ref_file is not None:
                parts.append(f"{DELIMITER}\nIDL: {ref}\n{_read(ref_file)}")
        return TypeDefinition(full, "ros2idl", "".join(parts), type_hash)
    return TypeDefinition(full, "", "", type_hash)

