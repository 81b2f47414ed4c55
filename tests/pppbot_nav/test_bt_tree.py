"""The behaviour-tree engine: BehaviorTree.CPP 4's control nodes and decorators, Nav2's controls,
the blackboard and subtrees, and what the XML loader refuses, each against its documented
semantics (which child is ticked, which halted, what is answered), with trees written here."""
from __future__ import annotations

from typing import Any, ClassVar

import pytest

from pppbot_nav.bt.tree import Blackboard, NodeConfig, Status, TreeNode, input_port, output_port
from pppbot_nav.bt.xml_tree import TreeFactory
from pppbot_nav.errors import BehaviorTreeError

S, F, R, K = Status.SUCCESS, Status.FAILURE, Status.RUNNING, Status.SKIPPED


class Step(TreeNode):
    """A leaf answering its script (``id`` names it in :attr:`SCRIPTS`), one answer a tick, the last
    again once it is spent; ticks and halts go to :attr:`LOG`."""

    PORTS = (input_port("id"),)
    SCRIPTS: ClassVar[dict[str, list[Status]]] = {}
    LOG: ClassVar[list[str]] = []

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.ticks = 0

    def tick(self) -> Status:
        key = self.get_input("id")
        script = self.SCRIPTS[key]
        self.LOG.append(key)
        status = script[min(self.ticks, len(script) - 1)]
        self.ticks += 1
        return status

    def halt(self) -> None:
        self.LOG.append(f"halt {self.get_input('id')}")


class Read(TreeNode):
    """Copies its input ``value`` to its output ``out``, where the test reads it."""

    PORTS = (input_port("value", float), output_port("out"))

    def tick(self) -> Status:
        self.set_output("out", self.get_input("value"))
        return Status.SUCCESS


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def tree(body: str, scripts: dict[str, list[Status]], clock: Any = None, **trees: str) -> Any:
    Step.SCRIPTS = scripts
    Step.LOG = []
    others = "".join(f'<BehaviorTree ID="{key}">{value}</BehaviorTree>' for key, value in trees.items())
    xml = (f'<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{body}</BehaviorTree>'
           f"{others}</root>")
    return TreeFactory({"Step": Step, "Read": Read}).load(xml, name="test.xml", clock=clock or Clock())


def ticks(loaded: Any, n: int) -> list[Status]:
    return [loaded.tick_once() for _ in range(n)]


def steps(*ids: str) -> str:
    return "".join(f'<Step id="{i}"/>' for i in ids)


# -- BehaviorTree.CPP's controls ----------------------------------------------------------------

def test_a_sequence_resumes_at_its_running_child_and_starts_again_after_it_ends():
    t = tree(f"<Sequence>{steps('a', 'b', 'c')}</Sequence>", {"a": [S], "b": [R, R, S], "c": [S]})
    assert ticks(t, 3) == [R, R, S]
    assert Step.LOG == ["a", "b", "b", "b", "c"]  # a not ticked again while b runs
    assert all(node.status is Status.IDLE for node in t.root.children)  # reset for the next run


@pytest.mark.parametrize(("control", "second_run"), [("Sequence", ["a", "b"]), ("SequenceWithMemory", ["b"])])
def test_a_sequence_fails_with_its_child_and_only_the_memory_one_keeps_its_place(control, second_run):
    t = tree(f"<{control}>{steps('a', 'b')}</{control}>", {"a": [S], "b": [F, S]})
    assert t.tick_once() is F and Step.LOG == ["a", "b"]
    Step.LOG.clear()
    assert t.tick_once() is S and second_run == Step.LOG


def test_a_reactive_sequence_checks_its_conditions_every_tick_and_halts_the_action_they_fail():
    t = tree(f"<ReactiveSequence>{steps('ok', 'act')}</ReactiveSequence>", {"ok": [S, S, F], "act": [R]})
    assert ticks(t, 3) == [R, R, F]
    assert Step.LOG == ["ok", "act", "ok", "act", "ok", "halt act"]


def test_a_fallback_tries_its_children_in_turn_and_a_reactive_one_halts_when_an_earlier_succeeds():
    t = tree(f"<Fallback>{steps('a', 'b', 'c')}</Fallback>", {"a": [F], "b": [F], "c": [R, S]})
    assert ticks(t, 2) == [R, S] and Step.LOG == ["a", "b", "c", "c"]
    t = tree(f"<ReactiveFallback>{steps('goal_reached', 'drive')}</ReactiveFallback>",
             {"goal_reached": [F, F, S], "drive": [R]})
    assert ticks(t, 3) == [R, R, S]
    assert Step.LOG[-2:] == ["goal_reached", "halt drive"]


