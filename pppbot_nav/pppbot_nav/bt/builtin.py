"""BehaviorTree.CPP 4's own nodes: the leaves ``AlwaysSuccess``, ``AlwaysFailure``, ``SetBlackboard``
and ``Sleep``; the controls ``Sequence``, ``SequenceWithMemory``, ``ReactiveSequence``,
``Fallback``, ``ReactiveFallback`` and ``Parallel``; the decorators ``Inverter``,
``ForceSuccess``, ``ForceFailure``, ``Repeat``, ``RetryUntilSuccessful``,
``KeepRunningUntilFailure``, ``Delay``, ``Timeout``, and ``SubTree``'s node. Their ports and
semantics are BehaviorTree.CPP 4's (see :mod:`pppbot_nav.bt.tree` for where they differ)."""
from __future__ import annotations

import math
from typing import ClassVar

from pppbot_nav.bt.tree import (
    NodeConfig,
    Port,
    PortKind,
    StatefulAction,
    Status,
    TreeNode,
    blackboard_key,
    input_port,
    reset_all,
)
from pppbot_nav.errors import BehaviorTreeError

# -- leaves ---------------------------------------------------------------------------------


class AlwaysSuccess(TreeNode):
    def tick(self) -> Status:
        return Status.SUCCESS


class AlwaysFailure(TreeNode):
    def tick(self) -> Status:
        return Status.FAILURE


class SetBlackboard(TreeNode):
    """Writes ``value`` (a literal, or another entry's value) to the entry ``output_key`` names."""

    PORTS = (input_port("value"), Port("output_key", str, kind=PortKind.INOUT))

    def tick(self) -> Status:
        key = self.config.attributes.get("output_key", "")
        target = blackboard_key(key) or key
        self.config.blackboard.set(target, self.get_input("value"))
        return Status.SUCCESS


class Sleep(StatefulAction):
    """RUNNING until ``msec`` ms of the tree's clock have passed, then SUCCESS."""

    PORTS = (input_port("msec", int),)
    _until = 0.0

    def on_start(self) -> Status:
        self._until = self.now() + self.get_input("msec") / 1000.0
        return self.on_running()

    def on_running(self) -> Status:
        return Status.SUCCESS if self.now() >= self._until else Status.RUNNING


# -- control nodes --------------------------------------------------------------------------


class _Ordered(TreeNode):
    """Sequence and Fallback: children in order, from the one that ran last (``reactive``: from the
    first, every tick). ``go_on``: what a child answers for the next to be ticked (SUCCESS in a
    sequence, FAILURE in a fallback); the other completion ends the node with it."""

    CHILDREN = None
    go_on = Status.SUCCESS
    reactive = False
    memory = False  # on the ending answer, keep the place (SequenceWithMemory)

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.current = 0
        self._all_skipped = True

    def tick(self) -> Status:
        if self.status is Status.IDLE:
            self._all_skipped = True
        start = 0 if self.reactive else self.current
        for index in range(start, len(self.children)):
            child = self.children[index]
            status = child.execute_tick()
            if status is Status.RUNNING:
                if self.reactive:  # every other child IDLE: what ran after it is no longer wanted
                    reset_all(self.children[:index] + self.children[index + 1:])
                else:
                    self.current = index
                self._all_skipped = False
                return Status.RUNNING
            if status is Status.SKIPPED:
                continue
            self._all_skipped = False
            if status is not self.go_on:
                if self.memory:
                    self.current = index
                    reset_all(self.children[index:])
                else:
                    self.current = 0
                    reset_all(self.children)
                return status
        self.current = 0
        reset_all(self.children)
        return Status.SKIPPED if self._all_skipped else self.go_on

    def halt(self) -> None:
        if not self.memory:  # SequenceWithMemory keeps its place, as BehaviorTree.CPP 4's
            self.current = 0
        super().halt()


class SequenceNode(_Ordered):
    """BehaviorTree.CPP's Sequence."""


class SequenceWithMemory(_Ordered):
    memory = True


class ReactiveSequence(_Ordered):
    reactive = True


class Fallback(_Ordered):
    go_on = Status.FAILURE


class ReactiveFallback(_Ordered):
    go_on = Status.FAILURE
    reactive = True


class Parallel(TreeNode):
    """Ticks every child not yet done, each tick: SUCCESS once ``success_count`` succeeded (-1: all),
    FAILURE once ``failure_count`` failed or success can no longer be reached."""

    CHILDREN = None
    PORTS = (input_port("success_count", int, -1), input_port("failure_count", int, 1))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self._done: dict[int, Status] = {}

    def tick(self) -> Status:
        n = len(self.children)
        success_needed = self.get_input("success_count")
        failure_needed = self.get_input("failure_count")
        success_needed = n + success_needed + 1 if success_needed < 0 else success_needed
        failure_needed = n + failure_needed + 1 if failure_needed < 0 else failure_needed
        if not (0 < success_needed <= n and 0 < failure_needed <= n):
            raise BehaviorTreeError(f"{self._where()}'{self.name}': success_count and failure_count must be "
                                    f"from 1 to its {n} children (or -1 for all)")
        for index, child in enumerate(self.children):  # decided as soon as a child's answer decides it
            if index in self._done:
                continue
            status = child.execute_tick()
            if status is Status.RUNNING:
                continue
            self._done[index] = status
            done = list(self._done.values())
            failures, skipped = done.count(Status.FAILURE), done.count(Status.SKIPPED)
            if done.count(Status.SUCCESS) >= success_needed:
                self.halt()
                return Status.SUCCESS
            if failures >= failure_needed or n - skipped - failures < success_needed:
                self.halt()
                return Status.FAILURE
        if len(self._done) == n:  # all skipped
            self.halt()
            return Status.SKIPPED
        return Status.RUNNING

    def halt(self) -> None:
        self._done.clear()
        super().halt()


