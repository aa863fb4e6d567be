"""Node logic as pure transitions: each kind's inputs and the effects they return.

No threads, no clocks, no actors: a node's logic is built from a hand-made
program node and driven input by input.
"""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from eamos.actors.logic import (
    ActionLogic,
    Broadcast,
    CancelAction,
    DoEndLogic,
    DoLogic,
    Emit,
    IfLogic,
    LoopLogic,
    Note,
    PassThrough,
    Progress,
    Record,
    ReleaseBegin,
    Resolve,
    Route,
    StartAction,
    UnwatchTelemetry,
    WaitLogic,
    WatchTelemetry,
    logic_class,
    node_logic,
    program_wiring,
)
from eamos.actors.messages import Interrupt
from eamos.compiler import compile_mission
from eamos.program.format import ProgramNode

GT = [">", ["prop", "D1", "Z"], ["num", 1.0]]  # D1.Z() > 1


def spec(kind: str, key: str = "n5", **kw) -> ProgramNode:
    return ProgramNode(key=key, meg=int(key[1:]), kind=kind, drone="D1", native=True, **kw)


def route(dst: str, kind: str = "seq", drone: str = "D1") -> Route:
    return Route(dst, drone, kind, drone != "D1")


def emits(effects) -> list[tuple[str, tuple[int, ...], str]]:
    return [(e.route.dst, e.iteration, e.status) for e in effects if isinstance(e, Emit)]


def resolved(effects) -> list[tuple[tuple[int, ...], str, bool]]:
    return [(e.iteration, e.status, e.top_level) for e in effects if isinstance(e, Resolve)]


def kinds(effects) -> list[str]:
    return [type(e).__name__ for e in effects if not isinstance(e, Note)]


def progress(effects) -> list[str]:
    return [e.event.state for e in effects if isinstance(e, Progress)]


def notes(effects) -> list[str]:
    return [e.event for e in effects if isinstance(e, Note)]


def values(z: float | None) -> dict:
    return {"Z": z, "X": 0.0}


# -- pass-through (init, fork, end) ----------------------------------------------------------


def fork(entry=("n1", "n2"), **kw) -> PassThrough:
    logic = node_logic(spec("fork", **kw), (route("n8"), route("n9", drone="D2")), frozenset(entry))
    assert isinstance(logic, PassThrough)
    return logic


def test_fork_fires_only_when_every_entry_arc_delivered():
    logic = fork()
    assert emits(logic.trigger("n1", (), "done")) == []
    fx = logic.trigger("n2", (), "done")
    assert emits(fx) == [("n8", (), "done"), ("n9", (), "done")]
    assert resolved(fx) == [((), "done", True)]
    assert "mission.node.triggered" in notes(fx)


@pytest.mark.parametrize(
    ("first", "second", "out"),
    [
        ("done", "skipped", "done"),
        ("skipped", "skipped", "skipped"),
        ("done", "failed", "failed"),
        ("skipped", "failed", "failed"),
    ],
)
def test_dead_path_elimination_combines_statuses(first, second, out):
    logic = fork()
    logic.trigger("n1", (), first)
    fx = logic.trigger("n2", (), second)
    assert {s for _, _, s in emits(fx)} == {out}
    assert resolved(fx) == [((), out, True)]


def test_duplicate_and_foreign_triggers_are_ignored():
    logic = fork(entry=("n1",))
    assert emits(logic.trigger("n1", (), "done"))
    assert kinds(logic.trigger("n1", (), "done")) == []  # duplicate
    assert kinds(logic.trigger("n7", (), "done")) == []  # not an arc of this node
    assert logic.pre.duplicates == 1


def test_initial_node_fires_once_without_arcs():
    logic = node_logic(spec("init", "n0"), (route("n2", drone="D2"),), frozenset())
    assert emits(logic.fire()) == [("n2", (), "done")]
    assert logic.fire() == []


def test_nested_node_keeps_iterations_apart_and_never_resolves_top_level():
    logic = fork(entry=("n1",), loops=(3,))
    fx0 = logic.trigger("n1", (0,), "done")
    fx1 = logic.trigger("n1", (1,), "done")
    assert emits(fx0)[0][1] == (0,) and emits(fx1)[0][1] == (1,)
    assert resolved(fx0) == [((0,), "done", False)]


