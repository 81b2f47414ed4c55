"""``launch_sim``: the simulation bringup, ppp_bot's ``launch_sim.launch.py`` (``name:=value`` arguments).

    ./pppbot launch_sim [world:=cones] [localization:=false] [use_teleop:=true] ...
    ./pppbot launch_sim --show-args

Start order, each step waiting for real readiness (a first message or a node's endpoints on
the graph, never a sleep): simulator (first /clock; the robot's controllers or DiffDrive plugin
run in it) → robot_state_publisher (/robot_description) → twist_mux (its output and inputs) →
mapping or localization → navigation → RViz (when on PATH) → the live view → keyboard teleop.
Every argument is checked, and the domain looked at, before anything starts.
"""
from __future__ import annotations

import contextlib
import os
import shutil
import sys
import time
from collections.abc import Sequence
from typing import Any

from pppbot_viz.errors import VizError

from pppbot_bringup.launch_sim import ARGUMENTS, LaunchArgs, controllers_file, parameter_file, plan
from pppbot_bringup.node_specs import VizPlan, twist_mux_inputs
from pppbot_bringup.notices import first_time
from pppbot_bringup.paths import checkout_root, config_directory, log_root, new_run_dir
from pppbot_bringup.robot import load_description, robot_facts
from pppbot_bringup.ros.graph_probe import GraphProbe, domain_taken_message
from pppbot_bringup.run import RunError, find_executable
from pppbot_bringup.supervisor import Output, Supervisor
from pppbot_common.launch_args import ArgumentError, describe
from pppbot_description.errors import DescriptionError
from pppbot_sim.errors import SpawnError, WorldError
from pppbot_sim.simulation import check_world
from pppbot_sim.worlds import find_world
from pppbot_viz import viewer


def viz_plan(args: LaunchArgs) -> tuple[VizPlan, list[str]]:
    """The live view's ports (the rerun server's: free ones; the page's: ``viz_port``, or a free
    one when that is taken: the view must not keep the robot from starting) and its settings,
    written; and what the user should know.

    Raises:
        VizError: ``viz_port`` is not a port number, or rerun's settings can't be written.
    """
    notes: list[str] = []
    page_port = viewer.available_port(args.viz_port, "viz_port:=")
    if args.viz_port and page_port != args.viz_port:
        notes.append(f"viz_port:={args.viz_port} is taken (another launch_sim?): the live view takes port "
                     f"{page_port} instead")
    state_dir = viewer.state_directory(checkout_root())
    viewer.write_viewer_settings(state_dir)
    return VizPlan(viewer.free_port(), viewer.free_port(), page_port, args.viz_viewer.native(os.environ),
                   state_dir), notes


def run(argv: Sequence[str]) -> int:
    if any(a in ("--show-args", "-s", "-h", "--help") for a in argv):
        print(__doc__.strip(), "", describe(ARGUMENTS), sep="\n")
        return 0
    terminal = sys.stdin.isatty() and sys.stdout.isatty()
    try:
        args = LaunchArgs.parse(argv)
        args.validate(os.environ)
        sigint_timeout_s, sigterm_timeout_s = args.stop_timeouts()
        world_file = find_world(args.world)
        check_world(world_file)
        controllers = controllers_file(args.controllers_file)
        urdf, urdf_source = load_description(args.description, args.xacro_args, controllers)
        mux_params = parameter_file(args.twist_mux_params, config_directory() / "twist_mux.yaml", "twist_mux_params")
        robot = robot_facts(urdf, urdf_source, twist_mux_inputs(mux_params))
        viz, viz_notes = viz_plan(args) if args.use_viz else (None, [])
        probe = GraphProbe()
        running = probe.running_stack()
        if running is not None:
            probe.close()
            raise ArgumentError(domain_taken_message(running))
        run_dir = new_run_dir(log_root(), time.strftime("%Y-%m-%d-%H-%M-%S"))
        urdf_file = run_dir / "robot.urdf"
    except (ArgumentError, WorldError, SpawnError, DescriptionError, RunError, VizError, OSError) as exc:
        print(f"launch_sim: {exc}", file=sys.stderr)
        return 2
    os.environ["PYTHONUNBUFFERED"] = "1"  # children's print() reaches the log as it happens
    try:
        try:
            the_plan = plan(args, world_file, urdf_file,
                            lambda pkg, exe: str(find_executable(pkg, exe)),
                            probe,
                            terminal and args.use_teleop, shutil.which("rviz2"), viz=viz, robot=robot)
        except (ArgumentError, RunError) as exc:
            print(f"launch_sim: {exc}", file=sys.stderr)
            with contextlib.suppress(OSError):
                run_dir.rmdir()  # nothing in it yet
            return 2
        urdf_file.write_text(urdf)
        for path, text in the_plan.files.items():
            path.write_text(text)
        teleop_owns_terminal = any(n.terminal for n in the_plan.nodes)
        output = Output(sys.stdout, log_dir=run_dir if teleop_owns_terminal else None)
        output.event("INFO", "launch", f"log directory: {run_dir}")
        if teleop_owns_terminal:
            output.event("INFO", "launch", "node output goes to the log directory; warnings and errors show here")
        for note in the_plan.start_info:
            output.event("INFO", "launch", note)
        for key, note in the_plan.once.items():
            if first_time(key):
                output.event("INFO", "launch", note)
        for note in [*viz_notes, *the_plan.notes]:
            output.event("WARNING", "launch", note)
        supervisor = Supervisor(the_plan.nodes, output, sigint_timeout_s=sigint_timeout_s,
                                sigterm_timeout_s=sigterm_timeout_s)
        supervisor.install_signal_handlers()
        announced = False

        def announce() -> bool:
            nonlocal announced
            if not announced and all(supervisor.is_ready(n.name) for n in the_plan.nodes):
                announced = True
                probe.close()  # its subscriptions are not needed any more
                drive = "the teleop keys" if teleop_owns_terminal else "./pppbot teleop (in another terminal)"
                output.event("INFO", "launch", f"{robot.name} is up in '{world_file.stem}': drive with {drive}; "
                                               "Ctrl-C stops everything")
                for line in the_plan.info:
                    output.event("INFO", "launch", line)
            return False

        return supervisor.run(until=announce)
    finally:
        probe.close()


# ------------------------------------------------------------ command line
def add_arguments(parser: Any) -> None:
    """Unused: ``pppbot launch_sim`` hands its raw arguments to :func:`main_argv`."""


def main_argv(argv: list[str]) -> int:
    return run(argv)


def main() -> int:
    """Console entry point (``ros2 run pppbot_bringup launch_sim world:=maze``)."""
    return run(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
