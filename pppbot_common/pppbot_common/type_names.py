"""Interface type names: ``pkg/msg/Name`` and its short form ``pkg/Name``."""
from __future__ import annotations

import re

from pppbot_common.errors import MessageTypeError

_TYPE_NAME = re.compile(r"^(?P<pkg>[A-Za-z][\w]*)/(?:(?P<kind>msg|srv|action)/)?(?P<name>[A-Z]\w*)$")


def split_type_name(type_name: str) -> tuple[str, str, str]:
    """``'pkg/msg/Name'`` or ``'pkg/Name'`` → ``(pkg, kind, Name)``.

    Raises:
        MessageTypeError: the name is not of that form.
    """
    match = _TYPE_NAME.match(type_name.strip())
    if match is None:
        raise MessageTypeError(
            f"'{type_name}' is not an interface type name; expected 'package/msg/Name' "
            "(e.g. 'geometry_msgs/msg/Twist')"
        )
    return match["pkg"], match["kind"] or "msg", match["name"]
