"""The tick engine of behaviour trees as BehaviorTree.CPP 4 runs them (the format of Nav2's trees).

A tree is made of :class:`TreeNode` objects; the root is ticked once per period
(:meth:`Tree.tick_once`) and answers :class:`Status`. Control nodes tick their children by
BehaviorTree.CPP 4's rules (:mod:`pppbot_nav.bt.builtin`: which child next, which to halt,
when to start again); a node that returned RUNNING and is no longer wanted is halted
(:meth:`TreeNode.reset`). Nodes read
their inputs through ports: an XML attribute is a literal (converted to the port's kind) or
``{key}``, an entry of the tree's :class:`Blackboard`. Time is the tree's clock
(:class:`NodeConfig`, sim seconds in a navigator): nothing here reads a wall clock.

Where this differs from BehaviorTree.CPP 4: scripting (``Script``, ``_skipIf`` and the other
``_``-preconditions) is not run; a tree that uses it is refused when it is loaded. ``Repeat``
with ``num_cycles="-1"`` ticks its child once per tick (BehaviorTree.CPP loops a synchronous
child forever within one tick).
"""
from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

from pppbot_nav.errors import BehaviorTreeError


class Status(enum.Enum):
    IDLE = "IDLE"
    RUNNING = "RUNNING"
    SUCCESS = "SUCCESS"
    FAILURE = "FAILURE"
    SKIPPED = "SKIPPED"

    @property
    def completed(self) -> bool:
        return self in (Status.SUCCESS, Status.FAILURE)


class PortKind(enum.Enum):
    INPUT = "input"
    OUTPUT = "output"
    INOUT = "inout"


_REQUIRED = object()


@dataclass(frozen=True)
class Port:
    """A node's port: ``convert`` turns an XML literal into its value (``None``: only a blackboard
    entry can give it, such as a path or a goal); without ``default`` it must be given."""

    name: str
    convert: Callable[[str], Any] | None = str
    default: Any = _REQUIRED
    kind: PortKind = PortKind.INPUT
    description: str = ""

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED and self.kind is not PortKind.OUTPUT


def as_bool(text: str) -> bool:
    """BehaviorTree.CPP's bool: true/false (any case) or 1/0."""
    value = text.strip().lower()
    if value in ("true", "1"):
        return True
    if value in ("false", "0"):
        return False
    raise ValueError(f"'{text}' is not a bool (true, false, 1 or 0)")


def input_port(name: str, convert: Callable[[str], Any] | None = str, default: Any = _REQUIRED,
               description: str = "") -> Port:
    return Port(name, convert, default, PortKind.INPUT, description)


def output_port(name: str, description: str = "") -> Port:
    return Port(name, None, None, PortKind.OUTPUT, description)


def blackboard_key(text: str, port: str = "") -> str | None:
    """``{key}`` → ``key``, ``{=}`` → ``port`` (the entry named as the port); a literal → None."""
    text = text.strip()
    key = text[1:-1].strip() if len(text) > 2 and text[0] == "{" and text[-1] == "}" else None
    return port if key == "=" and port else key


