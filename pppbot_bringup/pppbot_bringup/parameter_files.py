"""The parameter files ``launch_sim`` is given (``params_file:=`` and the others), checked before
anything starts: one message naming the argument, the file and what is wrong."""
from __future__ import annotations

from pathlib import Path

import yaml

from pppbot_common.errors import ParameterFileError
from pppbot_common.launch_args import ArgumentError
from pppbot_common.param_files import check_parameter_file, is_static_layer, node_parameters


def parameter_file(given: str, default: Path, argument: str) -> Path:
    """The parameter file ``argument:=given`` names (``default`` when empty), checked before anything
    starts: it exists and is a ROS 2 parameter file (:func:`pppbot_common.param_files.check_parameter_file`).

    Raises:
        ArgumentError: naming the argument, the file and, for bad YAML, the line and column.
    """
    path = Path(given) if given else default
    if not path.is_file():
        raise ArgumentError(f"{argument}:={path}: no such file")
    try:
        check_parameter_file(path)
    except ParameterFileError as exc:
        raise ArgumentError(f"{argument}:={exc}") from exc
    return path


def check_slam_localization(path: Path) -> None:
    """A slam file with ``mode: localization`` (slam_toolbox's localization node) must name the pose
    graph it localizes in, which must exist: else the node would wait for a deserialize_map call
    and the launch for a /map that never comes.

    Raises:
        ArgumentError: naming the file, the key and what is missing.
    """
    document = yaml.safe_load(path.read_text()) or {}
    sections = [v.get("ros__parameters", {}) for k, v in document.items()
                if isinstance(v, dict) and k.lstrip("/") in ("slam_toolbox", "**")]
    params = {k: v for section in sections if isinstance(section, dict) for k, v in section.items()}
    if params.get("mode") != "localization":
        return
    graph = str(params.get("map_file_name") or "")
    if not graph:
        raise ArgumentError(f"slam_params_file:={path}: mode: localization needs map_file_name, the pose graph to "
                            "localize in (serialize one with /slam_toolbox/serialize_map while mapping)")
    stem = Path(graph).expanduser()
    if not stem.with_name(stem.name + ".posegraph").is_file() and not stem.is_file():
        raise ArgumentError(f"slam_params_file:={path}: map_file_name: {graph}: no pose graph "
                            f"{stem.name}.posegraph there")


def map_free_navigation_problem(path: Path, odom_frame: str = "odom") -> str | None:
    """Why Nav2's parameters at ``path`` (already checked) cannot navigate without a map frame, or
    None when they can: as Nav2 runs with no map (outdoors, exploring), the navigator's and the
    behaviours' ``global_frame`` and the global costmap's are ``odom_frame``, and the global costmap
    rolls with the robot (``rolling_window: true``) and has no ``static_layer``."""
    nodes = check_parameter_file(path)
    wrong = []
    for node, key, wanted in (("/bt_navigator", "global_frame", odom_frame),
                              ("/behavior_server", "global_frame", odom_frame),
                              ("/global_costmap/global_costmap", "global_frame", odom_frame),
                              ("/global_costmap/global_costmap", "rolling_window", True)):
        value = node_parameters(nodes, node).get(key, "map" if key == "global_frame" else False)
        if value != wanted:
            wrong.append(f"{node.lstrip('/')} {key}: {value} (not {str(wanted).lower()})")
    costmap = node_parameters(nodes, "/global_costmap/global_costmap")
    plugins = costmap.get("plugins", ["static_layer"])
    static = [p for p in (plugins if isinstance(plugins, list) else [plugins])
              if is_static_layer(p, costmap.get(f"{p}.plugin"))]
    if static:
        wrong.append(f"global_costmap plugins include {', '.join(map(str, static))} (a StaticLayer waits for a /map)")
    return "; ".join(wrong) or None


#: The arguments that name ROS 2 parameter files.
PARAMETER_FILES = ("params_file", "slam_params_file", "twist_mux_params", "controllers_file", "joy_params")


#: Nodes Jazzy's Nav2 bringup runs that ppp_bot's (Humble's) did not: a params file written for
#: that bringup has no section for them, and they have no defaults that make sense (the collision
#: monitor needs its zones); the launch leaves them out (their commands bridged) when a file lacks
#: their section.
NOT_IN_PPP_BOTS_BRINGUP = ("collision_monitor",)


def sections_missing(path: Path, nodes: tuple[str, ...]) -> list[str]:
    """Which of ``nodes`` the parameter file at ``path`` (already checked) has no section for: no
    ``<node>:`` or ``/<node>:`` key (a ``/**`` section sets what all nodes share, not a node's own)."""
    try:
        document = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError):
        return []
    keys = {str(key).lstrip("/") for key in document} if isinstance(document, dict) else set()
    return [node for node in nodes if node not in keys]


def missing_sections_note(path: Path, missing: list[str], left_out: list[str]) -> str:
    """One line: which nodes run on their defaults and which are left out, for a file without their sections."""
    parts = []
    if left_out:
        parts.append(f"{', '.join(left_out)} left out (not in ppp_bot's Humble-era bringup, and no defaults "
                     "make sense; its commands are bridged: velocity_smoother to twist_mux)")
    defaults = [node for node in missing if node not in left_out]
    if defaults:
        parts.append(f"{', '.join(defaults)} on Nav2's defaults")
    return f"{path.name} has no section for {len(missing)} node(s): {'; '.join(parts)}"
