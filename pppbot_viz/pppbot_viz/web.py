"""The live view's web page: rerun's bundled web viewer with RViz's "2D Pose Estimate" and
"2D Goal Pose" tools on top, served on 127.0.0.1.

The viewer's files (``re_viewer.js``, ``re_viewer_bg.wasm``) come from rerun's own web server
(``rerun --serve-web``), which this server forwards to; only the page is pppbot's
(``page.html``). The page starts the viewer with its ``on_viewer_event`` option, which reports
where a click hit the scene in the view's frame (``map``), and posts two clicks (a position
and a point in the heading) to ``/pose``.

The page's Content-Security-Policy lets it connect to this server and the rerun server on
127.0.0.1 only, so the viewer's update check and usage reports never leave the machine.
"""
from __future__ import annotations

import contextlib
import http.server
import json
import math
import re
import threading
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources
from typing import Any, cast

from pppbot_viz.errors import VizError
from pppbot_viz.viewer import LOCALHOST, WEB_VIEWER_MEMORY_LIMIT, grpc_url
from pppbot_viz.visuals import pose_from_clicks

#: a page's viewer says it is still open this often (seconds)
ALIVE_PERIOD_S = 5.0
#: the timeline the view logs on (message stamps: sim time under a simulator)
TIMELINE = "sim_time"
#: the pose tools: a ``kind`` posted to ``/pose`` and the topic its pose goes to
POSE_KINDS = {"goal": "/goal_pose", "initial": "/initialpose"}
#: headers of rerun's responses the page needs (the wasm is served compressed, with its real size)
_FORWARDED_HEADERS = ("content-type", "content-encoding", "content-length", "rerun-final-length", "cache-control")
_MAX_POST_BYTES = 4096
#: what the page may ask for: its own path or one of rerun's files (never an absolute or odd
#: target, which would make the forwarded URL point elsewhere)
_ASSET_PATH = re.compile(r"^/(?!/)[A-Za-z0-9_.\-/]*(\?[A-Za-z0-9_.\-=&%+]*)?$")


@dataclass(frozen=True)
class PoseRequest:
    """A pose set in the view: ``kind`` ("goal" or "initial"), position (m) and heading (rad) in
    ``map``."""

    kind: str
    x: float
    y: float
    yaw: float


def parse_pose_request(body: bytes) -> PoseRequest:
    """A ``/pose`` body: ``{"kind": "goal"|"initial", "from": [x, y, ...], "to": [x, y, ...]}``.

    Raises:
        VizError: not JSON, an unknown kind, or positions that are not finite numbers.
    """
    try:
        data = json.loads(body)
        kind = data["kind"]
        first = [float(v) for v in data["from"][:2]]
        second = [float(v) for v in data["to"][:2]]
    except (ValueError, TypeError, KeyError) as exc:
        raise VizError(f'a pose must be {{"kind": "goal"|"initial", "from": [x, y], "to": [x, y]}} ({exc})') from exc
    if kind not in POSE_KINDS:
        raise VizError(f"kind '{kind}' is not one of {sorted(POSE_KINDS)}")
    if len(first) < 2 or len(second) < 2 or not all(math.isfinite(v) for v in (*first, *second)):
        raise VizError(f"positions must be two finite numbers each, got {data['from']} and {data['to']}")
    return PoseRequest(kind, *pose_from_clicks(first, second))


def render_page(grpc_url: str, frame: str, memory_limit: str = WEB_VIEWER_MEMORY_LIMIT) -> bytes:
    """``page.html`` with the viewer's start-up settings filled in."""
    template = resources.files("pppbot_viz").joinpath("page.html").read_text(encoding="utf-8")
    settings = json.dumps({"url": grpc_url, "frame": frame, "kinds": POSE_KINDS, "memory_limit": memory_limit,
                           "alive_period_ms": int(ALIVE_PERIOD_S * 1000)})
    return template.replace("/*PPPBOT_SETTINGS*/{}", settings).encode()


def content_security_policy(grpc_origin: str) -> str:
    """Scripts, the wasm and data from this page's server, and a connection to the rerun
    server: nothing beyond 127.0.0.1."""
    return ("default-src 'self'; script-src 'self' 'unsafe-inline' 'wasm-unsafe-eval'; "
            "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; worker-src 'self' blob:; "
            f"font-src 'self' data:; connect-src 'self' {grpc_origin}")


