"""Run pppbot's Supervisor on plain Python children described in JSON (argv[1]).

Each child: {"name", "code" (Python source), "after" [...], "ready" (a mark's name: the child
is ready once its code calls ``mark(name)``) or null,
"ready_timeout", "required", "respawn", "max_respawns", "ignore": ["INT", "TERM"],
"pppbot_node" (started as one of pppbot's nodes: stop signals blocked until the code unblocks them)}.
Options: "sigint_timeout", "sigterm_timeout", "log_dir" (the nodes' log files go there).
Prints the supervisor's lines; "PIDS <pid> ..." at the end; exits with its code.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from pppbot_bringup.supervisor import NodeSpec, Output, ReadyCheck, Supervisor

PRELUDE = """
import pathlib, signal, sys, time
for name in {ignore!r}:
    signal.signal(getattr(signal, 'SIG' + name), signal.SIG_IGN)
def mark(name):
    pathlib.Path({marks!r}, name).touch()
"""


def main() -> int:
    config = json.loads(sys.argv[1])
    marks = Path(config["marks"])  # the test's own folder: kept clean even when this process is killed
    marks.mkdir(parents=True, exist_ok=True)
    specs = []
    for c in config["children"]:
        code = PRELUDE.format(ignore=c.get("ignore", []), marks=str(marks)) + c["code"]
        ready = None
        if c.get("ready"):
            ready = ReadyCheck(f"'{c['ready']}' marked", (marks / c["ready"]).exists,
                               timeout_s=c.get("ready_timeout", 10.0))
        specs.append(NodeSpec(c["name"], [sys.executable, "-u", "-c", code], after=tuple(c.get("after", [])),
                              ready=ready, required=c.get("required", False), respawn=c.get("respawn", False),
                              max_respawns=c.get("max_respawns", 3), respawn_delay_s=c.get("respawn_delay", 0.0),
                              pppbot_node=c.get("pppbot_node", False)))
    log_dir = Path(config["log_dir"]) if config.get("log_dir") else None
    supervisor = Supervisor(specs, Output(sys.stdout, log_dir), sigint_timeout_s=config.get("sigint_timeout", 1.0),
                            sigterm_timeout_s=config.get("sigterm_timeout", 1.0))
    supervisor.install_signal_handlers()
    print("SUPERVISOR READY", flush=True)
    code = supervisor.run()
    print("PIDS", *supervisor.pids, flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
