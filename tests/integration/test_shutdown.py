"""Ctrl-C ends the whole navigation bringup cleanly, every time.

One SIGINT of four once left planner_server dead with SIGSEGV on the way down (a signal
thread triggering a guard condition of an executor being destroyed). The nodes now own
their signals (pppbot_lockstep.ros.runner); this starts the full localization and
navigation bringup again and again and stops it at different moments — while nodes are
still starting, right when it is up, and after it has run a while — and requires every
started process to finish with exit code 0.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest

from pppbot_common.errors import TimeoutExpired
from pppbot_nav.lifecycle import NAVIGATION_NODES

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
#: Every stop moment (run % 3) with every process layout (run % 4: composed, or each node its own)
#: once; a bug that struck one stop in four (the SIGSEGV above) fails here with 97 % odds.
RUNS = 12
#: The launch's escalation (SIGINT → SIGTERM → SIGKILL) waits longer than its 5 s defaults: on a
#: loaded machine a node still importing when the stop comes can need more, and any escalation
#: fails the test anyway; a node that hangs is still named.
ESCALATION = ("sigterm_timeout:=20", "sigkill_timeout:=30")
#: Processes of a localization + navigation bringup without teleop and RViz: robot_state_publisher
#: and twist_mux in the simulator's, map_server and amcl composed, and the navigation nodes (the
#: default), or each its own (``use_composition:=false``, every fourth run).
NODES = ("simulator", "localization", "navigation")
SEPARATE_NODES = ("simulator", "robot_state_publisher", "twist_mux", "map_server", "amcl",
                  "lifecycle_manager_localization", *NAVIGATION_NODES, "lifecycle_manager_navigation")


#: The interpreter's own frames, left out of a native stack (the Python stack is printed beside it).
INTERPRETER_FRAME = re.compile(r"_?Py|py|cfunction_|method_vectorcall|do_call_core|__libc_start|_start$|clone3$")


def _native_stacks_of_a_hung_node(launch: Any) -> str:
    """While the launch stops: if it names a node still running after SIGINT, that node's native
    stacks (gdb, where installed), each thread's functions innermost first. The Python stack the
    node prints ends at the binding call it hangs in; this shows where inside it."""
    try:
        hung = launch.wait_for_output(r"\[launch\]: (\S+) still running \d+ s after SIGINT", 60).group(1)
    except TimeoutExpired:
        return ""  # every node ended in time
    pid = re.search(rf"\[{re.escape(hung)}\]: process started with pid \[(\d+)\]", launch.output)
    if pid is None or shutil.which("gdb") is None:
        return ""
    try:
        dump = subprocess.run(["gdb", "-p", pid.group(1), "-batch", "-ex", "thread apply all bt 25"],
                              capture_output=True, text=True, timeout=25).stdout
    except subprocess.TimeoutExpired:
        return f"; gdb on {hung} did not finish"
    threads = []
    for block in re.split(r"\nThread ", dump)[1:]:
        functions = re.findall(r"^#\d+\s+(?:0x[0-9a-f]+ in )?([\w:~<>]+)", block, re.M)
        threads.append(" < ".join(f for f in functions if not INTERPRETER_FRAME.match(f)))
    return f"; {hung}'s native stacks (gdb): " + " || ".join(threads)


def _stop_moment(run: int) -> str:
    """When run ``run`` is interrupted: while starting, as soon as it is up, or a while after."""
    return ("starting", "up", "running")[run % 3]


@pytest.mark.ros
@pytest.mark.heavy
def test_sigint_ends_every_node_of_the_navigation_bringup_with_exit_code_0(spawn: Any) -> None:
    failures: list[str] = []
    stopped_while_starting = 0
    for run in range(RUNS):
        moment = _stop_moment(run)
        separate = run % 4 == 3
        launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", "use_teleop:=false",
                        "use_rviz:=false", "use_viz:=false", f"use_composition:={str(not separate).lower()}",
                        *ESCALATION],
                       name=f"launch_sim run {run}")
        if moment == "starting":
            launch.wait_for_output(r"\[(amcl|localization)-1\]: process started", 60)
        else:
            launch.wait_for_output(r"ppp_bot is up in 'room'", 90)
            if moment == "running":
                time.sleep(2.0)
        up = "ppp_bot is up" in launch.output
        os.kill(launch.pid, signal.SIGINT)
        native = _native_stacks_of_a_hung_node(launch)
        code = launch.wait(60)
        started = re.findall(r"\[([\w-]+)-\d+\]: process started", launch.output)
        clean = re.findall(r"\[([\w-]+)-\d+\]: process has finished cleanly", launch.output)
        died = [line for line in launch.output.splitlines()
                if "process has died" in line or re.search(r"sending SIG(TERM|KILL)", line)]
        if not up:
            stopped_while_starting += 1
        if code != 0 or sorted(started) != sorted(clean) or died:
            failures.append(f"run {run} ({moment}): launch exit {code}, started {started}, finished cleanly "
                            f"{clean}; " + " | ".join(died) + native)
            print(f"---- run {run} ({moment}): the launch's output (a hung node's stacks included)\n{launch.output}")
        if moment != "starting":
            assert sorted(started) == sorted(SEPARATE_NODES if separate else NODES), started
    assert not failures, "\n".join(failures)
    assert stopped_while_starting > 0  # some runs were interrupted before every node was up