def test_interrupt_in_mode_all_skips_later_activations_in_scope_only():
    logic = fork(entry=("n1",), loops=(3,), scopes=(3,))
    logic.interrupt(Interrupt(3, (1,), "all"))
    assert {s for *_, s in emits(logic.trigger("n1", (1,), "done"))} == {"skipped"}
    assert {s for *_, s in emits(logic.trigger("n1", (2,), "done"))} == {"done"}


def test_interrupts_of_other_scopes_or_mode_waits_do_not_reach_a_fork():
    logic = fork(entry=("n1",), scopes=(3,))
    assert logic.interrupt(Interrupt(4, (), "all")) == []
    assert logic.interrupt(Interrupt(3, (), "waits")) == []
    assert {s for *_, s in emits(logic.trigger("n1", (), "done"))} == {"done"}


@given(
    st.permutations(["n1", "n2", "n3"]),
    st.lists(st.sampled_from(["n1", "n2", "n3"]), max_size=6),
    st.lists(st.sampled_from(["done", "skipped", "failed"]), min_size=3, max_size=3),
)
def test_a_join_fires_exactly_once_whatever_the_order_and_duplicates(order, dups, statuses):
    logic = fork(entry=("n1", "n2", "n3"))
    status_of = dict(zip(["n1", "n2", "n3"], statuses, strict=True))
    out = []
    for src in [*order, *dups]:
        out += logic.trigger(src, (), status_of[src])  # type: ignore[arg-type]
    expected = "failed" if "failed" in statuses else "done" if "done" in statuses else "skipped"
    assert resolved(out) == [((), expected, True)]
    assert len(emits(out)) == 2


# -- action ----------------------------------------------------------------------------------


def action(**kw) -> ActionLogic:
    logic = node_logic(
        spec("action", action="FlyByX", args=(2.0,), label="FlyByX(2)", **kw),
        (route("n8"),),
        frozenset({"n1"}),
    )
    assert isinstance(logic, ActionLogic)
    return logic


def test_action_runs_then_hands_on_its_outcome():
    logic = action()
    fx = logic.trigger("n1", (), "done")
    assert kinds(fx) == ["Progress", "StartAction"]
    assert fx[-1] == StartAction((), "FlyByX", (2.0,))
    assert progress(fx) == ["running"]
    fx = logic.action_finished((), "ok", "", 10.0, 12.5)
    assert kinds(fx) == ["Record", "Emit", "Resolve"]
    (record,) = [e.record for e in fx if isinstance(e, Record)]
    assert (record.node, record.action, record.args, record.start, record.end) == (
        "n5",
        "FlyByX",
        (2.0,),
        10.0,
        12.5,
    )
    assert emits(fx) == [("n8", (), "done")]


@pytest.mark.parametrize(("result", "status"), [("failed", "failed"), ("cancelled", "skipped")])
def test_failed_action_blocks_successors_and_cancelled_one_skips_them(result, status):
    logic = action()
    logic.trigger("n1", (), "done")
    fx = logic.action_finished((), result, "why", 0.0, 1.0)
    assert emits(fx) == [("n8", (), status)] and resolved(fx) == [((), status, True)]
    assert ("mission.action.failed" in notes(fx)) == (result == "failed")


def test_action_result_for_an_activation_not_running_is_ignored():
    logic = action()
    assert logic.action_finished((), "ok", "", 0.0, 1.0) == []


@pytest.mark.parametrize(("incoming", "state"), [("failed", "blocked"), ("skipped", "skipped")])
def test_action_not_run_when_its_predecessor_failed_or_was_skipped(incoming, state):
    logic = action()
    fx = logic.trigger("n1", (), incoming)
    assert "StartAction" not in kinds(fx)
    assert progress(fx) == [state] and emits(fx) == [("n8", (), incoming)]


