"""Run pppbot's Supervisor on plain Python children described in JSON (argv[1]).

Each child: {"name", "code" (Python source), "after" [...], "ready" (regex) or null,
"ready_timeout", "required", "respawn", "max_respawns", "ignore": ["INT", "TERM"],
"pppbot_node" (started as one of pppbot's nodes: stop signals blocked until the code unblocks them)}.
Prints the supervisor's lines; "PIDS <pid> ..." at the end; exits with its code.
"""
from __future__ import annotations

import json
import sys

from pppbot_bringup.supervisor import NodeSpec, Output, ReadyCheck, Supervisor

PRELUDE = """
import signal, sys, time
for name in {ignore!r}:
    signal.signal(getattr(signal, 'SIG' + name), signal.SIG_IGN)
"""


def main() -> int:
    config = json.loads(sys.argv[1])
    specs = []
    for c in config["children"]:
        code = PRELUDE.format(ignore=c.get("ignore", [])) + c["code"]
        ready = None
        if c.get("ready"):
            ready = ReadyCheck(f"'{c['ready']}' printed", output_pattern=c["ready"],
                               timeout_s=c.get("ready_timeout", 10.0))
        specs.append(NodeSpec(c["name"], [sys.executable, "-u", "-c", code], after=tuple(c.get("after", [])),
                              ready=ready, required=c.get("required", False), respawn=c.get("respawn", False),
                              max_respawns=c.get("max_respawns", 3), respawn_delay_s=c.get("respawn_delay", 0.0),
                              pppbot_node=c.get("pppbot_node", False)))
    supervisor = Supervisor(specs, Output(sys.stdout), sigint_timeout_s=config.get("sigint_timeout", 1.0),
                            sigterm_timeout_s=config.get("sigterm_timeout", 1.0))
    supervisor.install_signal_handlers()
    print("SUPERVISOR READY", flush=True)
    code = supervisor.run()
    print("PIDS", *supervisor.pids, flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
