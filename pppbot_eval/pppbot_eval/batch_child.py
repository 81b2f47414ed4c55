"""A batch's run as a child process: ``pppbot eval`` that stops when its batch does.

``python -m pppbot_eval.batch_child <parent pid> eval <scenario> ...`` first makes the process
stop as a terminal's Ctrl-C would stop it, whatever it inherited: SIGINT and SIGTERM unblocked (a
Ray worker's task thread blocks them) and SIGINT raising KeyboardInterrupt (a shell's background
job ignores it); then asks Linux for SIGINT when the process that started it dies
(``PR_SET_PDEATHSIG``: a killed batch or Ray worker leaves no stack running), and runs the eval.
Done here, in the child itself, rather than in a ``preexec_fn``, which is unsafe in the batch's
threads.
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys

#: prctl(2): the signal the calling process gets when its parent dies.
PR_SET_PDEATHSIG = 1


def main(argv: list[str]) -> int:
    parent, arguments = int(argv[0]), argv[1:]
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    if sys.platform == "linux":
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGINT)
        if os.getppid() != parent:  # the batch died before the request: nobody is left to stop us
            return 130
    from pppbot_bringup.cli import main as pppbot
    try:
        return pppbot(arguments)
    except KeyboardInterrupt:  # before the eval's own handler is in place: nothing was started yet
        return 130


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