def test_interrupt_cancels_the_running_action_of_its_scope_activation_only():
    logic = node_logic(
        spec("action", action="FlyByX", args=(1.0,), loops=(3,), scopes=(3,)),
        (route("n8"),),
        frozenset({"n1"}),
    )
    logic.trigger("n1", (0,), "done")
    logic.trigger("n1", (1,), "done")
    fx = logic.interrupt(Interrupt(3, (1,), "all"))
    assert [e for e in fx if isinstance(e, CancelAction)] == [CancelAction((1,))]
    assert emits(logic.action_finished((1,), "cancelled", "", 0.0, 1.0)) == [
        ("n8", (1,), "skipped")
    ]


def test_action_in_mode_waits_is_not_interrupted():
    logic = action(scopes=(3,))
    logic.trigger("n1", (), "done")
    assert logic.interrupt(Interrupt(3, (), "waits")) == []


def test_after_abort_an_action_only_reports_its_record():
    logic = action()
    logic.trigger("n1", (), "done")
    assert notes(logic.abort()) == ["mission.node.aborted"]
    assert kinds(logic.action_finished((), "cancelled", "aborted", 0.0, 1.0)) == ["Record"]
    assert kinds(action_after_abort()) == []


def action_after_abort():
    logic = action()
    logic.abort()
    return logic.trigger("n1", (), "done")


# -- If ------------------------------------------------------------------------------------------


def if_node(cond=GT) -> IfLogic:
    logic = node_logic(
        spec("if", cond=cond),
        (route("n6", "then"), route("n7", "else"), route("n9", "seq")),
        frozenset({"n1"}),
    )
    assert isinstance(logic, IfLogic)
    return logic


@pytest.mark.parametrize(("z", "taken", "other"), [(2.0, "n6", "n7"), (0.5, "n7", "n6")])
def test_if_waits_for_telemetry_then_takes_one_branch(z, taken, other):
    logic = if_node()
    fx = logic.trigger("n1", (), "done")
    assert [e for e in fx if isinstance(e, WatchTelemetry)] == [WatchTelemetry(("D1",))]
    assert emits(fx) == []
    fx = logic.telemetry("D1", values(z))
    out = dict((dst, status) for dst, _, status in emits(fx))
    assert out == {taken: "done", other: "skipped", "n9": "done"}
    assert any(isinstance(e, UnwatchTelemetry) for e in fx)
    assert "mission.condition" in notes(fx) and resolved(fx) == [((), "done", True)]


def test_if_keeps_waiting_while_a_property_has_no_value():
    logic = if_node()
    logic.trigger("n1", (), "done")
    assert emits(logic.telemetry("D1", values(None))) == []
    assert emits(logic.telemetry("D1", values(3.0)))


def test_if_on_a_constant_decides_at_once_without_watching():
    logic = if_node(["bool", False])
    fx = logic.trigger("n1", (), "done")
    assert not any(isinstance(e, WatchTelemetry) for e in fx)
    assert ("n7", (), "done") in emits(fx)


def test_interrupted_if_skips_every_branch():
    logic = node_logic(
        spec("if", cond=GT, scopes=(3,)),
        (route("n6", "then"), route("n7", "else")),
        frozenset({"n1"}),
    )
    logic.trigger("n1", (), "done")
    fx = logic.interrupt(Interrupt(3, (), "all"))
    assert {s for *_, s in emits(fx)} == {"skipped"} and progress(fx) == ["skipped"]
    assert emits(logic.telemetry("D1", values(5.0))) == []


# -- Wait / Pause ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kind", "still", "over"),
    [
        ("wait_until", 0.0, 2.0),
        ("pause_until", 0.0, 2.0),
        ("wait_while", 2.0, 0.0),
        ("pause_while", 2.0, 0.0),
    ],
)
def test_wait_hands_on_when_its_condition_lets_go(kind, still, over):
    logic = node_logic(spec(kind, cond=GT), (route("n8"),), frozenset({"n1"}))
    assert isinstance(logic, WaitLogic)
    fx = logic.trigger("n1", (), "done")
    assert progress(fx) == ["waiting"]
    assert [e.event.detail for e in fx if isinstance(e, Progress)] == ["D1.Z() > 1"]
    assert emits(logic.telemetry("D1", values(still))) == []
    fx = logic.telemetry("D1", values(over))
    assert emits(fx) == [("n8", (), "done")] and progress(fx) == ["ok"]


