"""Try's node logic as pure transitions: a failing action inside Body, and the Try's end."""

from __future__ import annotations

from eamos.actors.logic import (
    ActionLogic,
    Broadcast,
    CancelAction,
    Emit,
    Progress,
    Record,
    Resolve,
    Route,
    StartAction,
    TryEndLogic,
    logic_class,
    node_logic,
)
from eamos.actors.messages import Interrupt
from eamos.program.format import ProgramNode


def spec(kind: str, key: str = "n5", **kw) -> ProgramNode:
    return ProgramNode(key=key, meg=int(key[1:]), kind=kind, drone="D1", native=True, **kw)


def route(dst: str, kind: str = "seq", drone: str = "D1") -> Route:
    return Route(dst, drone, kind, drone != "D1")


def emits(effects) -> list[tuple[str, tuple[int, ...], str]]:
    return [(e.route.dst, e.iteration, e.status) for e in effects if isinstance(e, Emit)]


def resolved(effects) -> list[tuple[tuple[int, ...], str, bool]]:
    return [(e.iteration, e.status, e.top_level) for e in effects if isinstance(e, Resolve)]


def caught_action(**kw) -> ActionLogic:
    """An action in a loop (n4) in a Try (n3, line 12) in a loop (n2): the Try's activation
    is the first counter of the action's."""
    node = spec(
        "action",
        action="FlyByZ",
        args=(-10.0,),
        loops=(2, 4),
        scopes=(2, 3, 4),
        catch=3,
        catch_loops=1,
        catch_drones=("D1", "D2"),
        catch_line=12,
        **kw,
    )
    logic = node_logic(node, (route("n6"), route("n20", drone="D2")), frozenset({"n4"}))
    assert isinstance(logic, ActionLogic)
    return logic


def test_a_failed_action_in_a_try_interrupts_body_and_hands_failed_on() -> None:
    logic = caught_action()
    assert [type(e) for e in logic.trigger("n4", (1, 0), "done") if isinstance(e, StartAction)]
    fx = logic.action_finished((1, 0), "failed", "target below ground", 3.0, 3.0)
    records = [e.record for e in fx if isinstance(e, Record)]
    assert [(r.result, r.reason) for r in records] == [
        ("caught", "target below ground; caught by the Try at line 12")
    ]
    # The Try's activation is the prefix of the loops outside it: iteration (1,).
    broadcasts = [e for e in fx if isinstance(e, Broadcast)]
    assert broadcasts == [Broadcast(Interrupt(3, (1,), "all"), ("D1", "D2"))]
    # The failure flows on (to the Try's end, through Body), but the node is not "blocked".
    assert emits(fx) == [("n6", (1, 0), "failed"), ("n20", (1, 0), "failed")]
    assert resolved(fx) == [((1, 0), "skipped", False)]
    # The interrupt comes back to it too: nothing runs, nothing more is sent.
    assert emits(logic.interrupt(Interrupt(3, (1,), "all"))) == []


def test_outside_a_try_a_failure_stays_a_failure() -> None:
    logic = node_logic(spec("action", action="Land"), (route("n6"),), frozenset({"n4"}))
    logic.trigger("n4", (), "done")
    fx = logic.action_finished((), "failed", "rejected by vehicle", 1.0, 1.0)
    assert [e.record.result for e in fx if isinstance(e, Record)] == ["failed"]
    assert not [e for e in fx if isinstance(e, Broadcast)]
    assert resolved(fx) == [((), "failed", True)]


def test_a_running_action_of_body_is_cancelled_by_the_try_interrupt() -> None:
    logic = caught_action()
    logic.trigger("n4", (0, 0), "done")
    fx = logic.interrupt(Interrupt(3, (0,), "all"))
    assert [e for e in fx if isinstance(e, CancelAction)] == [CancelAction((0, 0))]
    fx = logic.action_finished((0, 0), "cancelled", "cancelled", 1.0, 2.0)
    assert emits(fx) == [("n6", (0, 0), "skipped"), ("n20", (0, 0), "skipped")]
    # Another iteration of the loop around the Try is not touched.
    logic.trigger("n4", (1, 0), "done")
    assert not [
        e for e in logic.interrupt(Interrupt(3, (0,), "all")) if isinstance(e, CancelAction)
    ]


