"""The ``main()`` of a pppbot node: start, spin, and end cleanly however it ends.

A bad parameter (or any of ``fatal`` errors) at start prints one line naming it
and exits 1. Ctrl-C and shutdown end with 0, including the race where a callback
publishes while SIGINT is already tearing the context down.
"""
from __future__ import annotations

import sys
import time
from typing import Any, Callable, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from pppbot_common.errors import PppbotError
from pppbot_common.throttle import Throttle

N = TypeVar("N", bound=Node)


def run_node(factory: Callable[[], N], name: str, args: list[str] | None = None,
             spin: Callable[[N], None] = rclpy.spin,
             fatal: tuple[type[BaseException], ...] = (PppbotError,),
             signal_handlers: bool = True) -> int:
    """Create the node and ``spin`` it. ``signal_handlers=False`` leaves Ctrl-C to the
    node (rclpy then does not shut the context down under it)."""
    rclpy.init(args=args, signal_handler_options=None if signal_handlers else SignalHandlerOptions.NO)
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


def spin_together(*nodes: Node, threads: int = 1) -> None:
    """Spin several nodes of one process in one executor (``threads`` > 1: a multi-threaded one,
    for servers whose goals wait while other callbacks run)."""
    executor = SingleThreadedExecutor() if threads == 1 else MultiThreadedExecutor(num_threads=threads)
    for node in nodes:
        executor.add_node(node)
    try:
        executor.spin()
    finally:
        executor.shutdown()


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


class Warnings:
    """A node's warnings, at most one per ``period_s`` for each kind of problem
    (rclpy's own throttling is per call site, so different problems would hide each other)."""

    def __init__(self, node: Node, period_s: float = 5.0) -> None:
        self.node = node
        self.throttle = Throttle(period_s)

    def __call__(self, kind: str, text: str) -> None:
        if self.throttle.allow(kind, time.monotonic()):
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