def test_skipped_children_are_passed_over_and_all_skipped_is_skipped():
    assert tree(f"<Sequence>{steps('a', 'b')}</Sequence>", {"a": [K], "b": [S]}).tick_once() is S
    assert tree(f"<Sequence>{steps('a', 'b')}</Sequence>", {"a": [K], "b": [K]}).tick_once() is K


def test_parallel_counts_successes_and_failures_and_halts_what_still_runs():
    t = tree(f'<Parallel success_count="1" failure_count="2">{steps("a", "b", "c")}</Parallel>',
             {"a": [R, R, S], "b": [R], "c": [F]})
    assert ticks(t, 3) == [R, R, S]
    assert Step.LOG == ["a", "b", "c", "a", "b", "a", "halt b"]  # c done: not ticked again
    t = tree(f'<Parallel success_count="-1" failure_count="1">{steps("a", "b")}</Parallel>', {"a": [R], "b": [F]})
    assert t.tick_once() is F and Step.LOG[-1] == "halt a"


# -- BehaviorTree.CPP's decorators ---------------------------------------------------------------

@pytest.mark.parametrize(("decorator", "child", "answer"), [
    ("Inverter", S, F), ("Inverter", F, S), ("Inverter", R, R), ("ForceSuccess", F, S), ("ForceFailure", S, F),
    ("ForceSuccess", R, R)])
def test_inverting_and_forcing_decorators(decorator, child, answer):
    assert tree(f'<{decorator}><Step id="a"/></{decorator}>', {"a": [child]}).tick_once() is answer


def test_repeat_and_retry_loop_within_a_tick_up_to_their_count():
    t = tree('<Repeat num_cycles="3"><Step id="a"/></Repeat>', {"a": [S]})
    assert t.tick_once() is S and Step.LOG == ["a"] * 3
    assert tree('<Repeat num_cycles="3"><Step id="a"/></Repeat>', {"a": [S, F]}).tick_once() is F
    t = tree('<RetryUntilSuccessful num_attempts="3"><Step id="a"/></RetryUntilSuccessful>', {"a": [F, F, S]})
    assert t.tick_once() is S and Step.LOG == ["a"] * 3
    assert tree('<RetryUntilSuccessful num_attempts="2"><Step id="a"/></RetryUntilSuccessful>',
                {"a": [F, F, S]}).tick_once() is F
    forever = tree('<Repeat num_cycles="-1"><Step id="a"/></Repeat>', {"a": [S]})
    assert ticks(forever, 3) == [R, R, R] and Step.LOG == ["a"] * 3  # one cycle a tick
    keep = tree("<KeepRunningUntilFailure><Step id='a'/></KeepRunningUntilFailure>", {"a": [S, S, F]})
    assert ticks(keep, 3) == [R, R, F]
    # no cycle to run: done at once, the child untouched (BehaviorTree.CPP's loops test before ticking)
    assert tree('<Repeat num_cycles="0"><Step id="a"/></Repeat>', {"a": [F]}).tick_once() is S and not Step.LOG
    assert tree('<RetryUntilSuccessful num_attempts="0"><Step id="a"/></RetryUntilSuccessful>',
                {"a": [S]}).tick_once() is F and not Step.LOG
    with pytest.raises(BehaviorTreeError, match=r"num_cycles = -2: -1 \(without end\) or a count from 0"):
        tree('<Repeat num_cycles="-2"><Step id="a"/></Repeat>', {"a": [S]}).tick_once()


def test_delay_and_timeout_count_the_trees_clock():
    clock = Clock()
    t = tree('<Delay delay_msec="500"><Step id="a"/></Delay>', {"a": [S]}, clock)
    assert t.tick_once() is R and not Step.LOG
    clock.now = 0.5
    assert t.tick_once() is S and Step.LOG == ["a"]
    clock.now = 0.0
    t = tree('<Timeout msec="1000"><Step id="a"/></Timeout>', {"a": [R]}, clock)
    assert t.tick_once() is R
    clock.now = 1.0
    assert t.tick_once() is F and Step.LOG == ["a", "halt a"]
    clock.now = 0.0
    t = tree('<Timeout msec="0"><Step id="a"/></Timeout>', {"a": [R, R, S]}, clock)
    clock.now = 1e6
    assert ticks(t, 3) == [R, R, S]  # 0: no limit


