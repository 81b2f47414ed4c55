"""ROS interface types by name, and messages as plain data (for echo and bags)."""
from __future__ import annotations

import importlib
from collections import OrderedDict
from typing import Any

import yaml

from pppbot_common.errors import MessageTypeError
from pppbot_common.type_names import split_type_name


def get_interface(type_name: str) -> Any:
    """The Python class of an installed interface type.

    Raises:
        MessageTypeError: malformed name, package not installed, or no such type in it.
    """
    pkg, kind, name = split_type_name(type_name)
    try:
        module = importlib.import_module(f"{pkg}.{kind}")
    except ImportError as exc:
        raise MessageTypeError(
            f"interface package '{pkg}' (for '{type_name}') is not installed in this environment"
        ) from exc
    try:
        return getattr(module, name)
    except AttributeError as exc:
        raise MessageTypeError(f"'{pkg}/{kind}' has no type '{name}' (asked for '{type_name}')") from exc


def type_name_of(msg_class: Any) -> str:
    """``geometry_msgs.msg.Twist`` → ``'geometry_msgs/msg/Twist'``."""
    pkg, kind = msg_class.__module__.split(".")[:2]
    return f"{pkg}/{kind}/{msg_class.__name__}"


def message_to_dict(msg: Any, truncate_arrays: int | None = None, truncate_strings: int | None = None) -> Any:
    """A message as nested ordered dicts, lists and plain scalars (field order kept)."""
    if hasattr(msg, "get_fields_and_field_types"):
        return OrderedDict(
            (field, message_to_dict(getattr(msg, field), truncate_arrays, truncate_strings))
            for field in msg.get_fields_and_field_types()
        )
    if isinstance(msg, (bytes, bytearray)):
        msg = list(msg)
    if hasattr(msg, "tolist") and not isinstance(msg, (int, float)):
        msg = msg.tolist()
    if isinstance(msg, (list, tuple)):
        items = [message_to_dict(item, truncate_arrays, truncate_strings) for item in msg]
        if truncate_arrays is not None and len(items) > truncate_arrays:
            return items[:truncate_arrays] + ["..."]
        return items
    if isinstance(msg, str) and truncate_strings is not None and len(msg) > truncate_strings:
        return msg[:truncate_strings] + "..."
    if hasattr(msg, "item"):  # numpy scalar
        return msg.item()
    return msg


class _OrderedDumper(yaml.SafeDumper):
    pass


_OrderedDumper.add_representer(
    OrderedDict, lambda dumper, data: dumper.represent_mapping("tag:yaml.org,2002:map", data.items())
)


def message_to_yaml(msg: Any, flow_style: bool = False, truncate_arrays: int | None = None,
                    truncate_strings: int | None = None) -> str:
    """A message as YAML, in the layout ``ros2 topic echo`` prints."""
    data = message_to_dict(msg, truncate_arrays, truncate_strings)
    return yaml.dump(data, Dumper=_OrderedDumper, default_flow_style=flow_style, width=10_000,
                     allow_unicode=True, sort_keys=False)


def get_field(msg: Any, path: str) -> Any:
    """The value of a dotted field path, e.g. ``'header.stamp.sec'``.

    Raises:
        MessageTypeError: a part of the path is not a field.
    """
    value = msg
    for part in path.split("."):
        if not part:
            continue
        if not hasattr(value, "get_fields_and_field_types") or part not in value.get_fields_and_field_types():
            raise MessageTypeError(f"field '{part}' of '{path}' does not exist in {type(value).__name__}")
        value = getattr(value, part)
    return value
