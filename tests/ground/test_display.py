"""One event formatter for every display: ``eamos run``, ``eamos start`` and ``eamos-node``."""

from __future__ import annotations

import io
import sys
import time

from eamos.ground import DroneView, LiveDisplay, PlainDisplay, format_event
from eamos.ground.display import NO_LIVE_TABLE, live_table_installed, make_display
from eamos.net import wire
from eamos.net.link import PeerStatus

AT = time.mktime((2026, 1, 1, 12, 34, 56, 0, 0, -1))


def progress(state: str, detail: dict | None = None) -> wire.Progress:
    return wire.Progress(
        mission="m", sender="Drone1", state=state, node="n3", action="FlyByX(2)",
        detail=detail or {},
    )  # fmt: skip


def test_progress_ready_resolved_and_links_each_give_one_line() -> None:
    assert (
        format_event("Drone1", progress("running"), AT) == "[12:34:56]   Drone1 running   FlyByX(2)"
    )
    assert (
        format_event("Drone1", progress("failed", {"detail": "rejected"}), AT)
        == "[12:34:56]   Drone1 failed    FlyByX(2)  (rejected)"
    )
    assert format_event(
        "Drone1", wire.Ready(mission="m", sender="Drone1", program_checksum="c"), AT
    ) == ("[12:34:56]   Drone1 ready")
    assert format_event("GCS", wire.Resolved(mission="m", sender="GCS"), AT) == (
        "[12:34:56]      GCS resolved"
    )
    assert format_event("Drone1", PeerStatus("Drone1", "lost", 3.04, 1), AT) == (
        "[12:34:56]   Drone1 link lost (silent 3.0 s)"
    )
    assert format_event("Drone1", PeerStatus("Drone1", "back", 7.5, 2), AT) == (
        "[12:34:56]   Drone1 link back (silent 7.5 s)"
    )
    assert format_event("Drone1", PeerStatus("Drone1", "left", 0.0, 3), AT) == (
        "[12:34:56]   Drone1 link left"
    )


def test_messages_nobody_needs_to_see_give_no_line() -> None:
    assert format_event("Drone1", progress("queued"), AT) is None
    sample = wire.Report(mission="m", sender="Drone1", report={"ok": True})
    assert format_event("Drone1", sample, AT) is None


def test_plain_and_live_displays_both_print_peer_status() -> None:
    lost = PeerStatus("Drone2", "lost", 3.0, 1)
    out = io.StringIO()
    PlainDisplay(out, clock=lambda: AT).event("Drone2", DroneView("Drone2"), lost)
    assert out.getvalue() == "[12:34:56]   Drone2 link lost (silent 3.0 s)\n"
    said: list[str] = []
    live = LiveDisplay(["Drone2"], clock=lambda: AT)
    live.say = said.append  # type: ignore[method-assign, assignment]
    live.event("Drone2", DroneView("Drone2"), lost)
    live.event("Drone2", DroneView("Drone2"), progress("running"))  # shown in the table
    assert said == ["[12:34:56]   Drone2 link lost (silent 3.0 s)"]


# -- every state change, in order (issue 14) ------------------------------------------------


def event(sender: str, state: str, action: str, at: float, **detail: object) -> wire.Progress:
    return wire.Progress(
        mission="m", sender=sender, state=state, node="n3", action=action,
        detail={"at": at, **detail},
    )  # fmt: skip


def test_a_batch_carries_every_change_in_order_and_unpacks_into_them() -> None:
    from eamos.net.progress import progress_batch, progress_events

    changes = [
        ("running", "n3", "Arm()", {"at": AT}),
        ("ok", "n3", "Arm()", {"at": AT + 0.01}),
        ("running", "n4", "Takeoff(2)", {"at": AT + 0.02}),
    ]
    batch = progress_batch("m", "Drone1", changes)
    back = wire.decode(wire.encode(batch))
    assert isinstance(back, wire.Progress)
    events = progress_events(back)
    assert [(e.state, e.node, e.action, e.detail) for e in events] == [
        (s, n, a, dict(d)) for s, n, a, d in changes
    ]
    # A peer's malformed entries are left out, the rest kept.
    forged = wire.Progress(
        mission="m", sender="Drone1", state="ok", node="n5", action="Land()",
        detail={"earlier": [["ok", "n4", "Takeoff(2)", {}], "junk", [1, 2, 3, 4]]},
    )  # fmt: skip
    assert [e.action for e in progress_events(forged)] == ["Takeoff(2)", "Land()"]


