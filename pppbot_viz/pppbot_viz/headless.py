"""The live view's page in a real headless Chromium (Debian's ``chromium``), driven over the DevTools
protocol by playwright: for the tests and benchmarks that read the page as a user sees it.

Chromium is started with the flags a sandboxed machine needs (no GPU: WebGL is software) and a
fresh profile, by the caller's ``start`` (a test's ``spawn``, or :class:`ChildProcess`), in its
own process group; playwright only connects to it. What a page shows is read through
``window.pppbot`` (``page.html``): the viewer's state, the poses sent, the last point clicked and
the newest time the viewer shows.
"""
from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: what a sandboxed machine without a GPU or a network needs (no background requests, no updates)
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]


def chromium_executable() -> str:
    """Chromium's command.

    Raises:
        RuntimeError: no ``chromium`` on PATH.
    """
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        raise RuntimeError("the live view's browser tests and benchmark need Debian's chromium "
                           "(apt-get install chromium; .ci/run installs it)")
    return found


@dataclass
class Browser:
    """A playwright page, the URL of every request it made, and the browser's process id."""

    page: Any
    requests: list[str]
    pid: int


@contextmanager
def chromium_page(start: Callable[..., Any], profile: Path, size: tuple[int, int] = (1200, 800),
                  timeout_s: float = 60.0, playwright: Any = None) -> Iterator[Browser]:
    """A page in a fresh headless Chromium, started by ``start(cmd, name="chromium")`` (which
    returns something with a ``pid``; the caller stops it). ``playwright``: a running
    ``sync_playwright()`` to connect with (one per thread drives several browsers); else one
    of its own.

    Raises:
        TimeoutError: Chromium did not open its DevTools port within ``timeout_s``.
    """
    from playwright.sync_api import sync_playwright
    if playwright is None:
        with sync_playwright() as own, chromium_page(start, profile, size, timeout_s, own) as browser:
            yield browser
        return
    profile.mkdir(parents=True, exist_ok=True)
    process = start([chromium_executable(), *FLAGS, f"--user-data-dir={profile}",
                     "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0",
                     f"--window-size={size[0]},{size[1]}", "about:blank"], name="chromium")
    port_file = profile / "DevToolsActivePort"
    deadline = time.monotonic() + timeout_s
    while not (port_file.is_file() and port_file.read_text().strip()):
        if time.monotonic() > deadline:
            raise TimeoutError(f"chromium did not open its DevTools port within {timeout_s:.0f} s")
        time.sleep(0.1)
    port = int(port_file.read_text().split()[0])
    browser = playwright.chromium.connect_over_cdp(f"http://127.0.0.1:{port}")
    try:
        context = browser.contexts[0]
        page = context.pages[0] if context.pages else context.new_page()
        page.set_viewport_size({"width": size[0], "height": size[1]})
        requests: list[str] = []
        page.on("request", lambda request: requests.append(request.url))
        yield Browser(page, requests, int(process.pid))
    finally:
        browser.close()


def wait_for(page: Any, expression: str, timeout_s: float, what: str) -> Any:
    """Poll a JavaScript expression until it is truthy (``page.evaluate``: not subject to the
    page's Content-Security-Policy, unlike playwright's wait_for_function).

    Raises:
        TimeoutError: still falsy after ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what}: not within {timeout_s:.0f} s")
        time.sleep(0.25)


def set_pose(page: Any, button: str, position: tuple[float, float], heading: tuple[float, float],
             timeout_s: float = 20.0) -> float:
    """Use one of the page's pose tools as a user does: its button (``#goal`` or ``#initial``), a
    click on the position, a click on a point in the heading. The monotonic time of the second
    click; the pose is posted once the viewer reports that click (``window.pppbot.posted``).

    Raises:
        TimeoutError: the viewer did not take the first click within ``timeout_s``.
    """
    page.click(button)
    page.mouse.click(*position)
    wait_for(page, "document.getElementById('status').textContent.includes('heading')", timeout_s,
             "the tool to take its first click")
    clicked = time.monotonic()
    page.mouse.click(*heading)
    return clicked


def wait_for_view_time(page: Any, target_s: float, stall_s: float, timeout_s: float, what: str) -> float:
    """Wait until the page's viewer shows sim time ``target_s`` while its time keeps moving: a
    viewer without a GPU has frames of many seconds now and then (its first ones, a new kind of
    display) and catches up at its own pace after them. Returns the time it shows.

    Raises:
        TimeoutError: its time stood still for ``stall_s`` (or it showed nothing for as long),
            or ``timeout_s`` passed.
    """
    start = moved = time.monotonic()
    last = view_time_s(page)
    while last is None or last < target_s:
        now = time.monotonic()
        if now - moved > stall_s or now - start > timeout_s:
            shown = "nothing" if last is None else f"{last:.1f} s"
            raise TimeoutError(f"{what}: the view shows {shown} of sim time, not {target_s:.1f} s, after "
                               f"{now - start:.0f} s (standing still for {now - moved:.0f} s)")
        time.sleep(0.25)
        shown_now = view_time_s(page)
        if shown_now is not None and (last is None or shown_now > last):
            last, moved = shown_now, time.monotonic()
    return last


def view_time_s(page: Any) -> float | None:
    """The time the page's viewer shows (sim seconds; it follows the newest data), None before any."""
    value = page.evaluate("window.pppbot.time")
    return None if value is None else float(value) * 1e-9


def viewer_problem(page: Any) -> str | None:
    """Why the page's viewer is dead (its panic message), or None while it lives."""
    panic = page.evaluate("window.pppbot.panic()")
    return None if panic is None else str(panic)


def process_tree(root: int) -> list[int]:
    """``root`` and every process below it (Linux ``/proc``)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        parent = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(parent, []).append(int(entry.name))
    tree, todo = [], [root]
    while todo:
        pid = todo.pop()
        tree.append(pid)
        todo.extend(children.get(pid, []))
    return tree


def memory_mb(root: int) -> float:
    """What a browser and every process below it use, in MB: the sum of their proportional set
    sizes (PSS: each shared page split among its users), as Chromium's task manager counts a
    tab's footprint. 0 for processes gone meanwhile."""
    total_kb = 0
    for pid in process_tree(root):
        try:
            rollup = Path(f"/proc/{pid}/smaps_rollup").read_text()
        except OSError:
            continue
        for line in rollup.splitlines():
            if line.startswith("Pss:"):
                total_kb += int(line.split()[1])
                break
    return total_kb / 1024.0
