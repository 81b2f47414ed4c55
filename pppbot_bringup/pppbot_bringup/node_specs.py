"""Building blocks of ``launch_sim``'s plan: the readiness probes a plan uses, the command
lines of its nodes, the live view's and the joystick's nodes, twist_mux's inputs."""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import yaml

from pppbot_bringup.supervisor import NodeSpec, ReadyCheck
from pppbot_common.launch_args import ArgumentError

Resolver = Callable[[str, str], str]


class Probes(Protocol):
    """Readiness from the ROS graph (:class:`pppbot_bringup.ros.graph_probe.GraphProbe`)."""

    def first_message(self, topic: str, type_name: str, latched: bool) -> Callable[[], bool]:
        """True once a message came on ``topic``."""

    def endpoints(self, node: str, publishes: Sequence[str] = (), subscribes: Sequence[str] = (),
                  action_servers: Sequence[str] = ()) -> Callable[[], bool]:
        """True once ``node`` publishes, subscribes and serves every one of these names."""

    def joined(self, participant: str) -> Callable[[], bool]:
        """True once the simulator lists ``participant`` on /lockstep/status."""

    def lifecycle_active(self, node: str) -> Callable[[], bool]:
        """True once lifecycle node ``node`` says it is active."""


@dataclass(frozen=True)
class Endpoints:
    """What a navigation node has once it is up, as its own process: ``description`` says it."""

    description: str
    action_servers: tuple[str, ...] = ()
    subscribes: tuple[str, ...] = ()


def _serving(action: str) -> Endpoints:
    return Endpoints(f"its {action} action server", action_servers=(f"/{action}",))


#: Each node of lifecycle_manager_navigation's, and how its readiness shows.
NAVIGATION_ENDPOINTS = {
    "controller_server": _serving("follow_path"), "smoother_server": _serving("smooth_path"),
    "planner_server": _serving("compute_path_to_pose"), "behavior_server": _serving("spin"),
    "velocity_smoother": Endpoints("its /cmd_vel_nav subscription", subscribes=("/cmd_vel_nav",)),
    "collision_monitor": Endpoints("its /cmd_vel_smoothed subscription", subscribes=("/cmd_vel_smoothed",)),
    "bt_navigator": _serving("navigate_to_pose"), "waypoint_follower": _serving("follow_waypoints")}


#: Scans a view recording without a live view keeps per second (of 10): a fifth of the size.
RECORDING_SCAN_HZ = 2.0


@dataclass(frozen=True)
class VizPlan:
    """Where the live view runs: the rerun server's ports, the page's, the viewer and rerun's
    settings directory."""

    grpc_port: int
    web_port: int
    page_port: int
    native: bool
    state_dir: Path


def viz_nodes(viz: VizPlan | None, recording: Path | None, resolve: Resolver, probes: Probes, level: str,
              after: tuple[str, ...]) -> list[NodeSpec]:
    """The live view: the rerun server (gRPC and the web viewer's files, 127.0.0.1 only), the
    native viewer when asked for, and the viz node that streams to the server and serves the
    page; with ``recording``, the viz node also writes the stream to that ``.rrd`` file. Without
    ``viz``, only the viz node writing ``recording``."""
    from pppbot_viz import viewer
    nodes: list[NodeSpec] = []
    params: dict[str, Any] = {}
    if viz is not None:
        env = viewer.viewer_environment(viz.state_dir)
        nodes.append(NodeSpec("rerun", viewer.server_command(viz.grpc_port, viz.web_port), env=env,
                              ready=ReadyCheck(f"listening on 127.0.0.1:{viz.grpc_port}",
                                               lambda: viewer.listening(viz.grpc_port)
                                               and viewer.listening(viz.web_port))))
        if viz.native:
            nodes.append(NodeSpec("rerun_viewer", viewer.native_viewer_command(viz.grpc_port), env=env,
                                  after=("rerun",)))
        params.update(rerun_port=viz.grpc_port, rerun_web_port=viz.web_port, port=viz.page_port, announce=False,
                      images_while_watched=not viz.native)
        after = ("rerun", *after)
    if recording is not None:
        params["recording_path"] = str(recording)
        if viz is None:  # a recording only (the evaluation's): every scan would be most of the file
            params["scan_max_rate_hz"] = RECORDING_SCAN_HZ
    nodes.append(NodeSpec("viz", [resolve("pppbot_viz", "viz"), *ros_args(level, params)],
                          after=after, pppbot_node=True,
                          ready=ReadyCheck("its subscriptions", probes.endpoints(
                              "viz", publishes=("/goal_pose", "/initialpose"), subscribes=("/map", "/scan")))))
    return nodes


