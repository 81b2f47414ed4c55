"""Parameters given to a node that it never reads: named in one warning at start-up.

A parameter file written for Nav2, slam_toolbox or ros2_control may hold keys pppbot's node of
that name does not implement (a DWB critic's scale, a behaviour-tree plugin list). rclpy drops an
override nobody declares without a word; here each node that was given such keys says which,
once, when its process has built it, so that nothing in a user's file is silently ignored.
Nodes that declare every override they are given (``automatically_declare_parameters_from_overrides``,
as twist_mux) have none.
"""
from __future__ import annotations

from collections.abc import Collection, Iterable

from rclpy.node import Node

#: How many names one warning lists before it says how many more there are.
LISTED = 12
#: Parameters a process reads for all its nodes (its lockstep participant's), given to each.
PROCESS_PARAMETERS = frozenset({"lockstep", "lockstep_name"})


def unread_parameters(node: Node, read_in_process: Collection[str] = ()) -> list[str]:
    """The names of the overrides ``node`` was given (``--params-file``, ``-p``) that it has not
    declared, sorted. ``read_in_process``: names other nodes of its process read; a ``-p`` without a
    node name goes to every node of the process (the simulator's ``world`` to the controllers it
    hosts), so these count as read."""
    overrides = getattr(node, "_parameter_overrides", {}) or {}
    return sorted(name for name in overrides if not node.has_parameter(name) and name not in PROCESS_PARAMETERS
                  and name not in read_in_process)


def declared_names(nodes: Iterable[Node]) -> set[str]:
    """Every parameter name the ``nodes`` declare."""
    return {name for node in nodes for name in getattr(node, "_parameters", {})}


def warn_unread_parameters(node: Node, read_in_process: Collection[str] = ()) -> list[str]:
    """Log one warning naming ``node``'s unread parameters (if any); returns them."""
    names = unread_parameters(node, read_in_process)
    if names:
        shown = ", ".join(names[:LISTED]) + (f" and {len(names) - LISTED} more" if len(names) > LISTED else "")
        node.get_logger().warning(f"{len(names)} parameter{'s' if len(names) > 1 else ''} given to "
                                  f"{node.get_name()} {'have' if len(names) > 1 else 'has'} no effect: pppbot's "
                                  f"{node.get_name()} does not implement {'them' if len(names) > 1 else 'it'}: "
                                  f"{shown}")
    return names