def test_wait_is_interrupted_by_a_loop_ending_mode_waits():
    logic = node_logic(
        spec("wait_until", cond=GT, loops=(3,), scopes=(3,)), (route("n8"),), frozenset({"n1"})
    )
    logic.trigger("n1", (0,), "done")
    fx = logic.interrupt(Interrupt(3, (0,), "waits"))
    assert emits(fx) == [("n8", (0,), "skipped")] and progress(fx) == ["skipped"]


def test_a_new_activation_decides_on_fresh_telemetry_not_cached_values():
    logic = node_logic(spec("wait_until", cond=GT, loops=(3,)), (route("n8"),), frozenset({"n1"}))
    logic.trigger("n1", (0,), "done")
    assert emits(logic.telemetry("D1", values(2.0)))  # decided: stops watching
    fx = logic.trigger("n1", (1,), "done")
    assert any(isinstance(e, WatchTelemetry) for e in fx) and emits(fx) == []


def test_abort_stops_waiting():
    logic = node_logic(spec("wait_until", cond=GT), (route("n8"),), frozenset({"n1"}))
    logic.trigger("n1", (), "done")
    assert kinds(logic.abort()) == ["UnwatchTelemetry"]
    assert emits(logic.telemetry("D1", values(5.0))) == []


# -- loops -----------------------------------------------------------------------------------------


def loop(kind="repeat_for", count=None, cond=None, **kw) -> LoopLogic:
    logic = node_logic(
        spec(kind, key="n3", count=count, cond=cond, **kw),
        (route("n4", "body"), route("n9", "exit")),
        frozenset({"n1"}),
        frozenset({"n4"}),
    )
    assert isinstance(logic, LoopLogic)
    return logic


def test_repeat_for_rearms_its_body_with_a_new_counter_each_time():
    logic = loop(count=3)
    bodies = []
    fx = logic.trigger("n1", (), "done")
    for i in range(3):
        bodies += emits(fx)
        fx = logic.trigger("n4", (i,), "done")  # the body's back arc
    assert bodies == [("n4", (0,), "done"), ("n4", (1,), "done"), ("n4", (2,), "done")]
    assert emits(fx) == [("n9", (), "done")] and resolved(fx) == [((), "done", True)]
    assert "mission.loop.exit" in notes(fx)


def test_back_arcs_that_come_before_their_iteration_are_taken_when_it_begins():
    """A restarted node's peers resend every back arc at once, before its replay began
    the loop: each is kept until its iteration begins, then ends it, in order."""
    logic = loop(count=3)
    assert emits(logic.trigger("n4", (1,), "done")) == []  # iteration 1's end, early
    assert emits(logic.trigger("n4", (0,), "done")) == []  # before the loop even began
    fx = logic.trigger("n1", (), "done")  # the loop begins: iterations 0 and 1 end at once
    assert emits(fx) == [("n4", (0,), "done"), ("n4", (1,), "done"), ("n4", (2,), "done")]
    assert resolved(fx) == []  # iteration 2 runs: its back arc has not come
    fx = logic.trigger("n4", (2,), "done")
    assert emits(fx) == [("n9", (), "done")] and resolved(fx) == [((), "done", True)]


def test_a_while_loops_early_back_arc_waits_for_the_conditions_go():
    logic = loop("repeat_while", cond=GT)
    logic.trigger("n1", (), "done")
    assert emits(logic.trigger("n4", (0,), "done")) == []  # the condition has not said go
    fx = logic.telemetry("D1", values(2.0))
    assert emits(fx) == [("n4", (0,), "done")]  # iteration 0 began, and its end was here
    assert any(isinstance(e, WatchTelemetry) for e in fx)  # asking for iteration 1
    assert emits(logic.telemetry("D1", values(0.0))) == [("n9", (), "done")]


def test_repeat_for_zero_goes_straight_to_exit():
    assert emits(loop(count=0).trigger("n1", (), "done")) == [("n9", (), "done")]