def twist_mux_inputs(params_file: Path) -> tuple[str, ...]:
    """The topics twist_mux subscribes (its ``topics`` and ``locks`` entries' ``topic``), fully
    qualified, from its parameter file (the ``twist_mux`` or ``/**`` section).

    Raises:
        ArgumentError: the file cannot be read or has no such section.
    """
    try:
        document = yaml.safe_load(params_file.read_text())
        section = next(document[key]["ros__parameters"] for key in ("twist_mux", "/twist_mux", "/**")
                       if key in document)
        entries = [*section.get("topics", {}).values(), *section.get("locks", {}).values()]
        return tuple(sorted({"/" + str(entry["topic"]).lstrip("/") for entry in entries}))
    except (OSError, yaml.YAMLError, TypeError, KeyError, AttributeError, StopIteration) as exc:
        raise ArgumentError(f"{params_file}: not a twist_mux parameter file with topics.<name>.topic entries "
                            f"({type(exc).__name__}: {exc})") from exc


def ros_args(log_level: str, params: dict[str, Any] | None = None, params_file: Path | None = None,
             remaps: dict[str, str] | None = None, sim_time: bool = True) -> list[str]:
    args = ["--ros-args", "--log-level", log_level]
    if params_file is not None:
        args += ["--params-file", str(params_file)]
    all_params = {"use_sim_time": True} if sim_time else {}
    all_params.update(params or {})
    for name, value in all_params.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        args += ["-p", f"{name}:={text}"]
    for old, new in (remaps or {}).items():
        args += ["-r", f"{old}:={new}"]
    return args


def joystick_nodes(joy_config: Path, resolve: Any, level: str, after: str) -> list[NodeSpec]:
    """ppp_bot's joystick.launch.py: joy_node, and teleop_twist_joy named ``teleop_node`` (its section
    of joystick.yaml) publishing into twist_mux's teleop input. Neither is required: a missing
    joystick is said once and the rest runs."""
    return [
        NodeSpec("joy_node", [resolve("pppbot_control", "joy_node"), *ros_args(level, params_file=joy_config)],
                 after=("simulator",), pppbot_node=True),
        NodeSpec("teleop_node", [resolve("pppbot_control", "teleop_node"), *ros_args(
            level, params_file=joy_config, remaps={"__node": "teleop_node", "cmd_vel": "/cmd_vel_teleop"})],
            after=(after,), pppbot_node=True),
    ]


@dataclass(frozen=True)
class Beside:
    """robot_state_publisher and twist_mux in the simulator's process (``use_composition:=true``):
    their settings, and how their readiness shows."""

    urdf_file: Path
    mux_config: Path
    #: where twist_mux's output goes (the controller's command topic)
    command_topic: str
    rsp_ready: ReadyCheck
    mux_ready: ReadyCheck


def simulator_spec(resolve: Resolver, probes: Probes, level: str, params: dict[str, Any],
                   beside: Beside | None) -> NodeSpec:
    """The simulator, up at its first /clock. With ``beside``, robot_state_publisher and twist_mux run
    in its process (``--host``), as a component container runs components: each node's parameters
    and remappings scoped to it, their clocks the simulation's (``use_sim_time`` false: set by the
    simulator), in lockstep on its step port (their topics in-process, no round trips of their own);
    up once all three are."""
    clock = ReadyCheck("a first /clock", probes.first_message("/clock", "rosgraph_msgs/msg/Clock", False))
    executable = resolve("pppbot_sim", "simulator")
    if beside is None:
        return NodeSpec("simulator", [executable, *ros_args(level, params, sim_time=False)], ready=clock,
                        required=True, pppbot_node=True)
    scoped: dict[str, Any] = {f"simulator:{name}": value for name, value in params.items()}
    scoped.update({"robot_state_publisher:robot_description": beside.urdf_file,
                   "robot_state_publisher:use_sim_time": False, "twist_mux:use_sim_time": False})
    checks = (clock, beside.rsp_ready, beside.mux_ready)
    ready = ReadyCheck(", ".join(c.description for c in checks), lambda: all(c.probe() for c in checks))
    return NodeSpec("simulator", [executable, "--host", "robot_state_publisher", "--host", "twist_mux", *ros_args(
        level, scoped, params_file=beside.mux_config, remaps={"twist_mux:cmd_vel_out": beside.command_topic},
        sim_time=False)], ready=ready, required=True, pppbot_node=True)
