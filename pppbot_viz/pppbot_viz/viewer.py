"""The rerun viewer processes the live view runs: the gRPC + web server (always) and the native
viewer (with a display), each bound to 127.0.0.1 with rerun's usage analytics off.

rerun's command line is the wheel's own binary (``rerun_cli/rerun``), started directly so the
launch's signals reach the process that listens. Its analytics are switched off the way
``rerun analytics disable`` does, in a config directory of pppbot's own (``XDG_CONFIG_HOME``),
so nothing is written to the user's home.
"""
from __future__ import annotations

import enum
import json
import os
import socket
from collections.abc import Mapping
from pathlib import Path

from pppbot_viz.errors import VizError

#: the server keeps the newest data up to this for viewers that connect late, then drops the oldest
#: (half a minute or so of a mapping run: what a page opened late catches up with before it shows
#: the present; the view sends it the newest map, costmaps, plans and trail when it starts). With
#: 32 MiB, a page opened 12.5 minutes into a mapping run filled the browser's 4 GB WebAssembly heap
#: within 90 s and never caught up; with 2 MiB it shows the present within 30 s at about 710 MB
#: (benchmarks/view_browser.py --late-pages, RESULTS.md)
SERVER_MEMORY_LIMIT = "2MiB"
#: the native viewer's cap: past it, it drops its oldest data, keeping each thing's newest
VIEWER_MEMORY_LIMIT = "2GiB"
#: the web page's viewer's cap, the same way: over half an hour of mapping the tab levels off near
#: 1.0 GB with it (1.25 GB with 512 MiB; benchmarks/view_browser.py, RESULTS.md)
WEB_VIEWER_MEMORY_LIMIT = "256MiB"
LOCALHOST = "127.0.0.1"


class ViewerKind(enum.Enum):
    """``viz_viewer:=``: which viewer shows the live view. The web page is served in every case
    (it is where clicks become goals)."""

    AUTO = "auto"  # native with a display, else web
    NATIVE = "native"
    WEB = "web"

    def native(self, environ: Mapping[str, str]) -> bool:
        return self is ViewerKind.NATIVE or (self is ViewerKind.AUTO and has_display(environ))


def has_display(environ: Mapping[str, str]) -> bool:
    """A graphical session to open a window in (X11 or Wayland)."""
    return bool(environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY"))


def rerun_binary() -> Path:
    """The rerun command line the ``rerun-sdk`` wheel ships.

    Raises:
        VizError: rerun-sdk is not installed (``./pppbot setup`` installs it).
    """
    try:
        import rerun_cli
    except ImportError as exc:
        raise VizError("the live view needs rerun-sdk (./pppbot setup installs it)") from exc
    binary = Path(rerun_cli.__file__).parent / "rerun"
    if not binary.is_file():
        raise VizError(f"rerun-sdk is installed without its viewer binary ({binary} is missing)")
    return binary


def grpc_url(port: int, host: str = LOCALHOST) -> str:
    """Where logging SDKs and viewers reach the server."""
    return f"rerun+http://{host}:{port}/proxy"


def server_command(grpc_port: int, web_port: int, memory_limit: str = SERVER_MEMORY_LIMIT) -> list[str]:
    """The gRPC proxy and the bundled web viewer's files, on 127.0.0.1 only. A viewer that
    connects late gets the newest data first (in logged order instead, a page opened with the
    stack, as tests/pppbot_viz/test_live_view.py opens it, took 70 s longer on a busy machine)."""
    return [str(rerun_binary()), "--serve-web", "--bind", LOCALHOST, "--port", str(grpc_port),
            "--web-viewer-port", str(web_port), "--server-memory-limit", memory_limit, "--newest-first"]


def native_viewer_command(grpc_port: int, memory_limit: str = VIEWER_MEMORY_LIMIT) -> list[str]:
    """A native viewer window on the server's stream (its own server on a free 127.0.0.1 port)."""
    return [str(rerun_binary()), "--connect", grpc_url(grpc_port), "--bind", LOCALHOST, "--port", "auto",
            "--memory-limit", memory_limit]


def viewer_environment(state_dir: Path) -> dict[str, str]:
    """The environment for rerun's processes: its config and data directories under ``state_dir``
    (:func:`write_viewer_settings` puts the settings there)."""
    return {"XDG_CONFIG_HOME": str(state_dir / "config"), "XDG_DATA_HOME": str(state_dir / "data"),
            # warnings and errors only: its start-up lines name ports and URLs that are not the
            # view's (the launch prints the page's address)
            "RUST_LOG": "warn"}


def write_viewer_settings(state_dir: Path) -> Path:
    """rerun's analytics settings, off, where :func:`viewer_environment` points rerun; the file.

    Raises:
        VizError: ``state_dir`` can't be written.
    """
    config_file = state_dir / "config" / "rerun" / "analytics.json"
    text = json.dumps({"analytics_enabled": False, "analytics_id": "0" * 32, "metadata": {},
                       "config_file_path": str(config_file),
                       "data_dir_path": str(state_dir / "data" / "rerun" / "analytics")})
    try:
        config_file.parent.mkdir(parents=True, exist_ok=True)
        if not config_file.is_file() or config_file.read_text() != text:
            # whole or not at all: a rerun another launch starts meanwhile reads the old file or this one
            part = config_file.with_name(f"{config_file.name}.{os.getpid()}")
            part.write_text(text)
            os.replace(part, config_file)
    except OSError as exc:
        raise VizError(f"can't write rerun's settings under {state_dir}: {exc}") from exc
    return config_file


def free_port(host: str = LOCALHOST) -> int:
    """A TCP port nothing listens on now (the OS's pick)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return int(sock.getsockname()[1])


def available_port(wanted: int, name: str) -> int:
    """``wanted`` when nothing listens on it, else (or when 0) a free port: the view must not keep
    the robot from starting. ``name`` names the argument in the error (``viz_port:=``, ``--port ``).

    Raises:
        VizError: ``wanted`` is not a port number.
    """
    if not 0 <= wanted <= 65535:
        raise VizError(f"{name}{wanted}: must be a port number 1-65535, or 0 for a free one")
    return wanted if wanted and not listening(wanted) else free_port()


def listening(port: int, host: str = LOCALHOST) -> bool:
    """Whether a server accepts connections on ``host:port``."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.settimeout(0.5)
        return sock.connect_ex((host, port)) == 0


def state_directory(checkout: Path | None) -> Path:
    """Where rerun's settings live: the checkout's ``build/rerun``, else ``$ROS_HOME/rerun``."""
    if checkout is not None:
        return checkout / "build" / "rerun"
    return Path(os.environ.get("ROS_HOME", Path.home() / ".ros")) / "rerun"