@pytest.mark.parametrize(
    ("kind", "go", "stop"), [("repeat_while", 2.0, 0.0), ("repeat_until", 0.0, 2.0)]
)
def test_repeat_while_until_ask_the_condition_before_each_iteration(kind, go, stop):
    logic = loop(kind, cond=GT)
    logic.trigger("n1", (), "done")
    assert emits(logic.telemetry("D1", values(go))) == [("n4", (0,), "done")]
    fx = logic.trigger("n4", (0,), "done")
    assert any(isinstance(e, WatchTelemetry) for e in fx)  # fresh values for the next decision
    assert emits(logic.telemetry("D1", values(go))) == [("n4", (1,), "done")]
    logic.trigger("n4", (1,), "done")
    assert emits(logic.telemetry("D1", values(stop))) == [("n9", (), "done")]


def test_loop_ending_during_body_interrupts_the_waits_of_that_iteration_once():
    logic = loop("repeat_until", cond=GT, interrupt_drones=("D1", "D2"))
    logic.trigger("n1", (), "done")
    logic.telemetry("D1", values(0.0))  # iteration 0 starts, the loop watches
    fx = logic.telemetry("D1", values(2.0))
    assert [e for e in fx if isinstance(e, Broadcast)] == [
        Broadcast(Interrupt(3, (0,), "waits"), ("D1", "D2"))
    ]
    assert logic.telemetry("D1", values(3.0)) == []
    fx = logic.trigger("n4", (0,), "skipped")
    assert any(isinstance(e, WatchTelemetry) for e in fx)
    assert emits(logic.telemetry("D1", values(3.0))) == [("n9", (), "done")]


def test_failed_body_fails_the_loop():
    logic = loop(count=5)
    logic.trigger("n1", (), "done")
    fx = logic.trigger("n4", (0,), "failed")
    assert emits(fx) == [("n9", (), "failed")] and resolved(fx) == [((), "failed", True)]


def test_skipped_loop_skips_its_exit_only():
    assert emits(loop(count=2).trigger("n1", (), "skipped")) == [("n9", (), "skipped")]


def test_a_back_arc_for_another_iteration_is_ignored():
    logic = loop(count=3)
    logic.trigger("n1", (), "done")
    assert emits(logic.trigger("n4", (1,), "done")) == []


def test_loop_interrupted_by_an_enclosing_do_leaves_skipped():
    logic = loop("repeat_while", cond=GT, scopes=(1,))
    logic.trigger("n1", (), "done")  # waits for its condition
    fx = logic.interrupt(Interrupt(1, (), "all"))
    assert emits(fx) == [("n9", (), "skipped")]


def test_loop_interrupted_while_its_body_runs_leaves_after_the_body():
    logic = loop(count=5, scopes=(1,))
    logic.trigger("n1", (), "done")
    logic.interrupt(Interrupt(1, (), "all"))
    assert emits(logic.trigger("n4", (0,), "skipped")) == [("n9", (), "skipped")]


# -- Do ------------------------------------------------------------------------------------------


def do(kind="do_while") -> DoLogic:
    logic = node_logic(
        spec(kind, key="n3", cond=GT, end=14, interrupt_drones=("D1", "D2")),
        (route("n5", "body"), route("n14", "begin")),
        frozenset({"n2"}),
    )
    assert isinstance(logic, DoLogic)
    return logic


def test_do_runs_body_then_interrupts_it_when_the_condition_stops_holding():
    logic = do()
    logic.trigger("n2", (), "done")
    fx = logic.telemetry("D1", values(2.0))
    assert emits(fx) == [("n5", (), "done"), ("n14", (), "done")]
    assert resolved(fx) == [((), "done", True)]
    assert logic.telemetry("D1", values(1.5)) == []  # still holds
    fx = logic.telemetry("D1", values(0.5))
    assert [e for e in fx if isinstance(e, Broadcast)] == [
        Broadcast(Interrupt(3, (), "all"), ("D1", "D2"))
    ]
    assert "mission.interrupt" in notes(fx) and any(isinstance(e, UnwatchTelemetry) for e in fx)


def test_do_whose_condition_fails_at_once_skips_body_and_stops_watching():
    logic = do("do_until")
    logic.trigger("n2", (), "done")
    fx = logic.telemetry("D1", values(2.0))
    assert emits(fx) == [("n5", (), "skipped"), ("n14", (), "done")]
    assert any(isinstance(e, UnwatchTelemetry) for e in fx)