class Blackboard:
    """Named values shared by a tree's nodes. A subtree's blackboard reads and writes the keys
    its ``<SubTree>`` element remaps (``port="{parent_key}"``) in its parent's, holds the
    literals it is given, and with ``autoremap`` passes every other key to the parent too."""

    def __init__(self, parent: Blackboard | None = None, remap: Mapping[str, str] | None = None,
                 autoremap: bool = False) -> None:
        self._values: dict[str, Any] = {}
        #: the leaves that answered FAILURE, newest last (kept on a tree's top-level board)
        self.failures: list[str] = []
        self._parent = parent
        self._remap: dict[str, str] = {}
        self._autoremap = autoremap and parent is not None
        for key, text in (remap or {}).items():
            parent_key = blackboard_key(text, key)
            if parent_key is not None and parent is not None:
                self._remap[key] = parent_key
            else:
                self._values[key] = text

    def _owner(self, key: str) -> tuple[Blackboard, str]:
        if key in self._remap and self._parent is not None:
            return self._parent._owner(self._remap[key])
        if self._autoremap and key not in self._values and self._parent is not None:
            return self._parent._owner(key)
        return self, key

    def __contains__(self, key: str) -> bool:
        board, name = self._owner(key)
        return name in board._values

    def get(self, key: str, default: Any = None) -> Any:
        board, name = self._owner(key)
        return board._values.get(name, default)

    def set(self, key: str, value: Any) -> None:
        board, name = self._owner(key)
        board._values[name] = value

    def root(self) -> Blackboard:
        """The tree's top-level blackboard (a subtree's parents' parent ...)."""
        return self if self._parent is None else self._parent.root()

    #: How many leaf failures a tree keeps (the newest), for a failed goal's message.
    FAILURES_KEPT = 8

    def note_failure(self, where: str) -> None:
        """A leaf answered FAILURE (kept on the top-level board, newest last)."""
        failures = self.root().failures
        failures.append(where)
        del failures[:-self.FAILURES_KEPT]


@dataclass
class NodeConfig:
    """What a node is built with: its ports' raw values (XML attributes), the blackboard, the
    tree's clock (seconds) and where the node was written (``file:line``, for messages)."""

    attributes: Mapping[str, str] = field(default_factory=dict)
    blackboard: Blackboard = field(default_factory=Blackboard)
    clock: Callable[[], float] = lambda: 0.0
    where: str = ""


class TreeNode:
    """A node of a tree. Subclasses declare ``PORTS`` and implement :meth:`tick`; one that can
    return RUNNING implements :meth:`halt` (stop what it started)."""

    PORTS: ClassVar[tuple[Port, ...]] = ()
    #: children it takes: 0 (a leaf), 1 (a decorator) or None (one or more: a control node)
    CHILDREN: ClassVar[int | None] = 0

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        self.name = name
        self.config = config or NodeConfig()
        self.status = Status.IDLE
        #: why the node fails, when it can say (set with its FAILURE; part of a failed goal's message)
        self.why = ""
        self.children: list[TreeNode] = []
        self._ports = {port.name: port for port in type(self).PORTS}

    # -- ports ------------------------------------------------------------------------
    def get_input(self, name: str) -> Any:
        """The input port's value: the blackboard entry it names, its literal, or its default.

        Raises:
            BehaviorTreeError: not a port of this node, no value, or a literal its kind refuses.
        """
        port = self._ports.get(name)
        if port is None:
            raise BehaviorTreeError(f"{self._where()}'{self.name}' has no port '{name}'")
        text = self.config.attributes.get(name)
        if text is None:
            if port.default is _REQUIRED:
                raise BehaviorTreeError(f"{self._where()}'{self.name}': input port '{name}' is not given")
            return port.default
        key = blackboard_key(text, name)
        if key is not None:
            if key not in self.config.blackboard:
                if port.default is not _REQUIRED:
                    return port.default
                raise BehaviorTreeError(f"{self._where()}'{self.name}': blackboard entry '{key}' (port "
                                        f"'{name}') is not set")
            value = self.config.blackboard.get(key)
            return self._convert(port, value) if isinstance(value, str) else value
        return self._convert(port, text)

    def set_output(self, name: str, value: Any) -> None:
        """Write ``value`` to the blackboard entry the output port names (not connected: nothing).

        Raises:
            BehaviorTreeError: not an output port, or connected to a literal.
        """
        port = self._ports.get(name)
        if port is None or port.kind is PortKind.INPUT:
            raise BehaviorTreeError(f"{self._where()}'{self.name}' has no output port '{name}'")
        text = self.config.attributes.get(name)
        if text is None:
            return
        key = blackboard_key(text, name)
        if key is None:
            raise BehaviorTreeError(f"{self._where()}'{self.name}': output port '{name}' must name a blackboard "
                                    f"entry ({{key}}), not '{text}'")
        self.config.blackboard.set(key, value)

    def _convert(self, port: Port, text: str) -> Any:
        if port.convert is None:
            raise BehaviorTreeError(f"{self._where()}'{self.name}': port '{port.name}' takes a blackboard entry "
                                    f"({{key}}), not the text '{text}'")
        try:
            return port.convert(text)
        except ValueError as exc:
            raise BehaviorTreeError(f"{self._where()}'{self.name}': port '{port.name}' = '{text}': {exc}") from exc

    def _where(self) -> str:
        return f"{self.config.where}: " if self.config.where else ""

    # -- ticking ----------------------------------------------------------------------
    def execute_tick(self) -> Status:
        """Tick the node and keep what it answered."""
        status = self.tick()
        if status is Status.IDLE:
            raise BehaviorTreeError(f"{self._where()}'{self.name}' returned IDLE from a tick")
        if status is Status.FAILURE and not self.children:
            where = f"{self.name} ({self.config.where})" if self.config.where else self.name
            self.config.blackboard.note_failure(f"{where}: {self.why}" if self.why else where)
        self.why = ""
        self.status = status
        return status

    def tick(self) -> Status:
        raise NotImplementedError

    def halt(self) -> None:
        """Stop what a RUNNING node started (and its children's)."""
        for child in self.children:
            child.reset()

    def reset(self) -> None:
        """Halt the node if it runs, and make it IDLE (ready to start again)."""
        if self.status is Status.RUNNING:
            self.halt()
        self.status = Status.IDLE

    def now(self) -> float:
        return self.config.clock()


