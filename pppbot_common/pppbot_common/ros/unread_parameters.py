"""Parameters given to a node that it never reads: named in one warning at start-up.

A parameter file written for Nav2, slam_toolbox or ros2_control may hold keys pppbot's node of
that name does not implement (a DWB critic's scale, a behaviour-tree plugin list). rclpy drops an
override nobody declares without a word; here each node that was given such keys says which,
once, when its process has built it, so that nothing in a user's file is silently ignored.
Nodes that declare every override they are given (``automatically_declare_parameters_from_overrides``,
as twist_mux) have none. A node may say why some keys have no effect (``parameter_notes``: a
pattern, ``*`` standing for any name, to its reason); the warning then groups them by reason.
"""
from __future__ import annotations

import fnmatch
from collections.abc import Collection, Iterable, Mapping

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


def reasons(names: Iterable[str], notes: Mapping[str, str], default: str) -> dict[str, list[str]]:
    """``names`` grouped by the reason of the first note whose pattern matches each (``default``
    for the rest); an empty reason counts as no reason to warn (rclpy reads ``use_sim_time``)."""
    grouped: dict[str, list[str]] = {}
    for name in names:
        reason = next((why for pattern, why in notes.items() if fnmatch.fnmatchcase(name, pattern)), default)
        grouped.setdefault(reason, []).append(name)
    grouped.pop("", None)
    return grouped


def warn_unread_parameters(node: Node, read_in_process: Collection[str] = ()) -> list[str]:
    """Log one warning naming ``node``'s unread parameters (if any), each with the reason it has no
    effect; returns those named."""
    default = f"pppbot's {node.get_name()} does not implement them"
    grouped = reasons(unread_parameters(node, read_in_process), getattr(node, "parameter_notes", {}), default)
    names = [name for group in grouped.values() for name in group]
    if names:
        parts = []
        for reason, group in grouped.items():
            shown = ", ".join(group[:LISTED]) + (f" and {len(group) - LISTED} more" if len(group) > LISTED else "")
            parts.append(f"{shown} ({reason})")
        node.get_logger().warning(f"{len(names)} parameter{'s' if len(names) > 1 else ''} given to "
                                  f"{node.get_name()} {'have' if len(names) > 1 else 'has'} no effect: "
                                  + "; ".join(parts))
    return names
