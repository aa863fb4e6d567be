"""The MAVLink reader thread survives a message it cannot fold into the vehicle's state.

Real MAVLink bytes over UDP from a pymavlink sender; the fault is injected where a
bug would raise (the state tracker's handler of one message kind): the reader logs
it once per message, counts it, and the messages after it still arrive.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Any

import pytest

from eamos.ground.vehicles import free_port
from eamos.hal.mavlink.link import MavlinkLink, load_mavutil
from eamos.hal.mavlink.state import StateTracker

from .mavlink_helpers import WAIT_S

pytestmark = pytest.mark.timeout(120)


def test_a_message_the_tracker_cannot_handle_does_not_stop_the_reader(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real = StateTracker._on_statustext

    def statustext(self: StateTracker, msg: Any, now: float, events: Any) -> None:
        text = msg.text.decode() if isinstance(msg.text, bytes) else msg.text
        if text.startswith("poison"):
            raise ValueError("a tracker's bug")
        real(self, msg, now, events)

    monkeypatch.setattr(StateTracker, "_on_statustext", statustext)
    port = free_port(socket.SOCK_DGRAM)
    events: list[tuple[str, dict[str, Any]]] = []
    seen = threading.Condition()

    def on_event(name: str, fields: dict[str, Any]) -> None:
        with seen:
            events.append((name, fields))
            seen.notify_all()

    link = MavlinkLink(
        f"udpin:127.0.0.1:{port}",
        source_system=245,
        source_component=191,
        system_id=None,
        component_id=1,
        heartbeat_timeout_s=3.0,
        on_event=on_event,
    )
    link.open(time.monotonic() + WAIT_S)
    mavutil = load_mavutil()
    vehicle = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=1, source_component=1
    )
    try:
        mav = vehicle.mav
        quad, px4 = mavutil.mavlink.MAV_TYPE_QUADROTOR, mavutil.mavlink.MAV_AUTOPILOT_PX4
        sent = 0

        def texts() -> tuple[int, list[str]]:
            """How many texts arrived, and the last 20 (what the state keeps)."""
            with link.cond:
                return link.state.statustext_serial, list(link.state.statustexts)

        deadline = time.monotonic() + WAIT_S
        while link.state.system_id is None and time.monotonic() < deadline:
            mav.heartbeat_send(quad, px4, 0, 0, 0)
            link.wait_for(lambda: link.state.system_id is not None, time.monotonic() + 0.2)
        assert link.state.system_id == 1
        for _round in range(3):
            mav.statustext_send(6, b"poison")
            for _ in range(20):
                mav.statustext_send(6, f"after {sent}".encode())
                sent += 1
            mav.heartbeat_send(quad, px4, 0, 0, 0)

            def arrived(n: int = sent) -> bool:
                return texts()[0] >= n

            assert link.wait_for(arrived, time.monotonic() + WAIT_S)
            assert texts() == (sent, [f"after {n}" for n in range(sent - 20, sent)])
        assert link.message_errors == 3
        with seen:
            errors = [f for name, f in events if name == "link.message_error"]
        assert len(errors) == 3 and errors[0]["message"] == "STATUSTEXT"
        assert "a tracker's bug" in errors[0]["error"]
    finally:
        vehicle.close()
        link.close()
