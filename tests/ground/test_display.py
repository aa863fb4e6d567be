"""One event formatter for every display: ``eamos run``, ``eamos start`` and ``eamos-node``."""

from __future__ import annotations

import io
import time

from eamos.ground import DroneView, LiveDisplay, PlainDisplay, format_event
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
