"""Whenever's node logic as pure transitions: rising edges, suspend/resume, release, Abandon."""

from __future__ import annotations

from eamos.actors.logic import (
    AbandonLogic,
    ActionLogic,
    Broadcast,
    CancelAction,
    Emit,
    Record,
    ReleaseBegin,
    Resolve,
    Route,
    StartAction,
    WatchTelemetry,
    WheneverEndLogic,
    WheneverLogic,
    logic_class,
    node_logic,
)
from eamos.actors.messages import Interrupt
from eamos.program.format import ProgramNode

LOW = ["<", ["prop", "D1", "Battery"], ["num", 25.0]]  # D1.Battery() < 25


def spec(kind: str, key: str = "n4", **kw) -> ProgramNode:
    return ProgramNode(key=key, meg=int(key[1:]), kind=kind, drone="D1", native=True, **kw)


def route(dst: str, kind: str = "seq", drone: str = "D1") -> Route:
    return Route(dst, drone, kind, drone != "D1")


def emits(effects) -> list[tuple[str, tuple[int, ...], str]]:
    return [(e.route.dst, e.iteration, e.status) for e in effects if isinstance(e, Emit)]


def resolved(effects) -> list[tuple[tuple[int, ...], str]]:
    return [(e.iteration, e.status) for e in effects if isinstance(e, Resolve)]


def broadcasts(effects) -> list[tuple[str, tuple[int, ...], tuple[str, ...]]]:
    return [
        (e.interrupt.mode, e.interrupt.iteration, e.drones)
        for e in effects
        if isinstance(e, Broadcast)
    ]


def battery(pct: float) -> dict:
    return {"Battery": pct}


def whenever() -> WheneverLogic:
    node = spec(
        "whenever",
        cond=LOW,
        end=12,
        interrupt_drones=("D1", "D2"),
        suspend_drones=("D1",),
    )
    routes = (route("n9", "body"), route("n12", "begin"), route("n6", "handler"))
    logic = node_logic(node, routes, frozenset({"n3"}), frozenset({"n7"}))
    assert isinstance(logic, WheneverLogic)
    return logic


def test_whenever_starts_the_block_and_fires_on_each_rising_edge() -> None:
    logic = whenever()
    fx = logic.trigger("n3", (), "done")
    assert emits(fx) == [("n9", (), "done")]  # the guarded statements start at once
    assert [e for e in fx if isinstance(e, WatchTelemetry)] == [WatchTelemetry(("D1",))]
    assert emits(logic.telemetry("D1", battery(50))) == []
    fx = logic.telemetry("D1", battery(24))
    assert broadcasts(fx) == [("suspend", (), ("D1",))]
    assert emits(fx) == [("n6", (0,), "done")]  # the Handler, first firing
    # Still true, or true again while the Handler runs: no second firing.
    assert emits(logic.telemetry("D1", battery(23))) == []
    logic.telemetry("D1", battery(30))
    assert emits(logic.telemetry("D1", battery(20))) == []
    fx = logic.trigger("n7", (0,), "done")  # the Handler ended
    assert broadcasts(fx) == [("resume", (), ("D1",))]
    assert resolved(fx) == []  # the block still runs
    logic.telemetry("D1", battery(30))
    fx = logic.telemetry("D1", battery(10))
    assert emits(fx) == [("n6", (1,), "done")]  # second firing, counter 1
    # The block ends while the Handler runs: begin is sent when the Handler ends.
    assert emits(logic.release(())) == []
    fx = logic.trigger("n7", (1,), "done")
    assert emits(fx) == [("n12", (), "done")]
    assert resolved(fx) == [((), "done")]
    assert emits(logic.telemetry("D1", battery(40))) == []


def test_a_condition_already_true_at_the_start_fires_and_release_ends_it() -> None:
    logic = whenever()
    logic.trigger("n3", (), "done")
    fx = logic.telemetry("D1", battery(5))
    assert emits(fx) == [("n6", (0,), "done")]
    logic.trigger("n7", (0,), "done")
    fx = logic.release(())
    assert emits(fx) == [("n12", (), "done")] and resolved(fx) == [((), "done")]


def test_a_skipped_whenever_skips_the_block_and_never_runs_the_handler() -> None:
    logic = whenever()
    fx = logic.trigger("n3", (), "skipped")
    assert emits(fx) == [("n9", (), "skipped"), ("n12", (), "skipped")]


def whenever_end() -> WheneverEndLogic:
    node = spec("end", key="n12", begin=4)
    logic = node_logic(
        node, (route("n13"),), frozenset({"n4", "n10", "n11"}), begin_kind="whenever"
    )
    assert isinstance(logic, WheneverEndLogic)
    return logic


def test_whenever_end_releases_its_begin_when_the_block_ended() -> None:
    assert logic_class("end", "whenever") is WheneverEndLogic
    logic = whenever_end()
    assert [e for e in logic.trigger("n10", (), "done") if isinstance(e, ReleaseBegin)] == []
    fx = logic.trigger("n11", (), "skipped")
    assert [e for e in fx if isinstance(e, ReleaseBegin)] == [ReleaseBegin("n4", ())]
    fx = logic.trigger("n4", (), "done")
    assert emits(fx) == [("n13", (), "done")]  # an abandoned (skipped) block ends normally