# -- Nav2's controls ------------------------------------------------------------------------------

def test_a_pipeline_ticks_what_succeeded_again_and_lets_a_running_earlier_child_run_on():
    t = tree(f"<PipelineSequence>{steps('plan', 'follow')}</PipelineSequence>",
             {"plan": [R, S, R, S], "follow": [R, R, S]})
    assert ticks(t, 4) == [R, R, R, S]
    # plan runs, then succeeds and follow starts; plan (replanning) runs again while follow runs on
    assert Step.LOG == ["plan", "plan", "follow", "plan", "follow", "plan", "follow"]
    t = tree(f"<PipelineSequence>{steps('plan', 'follow')}</PipelineSequence>", {"plan": [S, F], "follow": [R]})
    assert ticks(t, 2) == [R, F] and Step.LOG[-1] == "halt follow"


def test_a_recovery_node_recovers_as_often_as_it_may_and_fails_after():
    t = tree(f'<RecoveryNode number_of_retries="2">{steps("nav", "clear")}</RecoveryNode>',
             {"nav": [F, F, S], "clear": [S]})
    assert t.tick_once() is S and Step.LOG == ["nav", "clear", "nav", "clear", "nav"]
    t = tree(f'<RecoveryNode number_of_retries="1">{steps("nav", "clear")}</RecoveryNode>', {"nav": [F], "clear": [S]})
    assert t.tick_once() is F and Step.LOG == ["nav", "clear", "nav"]
    t = tree(f"<RecoveryNode>{steps('nav', 'clear')}</RecoveryNode>", {"nav": [F], "clear": [F]})
    assert t.tick_once() is F and Step.LOG == ["nav", "clear"]
    t = tree(f"<RecoveryNode>{steps('nav', 'clear')}</RecoveryNode>", {"nav": [F], "clear": [R, S]})
    assert ticks(t, 2) == [R, F]  # the recovery runs; then the action, which fails again: retries spent


def test_a_round_robin_starts_after_the_child_that_last_ended():
    t = tree(f"<RoundRobin>{steps('spin', 'wait', 'back_up')}</RoundRobin>",
             {"spin": [F, S], "wait": [S], "back_up": [S]})
    assert t.tick_once() is S and Step.LOG == ["spin", "wait"]
    assert t.tick_once() is S and Step.LOG[2:] == ["back_up"]
    assert t.tick_once() is S and Step.LOG[3:] == ["spin"]
    t = tree(f"<RoundRobin>{steps('a', 'b', 'c')}</RoundRobin>", {"a": [S, F], "b": [F], "c": [F]})
    assert t.tick_once() is S and Step.LOG == ["a"]
    assert t.tick_once() is F and Step.LOG[1:] == ["b", "c", "a"]
    assert t.tick_once() is F and Step.LOG[4:] == ["a", "b", "c"]  # after all failed: from the first again
    t = tree(f"<RoundRobin>{steps('a', 'b')}</RoundRobin>", {"a": [K], "b": [K, F]})
    assert t.tick_once() is K and Step.LOG == ["a", "b"]  # all skipped: skipped
    assert t.tick_once() is F and Step.LOG[2:] == ["a", "b"]  # skips count in their tick only


def test_a_round_robin_of_recoveries_that_run_for_ticks_fails_once_each_failed_and_restarts_after_a_halt():
    t = tree(f"<RoundRobin>{steps('spin', 'wait', 'back_up')}</RoundRobin>",
             {"spin": [R, F], "wait": [R, F, R, S], "back_up": [R, F]})
    assert ticks(t, 4) == [R, R, R, F]  # each ran a tick and failed the next: all failed
    assert Step.LOG == ["spin", "spin", "wait", "wait", "back_up", "back_up"]
    assert t.tick_once() is R and Step.LOG[6:] == ["spin", "wait"]  # a new round: spin fails, wait runs
    t.halt()  # the goal ended: the next starts at the first child, not at wait
    Step.LOG.clear()
    t.tick_once()
    assert Step.LOG[0] == "spin"