def test_release_ends_the_watch_of_a_finished_body():
    logic = do()
    logic.trigger("n2", (), "done")
    logic.telemetry("D1", values(2.0))
    assert kinds(logic.release(())) == ["UnwatchTelemetry"]
    assert logic.telemetry("D1", values(0.0)) == []


def do_end() -> DoEndLogic:
    logic = node_logic(
        spec("end", key="n14", begin=3),
        (route("n7", "exit"), route("n8", "seq")),
        frozenset({"n3", "n5"}),
        begin_kind="do_while",
    )
    assert isinstance(logic, DoEndLogic)
    return logic


@pytest.mark.parametrize(
    ("begin", "body", "out"),
    [
        ("done", "done", {"n7": "skipped", "n8": "done"}),  # completed: no Exit
        ("done", "skipped", {"n7": "done", "n8": "done"}),  # interrupted: Exit runs
        ("done", "failed", {"n7": "failed", "n8": "failed"}),
        ("skipped", "skipped", {"n7": "skipped", "n8": "skipped"}),
    ],
)
def test_do_end_decides_whether_exit_runs(begin, body, out):
    logic = do_end()
    logic.trigger("n3", (), begin)
    fx = logic.trigger("n5", (), body)
    assert ReleaseBegin("n3", ()) in fx
    assert {dst: status for dst, _, status in emits(fx)} == out


# -- kinds and wiring ---------------------------------------------------------------------------


def test_every_program_kind_has_a_logic_class():
    from eamos.program.format import NODE_KINDS

    assert {k: logic_class(k).__name__ for k in NODE_KINDS} == {
        "init": "PassThrough",
        "fork": "PassThrough",
        "end": "PassThrough",
        "action": "ActionLogic",
        "if": "IfLogic",
        **dict.fromkeys(("wait_while", "wait_until", "pause_while", "pause_until"), "WaitLogic"),
        **dict.fromkeys(("repeat_while", "repeat_until", "repeat_for"), "LoopLogic"),
        **dict.fromkeys(("do_while", "do_until"), "DoLogic"),
        "try": "PassThrough",
        "whenever": "WheneverLogic",
        "abandon": "AbandonLogic",
    }
    assert logic_class("end", "do_until") is DoEndLogic
    with pytest.raises(ValueError, match="unknown node kind"):
        logic_class("goto")


def test_program_wiring_reads_routes_and_precondition_groups():
    compiled = compile_mission(
        "func SEQ_M() {\n RepeatFor(2, SEQ_B)\n D2.Land()\n}\nfunc SEQ_B() { D1.FlyByX(1) }",
        "t.go",
    )
    wiring = program_wiring(compiled.programs["D1"])
    begin = next(w for w in wiring.values() if w.spec.kind == "repeat_for")
    body = next(w for w in wiring.values() if w.spec.kind == "action")
    assert {r.kind for r in begin.routes} == {"body", "exit"}
    assert begin.loop == {body.spec.key} and body.spec.key not in begin.entry
    assert any(r.external and r.drone == "D2" for w in wiring.values() for r in w.routes)
    assert isinstance(body.logic(), ActionLogic)


def test_record_effect_carries_the_action_record():
    logic = action()
    logic.trigger("n1", (), "done")
    (record,) = [e for e in logic.action_finished((), "ok", "", 1.0, 2.0) if isinstance(e, Record)]
    assert record.record.result == "ok" and record.record.iteration == ()


@given(st.integers(min_value=0, max_value=12), st.sampled_from(["done", "skipped"]))
def test_repeat_for_runs_exactly_count_bodies_whatever_they_report(count, body_status):
    logic = loop(count=count)
    fx = logic.trigger("n1", (), "done")
    bodies: list[tuple[int, ...]] = []
    while True:
        out = emits(fx)
        bodies += [it for dst, it, _ in out if dst == "n4"]
        if any(dst == "n9" for dst, _, _ in out):
            break
        fx = logic.trigger("n4", bodies[-1], body_status)  # type: ignore[arg-type]
    assert bodies == [(i,) for i in range(count)]
    assert logic.loops == {}
