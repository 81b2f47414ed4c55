"""Hypothesis strategies for hostile ROS messages of any type: every field from the message's own
type description (rosidl's ``SLOT_TYPES``), floats that are NaN, ±inf, huge or subnormal,
sequences empty or of mismatched lengths, frames that do not exist, stamps in any order."""
from __future__ import annotations

import math
from typing import Any

from hypothesis import strategies as st
from rosidl_parser.definition import (
    AbstractGenericString,
    AbstractNestedType,
    Array,
    BasicType,
    BoundedSequence,
    NamespacedType,
)

from pppbot_common.ros.messages import get_interface, type_name_of

#: Floats a subscriber must survive, beside Hypothesis' own.
NASTY_FLOATS = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1e300, -1e300, 5e-324, 1.0, -1.0]
#: Frames: the stack's own, none, one that does not exist, odd spellings.
FRAMES = ["map", "odom", "base_link", "base_footprint", "lidar_frame", "", "no_such_frame", "/map", "map ", "ü" * 3,
          "x" * 300]
_INTEGERS = {"int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 255), "octet": (0, 255),
             "char": (0, 255), "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
             "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1),
             "uint64": (0, 2**64 - 1)}
#: Fields drawn from a narrower range than their type allows, per message type: rclpy's own
#: parameter services (not pppbot's code) leave a request with a parameter type rclpy does not know
#: unanswered (they log the ValueError and go on); a wrong known type, NaN or huge values are drawn.
NARROWED = {"rcl_interfaces/msg/ParameterValue": {"type": st.integers(0, 9)}}
#: Longest sequence drawn (a scan of 6 beams beside a header saying 360 is "mismatched").
MAX_SEQUENCE = 6


def _basic(typename: str) -> st.SearchStrategy[Any]:
    if typename == "boolean":
        return st.booleans()
    if typename == "float":  # float32: its setter refuses what float32 cannot hold
        return st.one_of(st.sampled_from([3.4e38 if abs(v) == 1e300 else v for v in NASTY_FLOATS]), st.floats(width=32))
    if typename in ("double", "long double"):
        return st.one_of(st.sampled_from(NASTY_FLOATS), st.floats())
    low, high = _INTEGERS[typename]
    return st.one_of(st.sampled_from([low, high, 0, 1]), st.integers(low, high))


def _slot(slot: Any, field: str) -> st.SearchStrategy[Any]:
    if isinstance(slot, AbstractNestedType):
        value = _slot(slot.value_type, field)
        if isinstance(slot, Array):
            return st.lists(value, min_size=slot.size, max_size=slot.size)
        limit = slot.maximum_size if isinstance(slot, BoundedSequence) else MAX_SEQUENCE
        return st.lists(value, max_size=min(limit, MAX_SEQUENCE))
    if isinstance(slot, BasicType):
        return _basic(slot.typename)
    if isinstance(slot, AbstractGenericString):
        if "frame" in field:
            return st.sampled_from(FRAMES)
        return st.one_of(st.sampled_from(FRAMES), st.text(max_size=20))
    if isinstance(slot, NamespacedType):
        return messages(get_interface("/".join([*slot.namespaces, slot.name])))
    raise TypeError(f"no strategy for {slot!r}")


def messages(cls: Any) -> st.SearchStrategy[Any]:
    """Any message of ``cls``, every field drawn (a sequence of bytes as a list of ints)."""
    fields = list(cls.get_fields_and_field_types())
    slots = {name: _slot(slot, name) for name, slot in zip(fields, cls.SLOT_TYPES, strict=True)}
    slots.update(NARROWED.get(type_name_of(cls), {}))

    def build(values: dict[str, Any]) -> Any:
        msg = cls()
        for name, value in values.items():
            setattr(msg, name, value)
        return msg

    return st.fixed_dictionaries(slots).map(build)


def of_the_stack(name: str) -> bool:
    """Whether the node ``name`` is the stack's: not hidden, and not the test harness's (``ros_node``
    names its nodes ``pytest_<test>``; a node another test of this process left may still be in
    the graph until the garbage collector takes its participant)."""
    return not name.startswith(("_", "pytest_"))


def servers(node: Any) -> tuple[dict[str, str], dict[str, str]]:
    """Every action server and every service the stack's nodes offer, each with its type (an
    action's own services are the action's, not counted as services)."""
    from rclpy.action.graph import get_action_server_names_and_types_by_node

    actions: dict[str, str] = {}
    services: dict[str, str] = {}
    for name, namespace in node.get_node_names_and_namespaces():
        if not of_the_stack(name):
            continue
        for action, types in get_action_server_names_and_types_by_node(node, name, namespace):
            actions.setdefault(action, types[0])
        for service, types in node.get_service_names_and_types_by_node(name, namespace):
            if "/_action/" not in service and not service.startswith("/_"):
                services.setdefault(service, types[0])
    return actions, services