def test_whenever_end_hands_a_failure_in_the_block_on() -> None:
    logic = whenever_end()
    logic.trigger("n10", (), "failed")
    logic.trigger("n11", (), "failed")
    assert emits(logic.trigger("n4", (), "done")) == [("n13", (), "failed")]


def guarded(action: str = "FlyByX", args: tuple[float, ...] = (20.0,)) -> ActionLogic:
    node = spec("action", key="n9", action=action, args=args, scopes=(4,), suspendable=True)
    logic = node_logic(node, (route("n10"),), frozenset({"n4"}))
    assert isinstance(logic, ActionLogic)
    return logic


def test_a_suspended_relative_move_is_reissued_for_what_is_left() -> None:
    logic = guarded()
    fx = logic.trigger("n4", (), "done")
    assert [e for e in fx if isinstance(e, WatchTelemetry)] == [WatchTelemetry(("D1",))]
    assert [e for e in fx if isinstance(e, StartAction)] == [StartAction((), "FlyByX", (20.0,))]
    logic.telemetry("D1", {"X": 2.0})  # where it started
    logic.telemetry("D1", {"X": 9.5})
    fx = logic.interrupt(Interrupt(4, (), "suspend"))
    assert [e for e in fx if isinstance(e, CancelAction)] == [CancelAction(())]
    fx = logic.action_finished((), "cancelled", "cancelled", 1.0, 4.0)
    records = [e.record for e in fx if isinstance(e, Record)]
    assert [(r.result, r.reason) for r in records] == [
        ("cancelled", "suspended: a Whenever handler runs")
    ]
    assert emits(fx) == [] and resolved(fx) == []  # not finished: it waits for the resume
    logic.telemetry("D1", {"X": 7.0})  # the Handler moved it back a little
    fx = logic.interrupt(Interrupt(4, (), "resume"))
    assert [e for e in fx if isinstance(e, StartAction)] == [StartAction((), "FlyByX", (15.0,))]
    fx = logic.action_finished((), "ok", "", 5.0, 9.0)
    assert [e.record.args for e in fx if isinstance(e, Record)] == [(15.0,)]
    assert emits(fx) == [("n10", (), "done")]


def test_a_trigger_while_suspended_waits_and_abandon_skips_it() -> None:
    logic = guarded("Land", ())
    logic.interrupt(Interrupt(4, (), "suspend"))
    fx = logic.trigger("n4", (), "done")
    assert not [e for e in fx if isinstance(e, StartAction)]
    fx = logic.interrupt(Interrupt(4, (), "all"))  # Abandon()
    assert emits(fx) == [("n10", (), "skipped")] and resolved(fx) == [((), "skipped")]
    assert not [
        e for e in logic.interrupt(Interrupt(4, (), "resume")) if isinstance(e, StartAction)
    ]


def test_an_action_that_ends_before_the_cancel_is_not_suspended() -> None:
    logic = guarded("PauseFor", (3.0,))
    logic.trigger("n4", (), "done")
    logic.interrupt(Interrupt(4, (), "suspend"))
    fx = logic.action_finished((), "ok", "", 0.0, 3.0)
    assert emits(fx) == [("n10", (), "done")]
    assert not [
        e for e in logic.interrupt(Interrupt(4, (), "resume")) if isinstance(e, StartAction)
    ]


def test_a_handler_action_refused_busy_is_reissued_at_the_next_sample() -> None:
    node = spec(
        "action", key="n6", action="FlyToXYZ", args=(0.0, 0.0, 2.0), loops=(4,), in_handler=True
    )
    logic = node_logic(node, (route("n7"),), frozenset({"n4"}))
    logic.trigger("n4", (0,), "done")
    fx = logic.action_finished((0,), "failed", "busy", 1.0, 1.0)
    assert emits(fx) == [] and [e for e in fx if isinstance(e, WatchTelemetry)]
    fx = logic.telemetry("D1", {"X": 0.0})
    assert [e for e in fx if isinstance(e, StartAction)] == [
        StartAction((0,), "FlyToXYZ", (0.0, 0.0, 2.0))
    ]
    assert emits(logic.action_finished((0,), "ok", "", 1.1, 5.0)) == [("n7", (0,), "done")]


def test_abandon_interrupts_the_guarded_block_of_its_whenever() -> None:
    node = spec("abandon", key="n7", begin=4, loops=(2, 4), interrupt_drones=("D1", "D2"))
    logic = node_logic(node, (route("n4", "loop"),), frozenset({"n6"}))
    assert isinstance(logic, AbandonLogic)
    fx = logic.trigger("n6", (3, 1), "done")
    assert broadcasts(fx) == [("all", (3,), ("D1", "D2"))]
    assert emits(fx) == [("n4", (3, 1), "done")]