def test_a_node_blocked_inside_body_shows_skipped_not_blocked() -> None:
    logic = caught_action()
    fx = logic.trigger("n4", (0, 0), "failed")
    assert emits(fx)[0] == ("n6", (0, 0), "failed")
    assert [e.event.state for e in fx if isinstance(e, Progress)] == ["skipped"]
    assert resolved(fx) == [((0, 0), "skipped", False)]


def try_end() -> TryEndLogic:
    node = spec("end", key="n9", begin=3, line=12)
    routes = (route("n10", "exit"), route("n11", "exit", drone="D2"), route("n12"))
    logic = node_logic(node, routes, frozenset({"n3", "n6", "n7"}), begin_kind="try")
    assert isinstance(logic, TryEndLogic)
    return logic


def test_try_end_runs_on_failure_only_when_body_failed() -> None:
    assert logic_class("end", "try") is TryEndLogic
    logic = try_end()
    logic.trigger("n3", (), "done")
    logic.trigger("n6", (), "failed")
    fx = logic.trigger("n7", (), "skipped")
    assert emits(fx) == [("n10", (), "done"), ("n11", (), "done"), ("n12", (), "done")]
    assert resolved(fx) == [((), "done", True)]
    assert [e.event.detail for e in fx if isinstance(e, Progress)] == [
        "Body failed: the failure is caught, OnFailure runs"
    ]


def test_try_end_skips_on_failure_when_body_completed() -> None:
    logic = try_end()
    for src in ("n3", "n6"):
        logic.trigger(src, (), "done")
    fx = logic.trigger("n7", (), "done")
    assert emits(fx) == [("n10", (), "skipped"), ("n11", (), "skipped"), ("n12", (), "done")]
    assert resolved(fx) == [((), "done", True)]


def test_try_end_hands_on_a_failure_from_before_the_try() -> None:
    logic = try_end()
    logic.trigger("n3", (), "failed")
    logic.trigger("n6", (), "failed")
    fx = logic.trigger("n7", (), "failed")
    assert {s for _, _, s in emits(fx)} == {"failed"}
    assert resolved(fx) == [((), "failed", True)]


def test_try_end_of_a_skipped_try_skips_everything() -> None:
    logic = try_end()
    for src in ("n3", "n6", "n7"):
        fx = logic.trigger(src, (), "skipped")
    assert {s for _, _, s in emits(fx)} == {"skipped"}


def test_a_lost_peer_inside_a_try_is_a_caught_failure() -> None:
    node = spec(
        "action",
        key="n8",
        action="Land",
        scopes=(3,),
        catch=3,
        catch_drones=("D1", "D2"),
        catch_line=12,
    )
    logic = node_logic(node, (route("n9"),), frozenset({"n6", "n20"}))
    logic.trigger("n6", (), "done")  # D1's own predecessor; n20 is on the lost drone
    fx = logic.peer_lost(frozenset({"n20", "n21"}))
    assert emits(fx) == [("n9", (), "failed")]  # on to the Try's end, which catches it
    assert resolved(fx) == [((), "skipped", True)]
    assert [e for e in fx if isinstance(e, Broadcast)] == [
        Broadcast(Interrupt(3, (), "all"), ("D1", "D2"))
    ]
    assert not [e for e in fx if isinstance(e, StartAction)]
    assert logic.peer_lost(frozenset({"n20"})) == []  # once


def test_a_lost_peer_outside_a_try_changes_nothing_here() -> None:
    logic = node_logic(spec("action", key="n8", action="Land"), (route("n9"),), frozenset({"n20"}))
    assert logic.peer_lost(frozenset({"n20"})) == []


def test_a_lost_peer_inside_a_try_before_any_trigger_arrived() -> None:
    node = spec("end", key="n8", scopes=(3,), catch=3, catch_drones=("D2",))
    logic = node_logic(node, (route("n9"),), frozenset({"n20"}))
    fx = logic.peer_lost(frozenset({"n20"}))
    assert emits(fx) == [("n9", (), "failed")]
