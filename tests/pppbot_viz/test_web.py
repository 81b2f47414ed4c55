"""The live view's page server: the page with its settings and CSP, rerun's files forwarded,
poses posted from the view, bad requests refused with a reason. Real HTTP on 127.0.0.1."""
from __future__ import annotations

import http.server
import json
import math
import socket
import threading
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest
from pppbot_viz.errors import VizError
from pppbot_viz.viewer import free_port, listening
from pppbot_viz.web import PoseRequest, ViewerPage, parse_pose_request


class FakeRerun(http.server.BaseHTTPRequestHandler):
    """Stands in for ``rerun --serve-web``'s file server."""

    def do_GET(self) -> None:
        body = b"// viewer" if self.path == "/re_viewer.js" else b""
        self.send_response(200 if body else 404)
        self.send_header("Content-Type", "text/javascript")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002
        pass


@pytest.fixture
def page() -> Iterator[tuple[ViewerPage, list[PoseRequest]]]:
    upstream = http.server.ThreadingHTTPServer(("127.0.0.1", 0), FakeRerun)
    threading.Thread(target=upstream.serve_forever, daemon=True).start()
    received: list[PoseRequest] = []

    def on_pose(request: PoseRequest) -> str:
        if request.x > 100:
            raise VizError("off the map")
        received.append(request)
        return "sent"

    server = ViewerPage(0, grpc_port=9876, viewer_port=upstream.server_address[1], on_pose=on_pose)
    server.start()
    yield server, received
    server.close()
    upstream.shutdown()
    upstream.server_close()


def post(url: str, body: bytes, headers: dict[str, str] | None = None) -> tuple[int, dict[str, Any]]:
    request = urllib.request.Request(url + "pose", data=body,
                                     headers={"Content-Type": "application/json", **(headers or {})})
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


def test_page_carries_its_settings_and_allows_localhost_only(page: tuple[ViewerPage, list[PoseRequest]]) -> None:
    server, _ = page
    assert server.url.startswith("http://127.0.0.1:")
    with urllib.request.urlopen(server.url, timeout=5) as response:
        text = response.read().decode()
        policy = response.headers["Content-Security-Policy"]
    assert '"url": "rerun+http://127.0.0.1:9876/proxy"' in text and '"frame": "map"' in text
    assert "connect-src 'self' http://127.0.0.1:9876" in policy and "default-src 'self'" in policy
    assert "https:" not in policy and "*" not in policy


def test_viewer_files_come_from_the_rerun_server(page: tuple[ViewerPage, list[PoseRequest]]) -> None:
    server, _ = page
    with urllib.request.urlopen(server.url + "re_viewer.js", timeout=5) as response:
        assert response.read() == b"// viewer"
    with pytest.raises(urllib.error.HTTPError) as missing:
        urllib.request.urlopen(server.url + "nothing.wasm", timeout=5)
    assert missing.value.code == 404


def test_two_clicks_make_a_pose(page: tuple[ViewerPage, list[PoseRequest]]) -> None:
    server, received = page
    status, reply = post(server.url, json.dumps({"kind": "goal", "from": [1, 2, 0], "to": [1, 3, 0]}).encode())
    assert (status, reply) == (200, {"ok": True, "message": "sent"})
    assert [(r.kind, r.x, r.y) for r in received] == [("goal", 1.0, 2.0)]
    assert received[0].yaw == pytest.approx(math.pi / 2)


@pytest.mark.parametrize(("body", "reason"), [
    (b"not json", "a pose must be"),
    (json.dumps({"kind": "teleport", "from": [0, 0], "to": [1, 0]}).encode(), "kind 'teleport' is not one of"),
    (json.dumps({"kind": "goal", "from": [0, "nan"], "to": [1, 0]}).encode(), "finite numbers"),
    (json.dumps({"kind": "goal", "from": [0], "to": [1, 0]}).encode(), "two finite numbers"),
    (json.dumps({"kind": "goal", "from": [200, 0], "to": [201, 0]}).encode(), "off the map"),
])
def test_bad_poses_are_refused_with_a_reason(page: tuple[ViewerPage, list[PoseRequest]], body: bytes,
                                             reason: str) -> None:
    server, received = page
    status, reply = post(server.url, body)
    assert status == 400 and reply["ok"] is False and reason in reply["message"]
    assert received == []


def test_pose_request_parsing() -> None:
    request = parse_pose_request(b'{"kind": "initial", "from": [0.5, -1.0, 0.0], "to": [0.5, -2.0, 0.0]}')
    assert (request.kind, request.x, request.y) == ("initial", 0.5, -1.0)
    assert request.yaw == pytest.approx(-math.pi / 2)


def test_a_taken_port_is_named() -> None:
    port = free_port()
    blocker = http.server.HTTPServer(("127.0.0.1", port), FakeRerun)
    try:
        assert listening(port)
        with pytest.raises(VizError, match=f"127.0.0.1:{port}.*viz_port"):
            ViewerPage(port, grpc_port=1, viewer_port=2, on_pose=lambda r: "")
    finally:
        blocker.server_close()
    assert not listening(port)


GOAL = json.dumps({"kind": "goal", "from": [1, 2], "to": [1, 3]}).encode()


@pytest.mark.parametrize(("headers", "reason"), [
    # another site's no-cors fetch or form: not JSON (JSON would need a preflight, never answered)
    ({"Content-Type": "text/plain"}, "application/json"),
    ({"Origin": "https://evil.example"}, "Origin 'https://evil.example' is not this page's"),
    ({"Host": "evil.example:9090"}, "Host 'evil.example:9090' is not this page's"),  # DNS rebinding
])
def test_poses_only_from_the_page_itself(page: tuple[ViewerPage, list[PoseRequest]], headers: dict[str, str],
                                         reason: str) -> None:
    server, received = page
    status, reply = post(server.url, GOAL, headers)
    assert status == 403 and reason in reply["message"]
    assert received == []
    port = server.url.rstrip("/").rsplit(":", 1)[1]
    status, _ = post(server.url, GOAL, {"Origin": f"http://127.0.0.1:{port}"})  # the page's own
    assert status == 200 and len(received) == 1


def test_odd_request_targets_are_not_forwarded(page: tuple[ViewerPage, list[PoseRequest]]) -> None:
    """``GET @example.com/x`` would make the forwarded URL http://127.0.0.1:port@example.com/x."""
    server, _ = page
    host, port = server.url.removeprefix("http://").rstrip("/").split(":")
    for target in ("@example.com/x", "//example.com/x", "/a@example.com"):
        with socket.create_connection((host, int(port)), timeout=5) as sock:
            sock.sendall(f"GET {target} HTTP/1.1\r\nHost: {host}:{port}\r\nConnection: close\r\n\r\n".encode())
            answer = sock.recv(200).decode(errors="replace")
        assert answer.startswith("HTTP/1.1 404"), (target, answer)