class ViewerPage:
    """The page server. ``on_pose`` is called (from the server's thread) with each pose set in
    the view and returns what the page shows, e.g. "goal sent"; raising VizError refuses it.
    ``on_viewer`` is called (from the server's thread) when a page's viewer has started (True) and
    every :data:`ALIVE_PERIOD_S` while it stays open (False)."""

    def __init__(self, port: int, grpc_port: int, viewer_port: int, on_pose: Callable[[PoseRequest], str],
                 frame: str = "map", host: str = LOCALHOST, on_viewer: Callable[[bool], None] = lambda started: None,
                 memory_limit: str = WEB_VIEWER_MEMORY_LIMIT) -> None:
        page = render_page(grpc_url(grpc_port), frame, memory_limit)
        policy = content_security_policy(f"http://{LOCALHOST}:{grpc_port}")
        upstream = f"http://{LOCALHOST}:{viewer_port}"
        handler = _handler(page, policy, upstream, on_pose, on_viewer)
        try:
            self._server = http.server.ThreadingHTTPServer((host, port), handler)
        except OSError as exc:
            raise VizError(f"can't serve the live view on {host}:{port}: {exc.strerror or exc} "
                           f"(viz_port:=<another port>, or 0 for a free one)") from exc
        self._server.daemon_threads = True
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host!s}:{port}/"

    def start(self) -> None:
        self._thread = threading.Thread(target=self._server.serve_forever, name="viz_page", daemon=True)
        self._thread.start()

    def close(self) -> None:
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join()
            self._thread = None
        self._server.server_close()


class _PageHandler(http.server.BaseHTTPRequestHandler):
    """One request to the page server; :func:`_handler` sets the page and where things go."""

    protocol_version = "HTTP/1.1"
    page: bytes = b""
    policy: str = ""
    upstream: str = ""
    on_pose: Callable[[PoseRequest], str]
    on_viewer: Callable[[bool], None]

    def do_GET(self) -> None:
        if not _ASSET_PATH.match(self.path):
            self._reply(404, b"not found", "text/plain")
            return
        if self.path.split("?")[0] in ("/", "/index.html"):
            self._reply(200, self.page, "text/html; charset=utf-8", {"Content-Security-Policy": self.policy})
            return
        self._forward()

    def do_POST(self) -> None:
        if self.path not in ("/pose", "/started", "/alive"):
            self._reply(404, b"not found", "text/plain")
            return
        refusal = self._refusal()
        if refusal:
            self._json(403, {"ok": False, "message": refusal})
            return
        if self.path in ("/started", "/alive"):
            self.rfile.read(min(int(self.headers.get("Content-Length") or 0), _MAX_POST_BYTES))
            self.on_viewer(self.path == "/started")
            self._json(200, {"ok": True, "message": "heard"})
            return
        length = int(self.headers.get("Content-Length") or 0)
        if not 0 < length <= _MAX_POST_BYTES:
            self._json(400, {"ok": False, "message": f"a pose is 1 to {_MAX_POST_BYTES} bytes of JSON"})
            return
        try:
            message = self.on_pose(parse_pose_request(self.rfile.read(length)))
        except VizError as exc:
            self._json(400, {"ok": False, "message": str(exc)})
            return
        except Exception as exc:  # the node is shutting down, say; the server must not die of it
            self._json(500, {"ok": False, "message": f"not sent: {type(exc).__name__}: {exc}"})
            return
        self._json(200, {"ok": True, "message": message})

    def _refusal(self) -> str:
        """Why a pose request is not the page's own: only the page sets poses, never another
        site the browser has open (a cross-site form or no-cors fetch can't send JSON
        without a preflight this server never answers, and carries its own Origin)."""
        port = cast("tuple[str, int]", self.server.server_address)[1]
        hosts = {f"127.0.0.1:{port}", f"localhost:{port}"}
        if self.headers.get("Host") not in hosts:
            return f"Host {self.headers.get('Host')!r} is not this page's ({sorted(hosts)})"
        origin = self.headers.get("Origin")
        if origin is not None and origin not in {f"http://{h}" for h in hosts}:
            return f"Origin {origin!r} is not this page's"
        if (self.headers.get("Content-Type") or "").split(";")[0].strip() != "application/json":
            return "a pose is sent as application/json"
        return ""

    def _forward(self) -> None:
        try:
            with urllib.request.urlopen(self.upstream + self.path, timeout=30) as response:  # noqa: S310
                headers = {k: v for k, v in response.headers.items() if k.lower() in _FORWARDED_HEADERS}
                body = response.read()
                status = response.status
        except urllib.error.HTTPError as exc:
            self._reply(exc.code, b"", "text/plain")
            return
        except (urllib.error.URLError, OSError) as exc:
            self._reply(502, f"the rerun server at {self.upstream} did not answer: {exc}".encode(), "text/plain")
            return
        headers.pop("Content-Length", None)
        headers.pop("content-length", None)
        content_type = headers.pop("Content-Type", headers.pop("content-type", "application/octet-stream"))
        self._reply(status, body, content_type, headers)

    def _json(self, status: int, data: dict[str, Any]) -> None:
        self._reply(status, json.dumps(data).encode(), "application/json")

    def _reply(self, status: int, body: bytes, content_type: str, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for name, value in (headers or {}).items():
            self.send_header(name, value)
        self.end_headers()
        with contextlib.suppress(ConnectionError):  # the browser left (a reload, a closed tab)
            self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        """Quiet: a page load is dozens of requests."""



def _handler(page: bytes, policy: str, upstream: str, on_pose: Callable[[PoseRequest], str],
             on_viewer: Callable[[bool], None]) -> type[http.server.BaseHTTPRequestHandler]:
    return type("Handler", (_PageHandler,), {"page": page, "policy": policy, "upstream": upstream,
                                             "on_pose": staticmethod(on_pose), "on_viewer": staticmethod(on_viewer)})
