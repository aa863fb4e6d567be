"""The plain display keeps each drone's lines in the order the drone sent them.

Observed once: ``Drone2 link left`` printed before Drone2's last ``ok Land()`` /
``ok Disarm()``.  A drone's messages reach the ground station in the order it
sent them, but the display orders lines by time: a progress line by the drone's
clock, a link change or ``resolved`` by its arrival (the ground station's clock),
and what was still held when the run ended was printed after a line that
arrived while the display closed.
"""

from __future__ import annotations

import io
import threading
import time

from eamos.ground import DroneView, PlainDisplay
from eamos.ground.display import HeldLines
from eamos.net import wire
from eamos.net.link import PeerStatus

AT = time.mktime((2026, 1, 1, 12, 34, 56, 0, 0, -1))


def done(sender: str, action: str, at: float) -> wire.Progress:
    return wire.Progress(
        mission="m", sender=sender, state="ok", node="n9", action=action, detail={"at": at}
    )


def words(text: str) -> list[str]:
    """Each line without its time stamp."""
    return [line.split(None, 1)[1] for line in text.splitlines()]


def test_lines_are_held_then_let_out_earliest_event_first() -> None:
    held = HeldLines(hold_s=0.25)
    held.add(AT + 0.2, "b", now=10.0)
    held.add(AT + 0.1, "a", now=10.5)
    assert len(held) == 2
    # "b" is due at 10.25, but "a" happened earlier and is held until 10.75: nothing yet.
    assert held.next_due() == 10.75
    assert held.due(10.5) == []
    assert held.due(10.75) == ["a", "b"]
    assert held.next_due() is None and len(held) == 0
    held.add(AT + 0.3, "c", now=11.0)
    assert held.due(11.0) == [] and held.due(11.25) == ["c"]


def test_a_drones_lines_keep_the_order_it_sent_them_whatever_the_clocks_say() -> None:
    """Drone2's clock runs 2 s ahead of the ground station's: its goodbye still comes last."""
    held = HeldLines(hold_s=0.3)
    held.add(AT + 2.0, "Drone2 ok Disarm()", now=0.0, who="Drone2")
    held.add(AT + 0.1, "Drone2 resolved", now=0.01, who="Drone2")  # arrival, ground clock
    held.add(AT + 0.2, "Drone2 link left", now=0.02, who="Drone2")
    held.add(AT + 0.15, "Drone1 link left", now=0.02, who="Drone1")
    held.add(AT + 0.05, "all done", now=0.02)  # nobody's: its own time only
    assert held.due(1.0) == [
        "all done",
        "Drone1 link left",
        "Drone2 ok Disarm()",
        "Drone2 resolved",
        "Drone2 link left",
    ]


def test_what_is_held_at_the_end_comes_out_in_order() -> None:
    held = HeldLines()
    held.add(AT + 0.1, "b", now=0.0, who="D")
    held.add(AT, "a", now=0.0)
    assert held.drain() == ["a", "b"]
    assert held.drain() == [] and held.next_due() is None


def test_a_drones_goodbye_prints_after_its_last_progress_when_its_clock_runs_ahead() -> None:
    out = io.StringIO()
    view = DroneView("Drone2")
    with PlainDisplay(out, clock=lambda: AT) as display:
        display.event("Drone2", view, done("Drone2", "Land()", AT + 1.9))
        display.event("Drone2", view, done("Drone2", "Disarm()", AT + 2.0))
        display.event("Drone2", view, wire.Resolved(mission="m", sender="Drone2"))
        display.event("Drone2", view, PeerStatus("Drone2", "left", 0.0, 1))
    assert words(out.getvalue()) == [
        "Drone2 ok        Land()",
        "Drone2 ok        Disarm()",
        "Drone2 resolved",
        "Drone2 link left",
    ]


def test_a_goodbye_arriving_while_the_display_closes_prints_after_the_held_lines() -> None:
    """The run ends as the last report arrives; the drone's goodbye follows at once.

    The goodbye is delivered right when the display closes (here: while it waits
    for its printer thread to end); the progress lines still held must not come
    out after it.
    """
    out = io.StringIO()
    view = DroneView("Drone2")
    display = PlainDisplay(out)
    display.__enter__()
    started = display._printer
    assert started is not None
    printer: threading.Thread = started

    class Closing:
        """The printer thread, with the goodbye arriving while the display waits for it."""

        def join(self) -> None:
            printer.join()
            display.event("Drone2", view, PeerStatus("Drone2", "left", 0.0, 1))

    display._printer = Closing()  # type: ignore[assignment]
    display.event("Drone2", view, done("Drone2", "Disarm()", time.time()))
    display.__exit__(None, None, None)
    assert words(out.getvalue()) == ["Drone2 ok        Disarm()", "Drone2 link left"]
