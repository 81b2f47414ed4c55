"""The ``main()`` of a pppbot process: start its nodes, spin them, and end cleanly however it ends.

:func:`run_nodes` runs one or more nodes (composition: several nodes, one process, one
executor) on rclpy's EventsExecutor, which handles a message in about 15 µs where the
Python executors take 150-550 µs (``benchmarks/stack_speed.py`` measures it). Callbacks
run one at a time in the main thread: a node never blocks in a callback, it keeps state
and acts on its timers (:func:`pppbot_lockstep.ros.participant.create_timer`).

The process owns SIGINT and SIGTERM (rclpy's own signal handling is off): a signal asks
the loop to stop, and then, in this thread and in this order, the lockstep participant
leaves, the executor stops, the nodes are destroyed and the context shuts down. Nothing
shuts the context down under a running callback, so no node dies on its way down.

A bad parameter (or any of ``fatal`` errors) at start prints one line naming it and
exits 1; so does a ``--params-file`` that is not a parameter file (checked before rcl reads
it: :func:`pppbot_common.param_files.check_parameter_file` names the file, line and column)
or a command line rcl refuses. A stop by signal or shutdown exits 0.

SIGUSR1 prints the stack of every thread to stderr (:mod:`faulthandler`, from C, so it
works while the main thread is stuck in a binding call): the launch sends it to a node
that has not stopped within ``sigterm_timeout`` of a SIGINT, before it escalates, so a
hang on the way down leaves its place in the log.
"""
from __future__ import annotations

import re
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Collection, Sequence
from pathlib import Path
from types import FrameType
from typing import Any, TypeVar

import rclpy
from rclpy.clock import ROSClock
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from pppbot_common.errors import ParameterFileError, PppbotError
from pppbot_common.param_files import check_parameter_file, parameter_file_arguments
from pppbot_common.process import STOP_SIGNALS, dump_stacks_on_signal, exit_if_stuck, trace_memory_if_asked
from pppbot_common.ros.unread_parameters import declared_names, warn_unread_parameters
from pppbot_common.throttle import Throttle
from pppbot_lockstep.ros.node import StepExecutor
from pppbot_lockstep.ros.participant import Participant
from pppbot_lockstep.ros.port import FREE_RUNNING

N = TypeVar("N", bound=Node)

#: Longest wait of the spin loop (wall s): how soon a signal is acted on.
SPIN_TIMEOUT_S = 0.2
#: A kind of callback failure is named at most once per this (wall s).
DROPPED_PERIOD_S = 5.0


class Process:
    """The running process as a custom loop sees it: its executor, its participant, its stop request."""

    def __init__(self, executor: Any, participant: Participant | None,
                 stop_requested: threading.Event | None = None, name: str = "pppbot") -> None:
        self.executor = executor
        self.participant = participant
        self.stop_requested = stop_requested or threading.Event()
        self.logger = rclpy.logging.get_logger(name)
        self._dropped = Throttle(DROPPED_PERIOD_S)

    def running(self) -> bool:
        return not self.stop_requested.is_set() and rclpy.ok()

    def spin_once(self, timeout_s: float = SPIN_TIMEOUT_S) -> None:
        """Run one ready callback, waiting at most ``timeout_s`` for one. A callback that raises on
        what it was given (one of rclpy's own: its /clock subscription takes no negative time) is
        named, at most once per :data:`DROPPED_PERIOD_S` for each kind, and the process goes on;
        pppbot's own errors (a :class:`PppbotError`) still end it."""
        try:
            self.executor.spin_once(timeout_sec=timeout_s)
        except (PppbotError, ExternalShutdownException):
            raise
        except Exception as exc:
            if not self.running():
                raise
            where = traceback.extract_tb(exc.__traceback__)[-1]
            if self._dropped.allow(f"{type(exc).__name__}@{where.name}", time.monotonic()):
                self.logger.warning(f"dropping what a callback could not take ({where.name} in "
                                    f"{Path(where.filename).name}): {type(exc).__name__}: {exc}")
        if self.participant is not None:
            self.participant.maintain()

    def request_stop(self, signum: int = 0, frame: FrameType | None = None) -> None:
        self.stop_requested.set()

    def install_signal_handlers(self) -> None:
        for sig in STOP_SIGNALS:
            signal.signal(sig, self.request_stop)


def take_stop_signals() -> threading.Event:
    """From now on SIGINT and SIGTERM set the returned event (a stop request). A launch starts
    pppbot's nodes with both signals blocked (:func:`pppbot_common.process.block_stop_signals`):
    one sent while the process was still importing, which would have killed it, is pending and
    taken here, and the process ends as cleanly as if it had come later."""
    requested = threading.Event()
    dump_stacks_on_signal()
    for sig in STOP_SIGNALS:
        signal.signal(sig, lambda signum, frame: requested.set())
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    return requested