def test_an_action_that_ended_answers_the_same_when_a_pipeline_ticks_it_again_until_reset():
    from pppbot_nav.bt.tree import StatefulAction

    class Plan(StatefulAction):
        starts = 0

        def on_start(self) -> Status:
            Plan.starts += 1
            return Status.RUNNING

        def on_running(self) -> Status:
            return Status.SUCCESS

    xml = ('<root BTCPP_format="4"><BehaviorTree ID="M"><PipelineSequence><Plan/><Step id="follow"/>'
           "</PipelineSequence></BehaviorTree></root>")
    Step.SCRIPTS, Step.LOG = {"follow": [R]}, []
    t = TreeFactory({"Plan": Plan, "Step": Step}).load(xml, name="t.xml")
    assert ticks(t, 5) == [R] * 5 and Plan.starts == 1  # started once; its SUCCESS stands
    t.halt()
    t.tick_once()
    assert Plan.starts == 2


def test_a_rate_controller_ticks_its_child_once_a_period_of_the_trees_clock():
    clock = Clock()
    t = tree(f'<PipelineSequence><RateController hz="1.0"><Step id="plan"/></RateController>{steps("follow")}'
             "</PipelineSequence>", {"plan": [S], "follow": [R]}, clock)
    for now in (0.0, 0.5, 0.99, 1.0, 1.5, 2.0):
        clock.now = now
        assert t.tick_once() is R
    assert Step.LOG.count("plan") == 3  # at 0, 1 and 2 s


def test_a_rate_controller_answers_running_between_its_periods():
    clock = Clock()
    t = tree('<RateController hz="2"><Step id="plan"/></RateController>', {"plan": [S]}, clock)
    answers = []
    for now in (0.0, 0.2, 0.5, 0.7):
        clock.now = now
        answers.append(t.tick_once())
    # nobody resets the root: between periods it says RUNNING (Nav2's), not its last SUCCESS
    assert answers == [S, R, S, R] and Step.LOG == ["plan", "plan"]


def test_a_reactive_sequence_restarts_a_rate_controller_before_a_running_child():
    clock = Clock()
    t = tree(f'<ReactiveSequence><RateController hz="2"><Step id="plan"/></RateController>{steps("follow")}'
             "</ReactiveSequence>", {"plan": [S], "follow": [R]}, clock)
    for now in (0.0, 0.2):
        clock.now = now
        assert t.tick_once() is R
    # BehaviorTree.CPP 4: a running child makes its siblings IDLE, so the controller starts anew
    assert Step.LOG == ["plan", "follow", "plan", "follow"]


def test_a_rate_controller_starts_its_period_again_when_its_parent_resets_it():
    clock = Clock()
    t = tree(f'<Sequence><RateController hz="2"><Step id="plan"/></RateController>{steps("after")}</Sequence>',
             {"plan": [S], "after": [S]}, clock)
    for now in (0.0, 0.2):
        clock.now = now
        assert t.tick_once() is S  # a sequence that ended made its children IDLE: a new first tick
    assert Step.LOG == ["plan", "after", "plan", "after"]


def test_a_single_trigger_ticks_its_child_once_until_reset():
    t = tree("<SingleTrigger><Step id='a'/></SingleTrigger>", {"a": [S]})
    assert ticks(t, 2) == [S, F] and Step.LOG == ["a"]
    t.halt()
    assert t.tick_once() is S


# -- the blackboard and subtrees -------------------------------------------------------------------

def test_ports_read_literals_and_entries_and_subtrees_remap_and_autoremap():
    t = tree('<Sequence><SetBlackboard value="2.5" output_key="speed"/><Read value="{speed}" out="{seen}"/>'
             '<SubTree ID="Inner" v="{speed}" result="{inner_seen}"/><SubTree ID="Auto" _autoremap="true"/>'
             '<Read value="7" out="{literal}"/></Sequence>', {},
             Inner='<Read value="{v}" out="{result}"/>', Auto='<Read value="{speed}" out="{auto_seen}"/>')
    assert t.tick_once() is S
    board = t.blackboard
    assert (board.get("seen"), board.get("inner_seen"), board.get("auto_seen"), board.get("literal")) == (
        2.5, 2.5, 2.5, 7.0)
    assert "result" not in board and "v" not in board  # the subtree's own names stay in it


def test_the_equals_shorthand_names_the_entry_after_the_port():
    t = tree('<Sequence><SetBlackboard value="4" output_key="value"/><Read value="{=}" out="{=}"/>'
             '<SubTree ID="Inner" out="{=}"/></Sequence>', {}, Inner='<Read value="1.5" out="{out}"/>')
    assert t.tick_once() is S and t.blackboard.get("out") == 1.5  # the subtree wrote the parent's 'out'
    t = tree('<Sequence><SetBlackboard value="4" output_key="value"/><Read value="{=}" out="{=}"/></Sequence>', {})
    assert t.tick_once() is S and t.blackboard.get("out") == 4.0


