"""Nav2's control nodes and its decorators that need nothing but the tree (nav2_behavior_tree's
``PipelineSequence``, ``RecoveryNode``, ``RoundRobin``, ``RateController``, ``SingleTrigger``),
with Nav2 Jazzy's ports, defaults and semantics."""
from __future__ import annotations

from pppbot_nav.bt.builtin import Decorator
from pppbot_nav.bt.tree import NodeConfig, Status, TreeNode, input_port, reset_all
from pppbot_nav.errors import BehaviorTreeError


class PipelineSequence(TreeNode):
    """Ticks its children in order, each tick from the first: a child that succeeded is ticked
    again, one still RUNNING before the furthest reached lets the next ones tick (a path kept
    being replanned while the robot follows it). FAILURE of any child halts all and fails; the
    last child's SUCCESS halts all and succeeds."""

    CHILDREN = None

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.furthest = 0

    def tick(self) -> Status:
        for index, child in enumerate(self.children):
            status = child.execute_tick()
            if status is Status.FAILURE:
                self.halt()
                return status
            if status is Status.RUNNING and index >= self.furthest:
                self.furthest = index
                return status
        self.halt()
        return Status.SUCCESS

    def halt(self) -> None:
        self.furthest = 0
        super().halt()


class RecoveryNode(TreeNode):
    """Two children: the action, and the recovery ticked when the action fails, up to
    ``number_of_retries`` times (default 1); after each successful recovery the action runs
    again. SUCCESS when the action succeeds; FAILURE when the recovery fails or is skipped,
    or the retries are spent."""

    CHILDREN = 2
    PORTS = (input_port("number_of_retries", int, 1),)

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.current = 0
        self.retries = 0

    def tick(self) -> Status:
        allowed = self.get_input("number_of_retries")
        while self.retries <= allowed:
            status = self.children[self.current].execute_tick()
            if status is Status.RUNNING:
                return status
            if self.current == 0:
                if status is Status.FAILURE and self.retries < allowed:
                    self.children[0].reset()
                    self.current = 1
                    continue
                self.halt()
                return status  # SUCCESS, SKIPPED, or FAILURE with the retries spent
            if status is Status.SUCCESS:
                self.children[1].reset()
                self.retries += 1
                self.current = 0
                continue
            if status is Status.SKIPPED:  # no recovery possible; it counts as no retry
                self.children[1].reset()
                self.current = 0
                return Status.FAILURE
            self.halt()
            return Status.FAILURE
        self.halt()
        return Status.FAILURE

    def halt(self) -> None:
        self.current = 0
        self.retries = 0
        super().halt()


class RoundRobin(TreeNode):
    """Ticks one child at a time, beginning after the one that last ended: SUCCESS with the first
    that succeeds (the next tick starts after it); FAILURE once every child failed in turn (over
    ticks: a recovery runs for many), or SKIPPED when all of this tick's were skipped; then it
    starts again at its first child, as after a halt (Nav2's)."""

    CHILDREN = None

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.current = 0
        self.failed = 0  # children failed in a row, over ticks

    def tick(self) -> Status:
        skipped = 0  # in this tick only, as Nav2's
        while self.failed + skipped < len(self.children):
            status = self.children[self.current].execute_tick()
            if status is Status.RUNNING:
                return status
            self.children[self.current].reset()
            self.current = (self.current + 1) % len(self.children)
            if status is Status.SUCCESS:
                self.failed = 0
                reset_all(self.children)
                return status
            if status is Status.SKIPPED:
                skipped += 1
            else:
                self.failed += 1
        all_skipped = skipped == len(self.children)
        self.halt()
        return Status.SKIPPED if all_skipped else Status.FAILURE

    def halt(self) -> None:
        self.current = 0  # a halted round robin (a goal's end) starts again at its first child
        self.failed = 0
        super().halt()


class RateController(Decorator):
    """Ticks its child at most ``hz`` times a second of the tree's clock (default 10): the first
    tick, while the child runs, and once the period has passed since the child last succeeded;
    between, RUNNING (as Nav2's: a Sequence above it waits, a PipelineSequence goes on to the
    next child)."""

    PORTS = (input_port("hz", float, 10.0),)

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.start = 0.0
        self.first = True

    def tick(self) -> Status:
        hz = self.get_input("hz")
        if not hz > 0:
            raise BehaviorTreeError(f"{self._where()}RateController '{self.name}': hz = {hz}: must be above 0")
        if self.status in (Status.IDLE, Status.SKIPPED):  # a new run: the period starts now
            self.start = self.now()
            self.first = True
        if self.first or self.child.status is Status.RUNNING or self.now() - self.start >= 1.0 / hz:
            self.first = False
            status = self.child.execute_tick()
            if status in (Status.RUNNING, Status.SKIPPED):
                return status
            if status is Status.SUCCESS:
                self.start = self.now()
            self.child.reset()
            return status
        return Status.RUNNING


class SingleTrigger(Decorator):
    """Ticks its child to the end once; after that, FAILURE until the node is reset."""

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.first = True

    def tick(self) -> Status:
        if self.status is Status.IDLE:
            self.first = True
        if not self.first:
            return Status.FAILURE
        status = self.child.execute_tick()
        if status is not Status.RUNNING:
            self.first = False
            self.child.reset()
        return status


#: Nav2's nodes here, by their XML names
NAV2_CONTROL_NODES: dict[str, type[TreeNode]] = {
    "PipelineSequence": PipelineSequence, "RecoveryNode": RecoveryNode, "RoundRobin": RoundRobin,
    "RateController": RateController, "SingleTrigger": SingleTrigger,
}
