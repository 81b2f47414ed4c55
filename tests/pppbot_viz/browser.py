"""A real headless Chromium (Debian's ``chromium``) driven over the DevTools protocol by
playwright, for tests of pages pppbot serves.

Chromium is started with the flags a sandboxed CI needs and a fresh profile, in its own process
group (the test harness's ``spawn`` stops the whole group); playwright only connects to it.
"""
from __future__ import annotations

import shutil
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]


def chromium_executable() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        raise RuntimeError("the browser tests need Debian's chromium (apt-get install chromium; .ci/run installs it)")
    return found


@dataclass
class Browser:
    """A playwright page and the URL of every request it made."""

    page: Any
    requests: list[str]


@contextmanager
def chromium_page(spawn: Callable[..., Any], profile: Path, size: tuple[int, int] = (1200, 800)) -> Iterator[Browser]:
    """A page in a fresh headless Chromium."""
    from playwright.sync_api import sync_playwright
    profile.mkdir(parents=True, exist_ok=True)
    spawn([chromium_executable(), *FLAGS, f"--user-data-dir={profile}", "--remote-debugging-address=127.0.0.1",
           "--remote-debugging-port=0", f"--window-size={size[0]},{size[1]}", "about:blank"], name="chromium")
    port_file = profile / "DevToolsActivePort"
    deadline = time.monotonic() + 60
    while not (port_file.is_file() and port_file.read_text().strip()):
        if time.monotonic() > deadline:
            raise TimeoutError("chromium did not open its DevTools port within 60 s")
        time.sleep(0.1)
    port = int(port_file.read_text().split()[0])
    with sync_playwright() as playwright:
        browser = playwright.chromium.connect_over_cdp(f"http://127.0.0.1:{port}")
        try:
            context = browser.contexts[0]
            page = context.pages[0] if context.pages else context.new_page()
            page.set_viewport_size({"width": size[0], "height": size[1]})
            requests: list[str] = []
            page.on("request", lambda request: requests.append(request.url))
            yield Browser(page, requests)
        finally:
            browser.close()


def wait_for(page: Any, expression: str, timeout_s: float, what: str) -> Any:
    """Poll a JavaScript expression until it is truthy (``page.evaluate``: not subject to the
    page's Content-Security-Policy, unlike playwright's wait_for_function)."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > deadline:
            raise TimeoutError(f"{what}: not within {timeout_s:.0f} s")
        time.sleep(0.25)