def test_a_subtree_without_remapping_keeps_its_entries_to_itself():
    parent = Blackboard()
    parent.set("x", 1)
    inner = Blackboard(parent, {"y": "{x}", "z": "literal"})
    inner.set("own", 3)
    assert (inner.get("y"), inner.get("z"), "x" in inner, "own" in parent) == (1, "literal", False, False)
    inner.set("y", 5)
    assert parent.get("x") == 5


def test_a_file_without_btcpp_format_is_read_as_4_with_a_warning_naming_it():
    t = TreeFactory().load('<root>\n<BehaviorTree ID="M"><AlwaysSuccess/></BehaviorTree></root>', name="old.xml")
    assert t.tick_once() is S
    assert t.warnings == ['old.xml:1: <root> has no BTCPP_format: read as BehaviorTree.CPP 4\'s (BTCPP_format="4")']
    assert tree("<AlwaysSuccess/>", {}).warnings == []


# -- what the loader refuses -------------------------------------------------------------------------

@pytest.mark.parametrize(("xml", "message"), [
    ('<root BTCPP_format="4"><BehaviorTree ID="M">\n<Sequence>\n<Nope/></Sequence></BehaviorTree></root>',
     r"^bad\.xml:3: unknown node 'Nope'; known: .*AlwaysFailure.*"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M">\n<RateController rate="2"><Step id="a"/></RateController>'
     "</BehaviorTree></root>", r"^bad\.xml:2: RateController 'RateController' has no port 'rate'; its ports: hz$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><Repeat><Step id="a"/></Repeat></BehaviorTree></root>',
     r"^bad\.xml:1: Repeat 'Repeat': port 'num_cycles' is required$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><RateController hz="fast"><Step id="a"/></RateController>'
     "</BehaviorTree></root>", r"RateController': port 'hz' = 'fast': could not convert"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><Inverter>' + steps("a", "b") + "</Inverter></BehaviorTree></root>",
     r"Inverter 'Inverter' takes 1 child, not 2$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><RecoveryNode><Step id="a"/></RecoveryNode></BehaviorTree></root>',
     r"RecoveryNode 'RecoveryNode' takes 2 children, not 1$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><Sequence/></BehaviorTree></root>',
     r"Sequence 'Sequence' takes one or more children, not 0$"),
    ('<root BTCPP_format="3"><BehaviorTree ID="M"><AlwaysSuccess/></BehaviorTree></root>',
     r"^bad\.xml:1: BTCPP_format is '3': pppbot reads BehaviorTree.CPP 4's format"),
    ('<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="M"><AlwaysSuccess/></BehaviorTree></root>',
     r"main tree 'Main' is not in the file; its trees: M$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><SubTree ID="M"/></BehaviorTree></root>',
     r"SubTree 'M' runs itself \(M -> M\)$"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M"><AlwaysSuccess _skipIf="x"/></BehaviorTree></root>',
     r"'AlwaysSuccess': _skipIf: BehaviorTree.CPP's scripted preconditions and post-conditions are not supported"),
    ('<root BTCPP_format="4"><BehaviorTree ID="M">\n\n<Sequence></BehaviorTree></root>', r"^bad\.xml:3: malformed XML"),
])
def test_a_tree_written_wrong_is_refused_at_load_naming_file_line_and_what_is_known(xml, message):
    with pytest.raises(BehaviorTreeError, match=message):
        TreeFactory({"Step": Step}).load(xml, name="bad.xml")


def test_a_failed_tree_says_which_leaves_failed_where_and_why():
    class Refused(TreeNode):
        def tick(self) -> Status:
            self.why = "the server refused the goal"
            return Status.FAILURE

    xml = ('<root BTCPP_format="4">\n<BehaviorTree ID="M">\n<Fallback>\n<AlwaysFailure/>\n'
           '<Refused name="Follow"/>\n</Fallback>\n</BehaviorTree></root>')
    t = TreeFactory({"Refused": Refused}).load(xml, name="why.xml")
    assert t.tick_once() is F
    assert t.failures() == ["AlwaysFailure (why.xml:4)", "Follow (why.xml:5): the server refused the goal"]
    t.halt()
    assert len(t.failures()) == 2  # kept for the goal's message after the halt
    t.forget_failures()
    assert t.failures() == []