# -- decorators -----------------------------------------------------------------------------


class Decorator(TreeNode):
    CHILDREN = 1

    @property
    def child(self) -> TreeNode:
        return self.children[0]


class _Mapped(Decorator):
    """Inverter, ForceSuccess and ForceFailure: the child's SUCCESS and FAILURE answered as
    ``answers`` says (the child reset); RUNNING and SKIPPED as they are."""

    answers: ClassVar[dict[Status, Status]] = {}

    def tick(self) -> Status:
        status = self.child.execute_tick()
        if status.completed:
            self.child.reset()
            return self.answers[status]
        return status


class Inverter(_Mapped):
    answers = {Status.SUCCESS: Status.FAILURE, Status.FAILURE: Status.SUCCESS}


class ForceSuccess(_Mapped):
    answers = {Status.SUCCESS: Status.SUCCESS, Status.FAILURE: Status.SUCCESS}


class ForceFailure(_Mapped):
    answers = {Status.SUCCESS: Status.FAILURE, Status.FAILURE: Status.FAILURE}


class _Loop(Decorator):
    """Repeat and RetryUntilSuccessful: the child again while it answers ``again``, up to ``limit``
    times (-1: without end, once per tick)."""

    again = Status.SUCCESS
    limit_port = "num_cycles"

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.count = 0

    def tick(self) -> Status:
        limit = self.get_input(self.limit_port)
        if limit < -1:
            raise BehaviorTreeError(f"{self._where()}{type(self).__name__} '{self.name}': {self.limit_port} = "
                                    f"{limit}: -1 (without end) or a count from 0")
        if limit == 0:  # nothing to run: done as if every cycle had gone
            return self.again
        while True:
            status = self.child.execute_tick()
            if status is Status.RUNNING:
                return status
            self.child.reset()
            if status is Status.SKIPPED:
                return status
            if status is not self.again:
                self.count = 0
                return status
            self.count += 1
            if limit < 0:
                return Status.RUNNING  # without end: one cycle per tick
            if self.count >= limit:
                self.count = 0
                return self.again

    def halt(self) -> None:
        self.count = 0
        super().halt()


class Repeat(_Loop):
    PORTS = (input_port("num_cycles", int),)


class RetryUntilSuccessful(_Loop):
    PORTS = (input_port("num_attempts", int),)
    again = Status.FAILURE
    limit_port = "num_attempts"


class KeepRunningUntilFailure(Decorator):
    def tick(self) -> Status:
        status = self.child.execute_tick()
        if status is Status.SUCCESS:
            self.child.reset()
            return Status.RUNNING
        if status is Status.FAILURE:
            self.child.reset()
        return status


class Delay(Decorator):
    """RUNNING for ``delay_msec`` ms of the tree's clock, then the child's answers."""

    PORTS = (input_port("delay_msec", int),)
    _until: float | None = None

    def tick(self) -> Status:
        if self._until is None:
            self._until = self.now() + self.get_input("delay_msec") / 1000.0
        if self.now() < self._until:
            return Status.RUNNING
        status = self.child.execute_tick()
        if status is not Status.RUNNING:
            self._until = None
            self.child.reset()
        return status

    def halt(self) -> None:
        self._until = None
        super().halt()


class Timeout(Decorator):
    """The child's answers, but FAILURE (the child halted) once it ran ``msec`` ms of the tree's clock
    (0 or less: no limit, as BehaviorTree.CPP's)."""

    PORTS = (input_port("msec", int),)
    _until: float | None = None

    def tick(self) -> Status:
        if self._until is None:
            msec = self.get_input("msec")
            self._until = self.now() + msec / 1000.0 if msec > 0 else math.inf
        if self.now() >= self._until:
            self.halt()
            return Status.FAILURE
        status = self.child.execute_tick()
        if status is not Status.RUNNING:
            self._until = None
            self.child.reset()
        return status

    def halt(self) -> None:
        self._until = None
        super().halt()


class SubTree(Decorator):
    """A tree of the same file, on a blackboard of its own (see :class:`Blackboard`)."""

    def tick(self) -> Status:
        status = self.child.execute_tick()
        if status is not Status.RUNNING:
            self.child.reset()
        return status


#: BehaviorTree.CPP 4's own nodes, by their XML names
BUILTIN_NODES: dict[str, type[TreeNode]] = {
    "AlwaysSuccess": AlwaysSuccess, "AlwaysFailure": AlwaysFailure, "SetBlackboard": SetBlackboard,
    "Sleep": Sleep,
    "Sequence": SequenceNode, "SequenceWithMemory": SequenceWithMemory, "ReactiveSequence": ReactiveSequence,
    "Fallback": Fallback, "ReactiveFallback": ReactiveFallback, "Parallel": Parallel,
    "Inverter": Inverter, "ForceSuccess": ForceSuccess, "ForceFailure": ForceFailure, "Repeat": Repeat,
    "RetryUntilSuccessful": RetryUntilSuccessful, "KeepRunningUntilFailure": KeepRunningUntilFailure,
    "Delay": Delay, "Timeout": Timeout,
}