def spin_until_stopped(nodes: Sequence[Node], process: Process) -> int | None:
    """The default loop: callbacks as they come, until a signal or shutdown."""
    while process.running():
        process.spin_once()
    return None


#: What the runner makes a process's nodes with: a node class (or a function) that takes the
#: process's step port as ``port=``.
NodeFactory = Callable[..., Node]


def run_nodes(factories: Sequence[NodeFactory], name: str, args: list[str] | None = None, *,
              fatal: tuple[type[BaseException], ...] = (PppbotError,),
              loop: Callable[[Sequence[Node], Process], int | None] = spin_until_stopped,
              lockstep: bool = True) -> int:
    """Create the nodes (in order) in one process, each handed the process's step port
    (``factory(port=...)``: the lockstep participant the parameters ``lockstep:=true`` ask for, else
    the free-running port), and run ``loop`` until stopped; the exit code (the loop's, or 0).
    ``lockstep=False``: the process never takes part in lockstep (the simulator, which runs it)."""
    stop_requested = take_stop_signals()
    trace_memory_if_asked(name)
    if not _init(name, args, SignalHandlerOptions.NO):
        return 1
    nodes: list[Node] = []
    spare: list[Node] = []  # destroyed once the process's own nodes hold its DDS participant
    participant: Participant | None = None
    try:
        participant = Participant.from_parameters(name, spare) if lockstep else None
        port = participant if participant is not None else FREE_RUNNING
        for factory in factories:
            nodes.append(factory(port=port))
    except fatal as exc:
        print(f"[{name}] error: {exc}", file=sys.stderr)
        _teardown(None, [*spare, *nodes], participant)
        return 1
    for node in spare:
        node.destroy_node()
    # In lockstep the executor tells the participant of every task it makes (work a step waits for).
    executor = StepExecutor(participant) if participant is not None else EventsExecutor()
    share_clock(_with_composed(nodes))
    read_in_process = declared_names(_with_composed(nodes))
    for node in _with_composed(nodes):
        warn_unread_parameters(node, read_in_process)
        executor.add_node(node)
    if participant is not None:
        executor.add_node(participant.node)
    process = Process(executor, participant, stop_requested, name)
    process.install_signal_handlers()  # after the executor: it installs handlers of its own
    if participant is not None:
        participant.start(executor, _with_composed(nodes))
    code: int | None = 0
    try:
        code = loop(nodes, process)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if process.running():
            raise
        # The context went down under a running callback: that is the end we asked for.
    finally:
        if participant is not None and rclpy.ok():
            participant.leave()
        _teardown(executor, nodes, participant, process)
    return code or 0


def _init(name: str, args: list[str] | None, signal_handler_options: SignalHandlerOptions | None) -> bool:
    """``rclpy.init``, after checking the command line's parameter files; False (one line said why)
    when a file or the command line is refused."""
    try:
        for path in parameter_file_arguments(sys.argv if args is None else args):
            check_parameter_file(path)
    except ParameterFileError as exc:
        print(f"[{name}] error: {exc}", file=sys.stderr)
        return False
    try:
        rclpy.init(args=args, signal_handler_options=signal_handler_options)
    except _rclpy.UnknownROSArgsError as exc:
        print(f"[{name}] error: unknown ROS argument(s) after --ros-args: {exc}", file=sys.stderr)
        return False
    except _rclpy.RCLError as exc:  # rclpy re-exports it only from rclpy.action.server
        print(f"[{name}] error: {rcl_error_text(exc)}", file=sys.stderr)
        return False
    return True


def rcl_error_text(exc: BaseException) -> str:
    """rcl's message without the C source locations it appends (``, at /project/src/parse.c:782``)."""
    return re.sub(r",? at \S+\.c:\d+", "", str(exc)).strip()


def _with_composed(nodes: Sequence[Node]) -> list[Node]:
    """The nodes and the nodes each runs in its process (``composed_nodes``: a server's costmap, the
    simulator's controllers), that the process's executor spins; a node destroys its own composed
    nodes. A node that ``spins_itself`` (a lifecycle manager, which waits on the others' services
    from its own thread) is left out."""
    return [n for node in nodes for n in (node, *getattr(node, "composed_nodes", ()))
            if not getattr(n, "spins_itself", False)]