def reset_all(nodes: Sequence[TreeNode]) -> None:
    for node in nodes:
        node.reset()


# -- an action over many ticks ----------------------------------------------------------------


class StatefulAction(TreeNode):
    """An action that runs over many ticks: :meth:`on_start` on its first, :meth:`on_running`
    while it runs, :meth:`on_halted` when it is halted while RUNNING; ticked again once it
    ended (a pipeline ticks what succeeded), it answers what it ended with until it is reset
    (BehaviorTree.CPP's StatefulActionNode)."""

    def tick(self) -> Status:
        if self.status is Status.IDLE:
            return self.on_start()
        return self.on_running() if self.status is Status.RUNNING else self.status

    def on_start(self) -> Status:
        raise NotImplementedError

    def on_running(self) -> Status:
        raise NotImplementedError

    def on_halted(self) -> None:
        pass

    def halt(self) -> None:
        if self.status is Status.RUNNING:
            self.on_halted()


class Tree:
    """A loaded tree: ``root`` ticked by :meth:`tick_once`, ``blackboard`` its top-level entries."""

    def __init__(self, root: TreeNode, blackboard: Blackboard) -> None:
        self.root = root
        self.blackboard = blackboard
        #: what the loader found worth saying (the file's own words), for its user to log
        self.warnings: list[str] = []

    def tick_once(self) -> Status:
        return self.root.execute_tick()

    def halt(self) -> None:
        """Halt every node and make it IDLE, as BehaviorTree.CPP's haltTree (a goal's end)."""
        for node in reversed(self.nodes()):  # leaves first
            node.halt()
            node.status = Status.IDLE

    def failures(self) -> list[str]:
        """The leaves that answered FAILURE since :meth:`forget_failures`, newest last (at most
        ``Blackboard.FAILURES_KEPT``), each ``name (file:line)``: where a failed tree failed."""
        return list(self.blackboard.failures)

    def forget_failures(self) -> None:
        self.blackboard.failures.clear()

    def nodes(self) -> list[TreeNode]:
        """Every node, depth first."""
        found: list[TreeNode] = []
        stack = [self.root]
        while stack:
            node = stack.pop()
            found.append(node)
            stack.extend(reversed(node.children))
        return found


#: A library of BT nodes, by the XML name a tree gives each: what ``plugin_lib_names`` loads (an
#: entry point of ``pppbot_nav.bt_plugins``, or a module's ``BT_NODES``).
NodeLibrary = Mapping[str, type[TreeNode]]