def test_lines_come_out_in_the_order_things_happened_not_as_they_arrived() -> None:
    """A leader's "ok" arriving after its follower's "running" is still printed first.

    (One drone's lines arrive in the order it sent them: tests/ground/test_display_order.py.)
    """
    out = io.StringIO()
    view = DroneView("x")
    with PlainDisplay(out) as display:
        display.event("Drone2", view, event("Drone2", "running", "FlyByX(1)", AT + 0.2))
        display.event("Drone1", view, event("Drone1", "running", "Arm()", AT))
        display.event("Drone1", view, event("Drone1", "ok", "Takeoff(2)", AT + 0.1))
    lines = out.getvalue().splitlines()
    assert [line.split(None, 2)[2] for line in lines] == [
        "running   Arm()",
        "ok        Takeoff(2)",
        "running   FlyByX(1)",
    ]


def test_waits_and_decisions_say_what_they_wait_for_and_which_way() -> None:
    wait = event("D3", "waiting", "WaitUntil", AT, detail="D1.X() > 4")
    assert format_event("D3", wait, AT).endswith("waiting   WaitUntil  (D1.X() > 4)")  # type: ignore[union-attr]
    decided = event(
        "D1", "decided", "If D1.Battery() > 30", AT, detail="else: D1.Battery() > 30 is false"
    )
    assert format_event("D1", decided, AT).endswith(  # type: ignore[union-attr]
        "decided   If D1.Battery() > 30  (else: D1.Battery() > 30 is false)"
    )


def test_a_quiet_spell_gets_a_line_saying_what_every_drone_does() -> None:
    from eamos.ground.display import QUIET_S, quiet_line

    a, b = DroneView("Drone1"), DroneView("Drone2")
    a.state, a.action = "waiting", "WaitUntil D2.Z() > 3"
    a.events.append({"t": AT - 42})
    b.state, b.action = "running", "FlyByZ(5)"
    line = quiet_line({"Drone1": a, "Drone2": b}, AT, QUIET_S)
    assert line == (
        "[12:34:56] no change for 10 s: Drone1 waiting WaitUntil D2.Z() > 3 for 42 s; "
        "Drone2 running FlyByZ(5)"
    )


def test_the_station_hands_on_every_change_of_a_batch() -> None:
    from eamos.ground import GroundStation
    from eamos.net.progress import progress_batch

    seen: list[tuple[str, str, str]] = []
    station = GroundStation(
        ["Drone1"],
        "m",
        on_change=lambda name, view, msg: seen.append((name, msg.state, msg.action)),
    )
    batch = progress_batch(
        "m",
        "Drone1",
        [
            ("running", "n3", "Arm()", {"at": AT, "finished": 0}),
            ("ok", "n3", "Arm()", {"at": AT + 0.01, "finished": 1}),
            ("running", "n4", "Takeoff(2)", {"at": AT + 0.02, "finished": 1}),
        ],
    )
    station.handle(batch)
    assert seen == [
        ("Drone1", "running", "Arm()"),
        ("Drone1", "ok", "Arm()"),
        ("Drone1", "running", "Takeoff(2)"),
    ]
    view = station.snapshot()["Drone1"]
    assert (view.state, view.action, view.done_actions) == ("running", "Takeoff(2)", 1)
    assert [e["state"] for e in view.events] == ["running", "ok", "running"]


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_terminal_without_rich_gets_plain_lines_and_is_told_once(monkeypatch) -> None:
    # rich is the `live` extra: a drone's node need not load it (structlog imports rich
    # whenever it is installed).  Without it, a terminal gets plain lines and one hint.
    terminal = _Terminal()
    monkeypatch.setattr(sys, "stdout", terminal)
    shown = make_display(None, ["Drone1"], installed=lambda: False)
    assert isinstance(shown, PlainDisplay)
    assert terminal.getvalue() == NO_LIVE_TABLE + "\n"
    assert isinstance(make_display(None, ["Drone1"], installed=lambda: True), LiveDisplay)
    # Not a terminal (a pipe, a log file): plain lines, no hint; --plain: the same.
    pipe = io.StringIO()
    monkeypatch.setattr(sys, "stdout", pipe)
    assert isinstance(make_display(None, ["Drone1"], installed=lambda: False), PlainDisplay)
    assert isinstance(make_display(False, ["Drone1"], installed=lambda: True), PlainDisplay)
    assert pipe.getvalue() == ""
    assert live_table_installed()  # the test extra installs it