def share_clock(nodes: Sequence[Node]) -> None:
    """One ``/clock`` subscription per process: the nodes on sim time after the first take their
    time from the first one's time source instead of each taking every ``/clock`` message (in
    the composed navigation process, four subscriptions fewer took 1.2 % of a core off at 1×
    real time). rclpy gives a node's time source
    no public name; ``_time_source`` is the one rclpy's Node makes for itself."""
    source = None
    for node in nodes:
        own = getattr(node, "_time_source", None)
        clock = node.get_clock()
        if own is None or not isinstance(clock, ROSClock) or not clock.ros_time_is_active:
            continue
        if source is None:
            source = own
        else:
            own.detach_node()  # its /clock subscription goes; it sets the clock no more
            source.attach_clock(clock)


#: Wall seconds a process's end may take (its nodes, then its DDS participant, destroyed) before it
#: prints its stacks and exits with status 1 all the same.
FINI_TIMEOUT_S = 15.0


def _teardown(executor: Any, nodes: list[Node], participant: Participant | None,
              process: Process | None = None) -> None:
    # Fast DDS (2.14) can hang for good destroying a participant while discovery is under way (its
    # set_listener waits for a discovery callback that waits for it): the process ends regardless.
    with exit_if_stuck(FINI_TIMEOUT_S):
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if process is not None:
            process.install_signal_handlers()  # the executor's shutdown put the default handlers back
        for node in reversed(nodes):
            node.destroy_node()
        if participant is not None:
            participant.node.destroy_node()
        rclpy.try_shutdown()


def run_node(factory: Callable[..., N], name: str, args: list[str] | None = None,
             spin: Callable[[N], None] | None = None,
             fatal: tuple[type[BaseException], ...] = (PppbotError,),
             signal_handlers: bool = True) -> int:
    """One node. Without ``spin``, :func:`run_nodes`. With ``spin`` (a terminal program, a node that
    blocks in a service callback), rclpy's way: ``spin(node)`` on rclpy's own executors;
    ``signal_handlers=False`` leaves Ctrl-C to the node (rclpy then does not shut the context
    down under it)."""
    if spin is None:
        return run_nodes([factory], name, args, fatal=fatal)
    dump_stacks_on_signal()
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)  # rclpy's handlers take them from here
    if not _init(name, args, None if signal_handlers else SignalHandlerOptions.NO):
        return 1
    try:
        node = factory()
    except fatal as exc:
        print(f"[{name}] error: {exc}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    except KeyboardInterrupt:
        rclpy.try_shutdown()
        return 0
    try:
        spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if not _shutting_down():
            raise
        # The context was shut down under a running callback: that is the end we asked for.
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def _shutting_down(grace_s: float = 2.0) -> bool:
    """Whether the context is (about to be) shut down.

    rclpy shuts it down from a signal thread, a moment after Python has seen the
    signal. A KeyboardInterrupt that lands inside a binding call surfaces as that
    call's error (pybind11: "Unable to convert call argument") while ``rclpy.ok()``
    still holds, so wait a little before calling the error real.
    """
    deadline = time.monotonic() + grace_s
    while rclpy.ok():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


#: While a stack comes up, transforms and maps are missing for a few seconds: warnings about them
#: in this first stretch of a node's life are debug messages, not warnings.
STARTUP_SETTLE_S = 10.0


class Warnings:
    """A node's warnings, at most one per ``period_s`` for each kind of problem
    (rclpy's own throttling is per call site, so different problems would hide each other).
    Kinds in ``settling`` (no transform yet, no map yet: what is normal while a stack comes up)
    are debug messages until :meth:`settled` says that kind once went well, or for at most
    :data:`STARTUP_SETTLE_S` after the node's start (a frame that never comes is a warning)."""

    def __init__(self, node: Node, period_s: float = 5.0, settling: Collection[str] = ()) -> None:
        self.node = node
        self.throttle = Throttle(period_s)
        self.settling = set(settling)
        self.quiet_until = time.monotonic() + STARTUP_SETTLE_S

    def settled(self, kind: str) -> None:
        """What ``kind`` warns about went well once: from now on its problems are warnings."""
        self.settling.discard(kind)

    def __call__(self, kind: str, text: str) -> None:
        now = time.monotonic()
        if kind in self.settling and now < self.quiet_until:
            self.node.get_logger().debug(text)
        elif self.throttle.allow(kind, now):
            self.node.get_logger().warning(text)


def guarded(node: Node, callback: Callable[[Any], None], what: str,
            period_s: float = 5.0) -> Callable[[Any], None]:
    """``callback`` that survives one bad message: an exception is logged (at most once
    per ``period_s`` for each kind of error) and the message dropped."""
    warn = Warnings(node, period_s)

    def call(msg: Any) -> None:
        try:
            callback(msg)
        except Exception as exc:  # one bad message must not end the node
            warn(type(exc).__name__, f"dropping a {what} message: {type(exc).__name__}: {exc}")

    return call
