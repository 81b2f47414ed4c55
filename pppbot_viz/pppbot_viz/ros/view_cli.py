"""``pppbot view``: the live view on its own: of a bag being played, of a robot on this ROS domain, or of a recording.

    pppbot view                      # what runs on this ROS_DOMAIN_ID, e.g. `pppbot bag play BAG --clock`
    pppbot view eval_slam_maze_…/view.rrd   # a recording (pppbot eval's view.rrd)
    pppbot view --port 9091 --viewer web

It is the view ``launch_sim`` starts (``use_viz:=true``): rerun's server on 127.0.0.1
with analytics off, the ``viz`` node and its page with the 2D Goal Pose / 2D Pose
Estimate tools, and a native window when there is a display. A recording is shown as it
was saved; it has no ROS behind it, so its page sets no poses. Ctrl-C stops it.
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pppbot_common.process import StopTimeouts, die_with_parent, stop_process_group
from pppbot_common.resources import checkout_root
from pppbot_viz import viewer
from pppbot_viz.errors import VizError
from pppbot_viz.web import PoseRequest, ViewerPage

#: Wall seconds the rerun server gets to listen (it loads a recording first).
SERVER_START_S = 60.0
#: Wall seconds rerun's server and viewer get after SIGINT, and after SIGTERM, before SIGKILL. The
#: server ignores both (rerun 0.2x): waiting longer only lets whoever stops this program (a
#: launch's or a test's ladder, 5 s a rung) kill it first, and leave the server running.
STOP_S = 1.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = (__doc__ or "").split("\n", 1)[1]
    parser.add_argument("recording", nargs="?", type=Path, default=None,
                        help="a rerun recording (.rrd) to show instead of the ROS topics")
    parser.add_argument("--port", type=int, default=9090,
                        help="the page's port on 127.0.0.1 (default 9090, a free one when taken; 0: a free one)")
    parser.add_argument("--viewer", choices=[k.value for k in viewer.ViewerKind], default="auto",
                        help="native: a window; web: the page only; auto (default): a window too with a display")
    parser.add_argument("--fixed-frame", default="map", help="the view's frame, as RViz's Fixed Frame (default map)")
    parser.add_argument("--wall-time", action="store_true",
                        help="the node's clock (goal stamps) is the wall clock instead of sim time (/clock)")


def check_recording(path: Path) -> None:
    """Raises VizError unless ``path`` is a readable rerun recording (by its file header)."""
    try:
        with path.open("rb") as stream:
            magic = stream.read(4)
    except OSError as exc:
        raise VizError(f"{path}: can't read it ({exc.strerror or exc})") from exc
    if magic != b"RRF2":
        raise VizError(f"{path}: not a rerun recording (.rrd files start with 'RRF2'; pppbot eval writes view.rrd)")


def _refuse_pose(request: PoseRequest) -> str:
    raise VizError("a recording has no robot behind it: poses are set in a live view")


def main(args: argparse.Namespace) -> int:
    try:
        if args.recording is not None:
            check_recording(args.recording)
        port = viewer.available_port(args.port, "--port ")
        note = f"port {args.port} is taken; the page is on {port} instead" if args.port and port != args.port else None
        state_dir = viewer.state_directory(checkout_root())
        viewer.write_viewer_settings(state_dir)
        grpc_port, web_port = viewer.free_port(), viewer.free_port()
        command = viewer.server_command(grpc_port, web_port)
    except (VizError, OSError) as exc:
        print(f"pppbot view: {exc}", file=sys.stderr)
        return 2
    if note:
        print(f"pppbot view: {note}", file=sys.stderr)
    env = {**os.environ, **viewer.viewer_environment(state_dir), "RUST_LOG": "warn"}
    if args.recording is not None:
        command.append(str(args.recording))
    # Own process groups: stopped by this program, with the project's stop ladder.
    # And killed by the kernel should this program be killed first (rerun's server ignores SIGTERM).
    processes = [subprocess.Popen(command, env=env, stdin=subprocess.DEVNULL, start_new_session=True,
                                  preexec_fn=_die_with_view)]
    try:
        deadline = time.monotonic() + SERVER_START_S
        while not (viewer.listening(grpc_port) and viewer.listening(web_port)):
            if processes[0].poll() is not None or time.monotonic() > deadline:
                print(f"pppbot view: rerun's server did not start ({' '.join(command)})", file=sys.stderr)
                return 1
            time.sleep(0.1)
        if viewer.ViewerKind(args.viewer).native(os.environ):
            processes.append(subprocess.Popen(viewer.native_viewer_command(grpc_port), env=env,
                                              stdin=subprocess.DEVNULL, start_new_session=True,
                                              preexec_fn=_die_with_view))
        if args.recording is None:
            return _run_node(grpc_port, web_port, port, args, native=len(processes) > 1)
        return _serve_recording(grpc_port, web_port, port, args, processes[0])
    except KeyboardInterrupt:
        return 0
    finally:
        for process in reversed(processes):
            stop_process_group(process, StopTimeouts(STOP_S, STOP_S))


def _die_with_view() -> None:
    die_with_parent(signal.SIGKILL)


def _run_node(grpc_port: int, web_port: int, port: int, args: argparse.Namespace, native: bool) -> int:
    from pppbot_viz.ros import viz
    params = {"rerun_port": grpc_port, "rerun_web_port": web_port, "port": port, "fixed_frame": args.fixed_frame,
              "use_sim_time": str(not args.wall_time).lower(), "images_while_watched": str(not native).lower()}
    return viz.main(["pppbot view", "--ros-args", *(f for name, value in params.items()
                                                    for f in ("-p", f"{name}:={value}"))])


def _serve_recording(grpc_port: int, web_port: int, port: int, args: argparse.Namespace,
                     server: subprocess.Popen[bytes]) -> int:
    page = ViewerPage(port, grpc_port, web_port, _refuse_pose, args.fixed_frame)
    page.start()
    print(f"{args.recording}: open {page.url} in a browser (Ctrl-C stops)", flush=True)
    try:
        return _wait_for_stop(server)
    finally:
        page.close()


def _wait_for_stop(server: subprocess.Popen[bytes]) -> int:
    """Until Ctrl-C or SIGTERM (0; also when started with them ignored, as in a background job),
    or until rerun's server ends (1)."""
    stop = {signal.SIGINT, signal.SIGTERM}
    signal.pthread_sigmask(signal.SIG_BLOCK, stop)
    for number in stop:
        signal.signal(number, signal.SIG_DFL)  # blocked: waited for below, never acted on
    while server.poll() is None:
        if signal.sigtimedwait(stop, 1.0) is not None:
            return 0
    print("pppbot view: rerun's server ended", file=sys.stderr)
    return 1
