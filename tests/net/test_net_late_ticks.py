"""A participant whose own loop stalls does not take the stall for its peers' silence.

Pure: one :class:`ReliableSession` driven with a fake clock.  Its timer called
on time, a silent peer is lost after ``peer_timeout_s``; called late (a busy
machine), the lateness is credited to every peer and counted.
"""

from __future__ import annotations

from typing import Any

from eamos.net import wire
from eamos.net.effects import PeerChanged
from eamos.net.session import LATE_TICK_S, ReliableSession

from .session_helpers import FAST, MISSION


def heartbeat_from(peer: str, incarnation: int = 5) -> wire.Heartbeat:
    return wire.Heartbeat(MISSION, peer, {}, 0, incarnation=incarnation)


def lost_events(actions: list[Any]) -> list[str]:
    return [a.status.state for a in actions if isinstance(a, PeerChanged)]


def session_hearing_b() -> tuple[ReliableSession, float]:
    s = ReliableSession("A", MISSION, FAST, incarnation=1)
    s.add_peers(["B"])
    s.on_receive(heartbeat_from("B"), 0.0)
    _, due = s.on_tick(0.0)
    return s, due


def test_a_peer_silent_while_the_timer_runs_on_time_is_lost() -> None:
    s, due = session_hearing_b()
    now, events = 0.0, list[str]()
    while now < 2 * FAST.peer_timeout_s and not events:
        now = due  # every call exactly when asked
        actions, due = s.on_tick(now)
        events = lost_events(actions)
    assert events == ["lost"]
    assert FAST.peer_timeout_s < now <= FAST.peer_timeout_s + FAST.heartbeat_s + 1e-3
    assert s.counters.late_ticks == 0


def test_a_stalled_timer_does_not_make_a_peer_lost() -> None:
    s, due = session_hearing_b()
    stall = 5 * FAST.peer_timeout_s
    actions, due = s.on_tick(due + stall)  # this participant was frozen for the stall
    assert lost_events(actions) == []
    assert s.counters.late_ticks == 1 and s.counters.stalled_s >= stall
    # B is heard again once the loop runs (its heartbeats waited in the socket).
    s.on_receive(heartbeat_from("B"), due)
    assert s.peer_stats()["B"]["state"] == "up"


def test_a_stall_credits_only_its_own_length() -> None:
    s, due = session_hearing_b()
    late = due + LATE_TICK_S * 2
    actions, due = s.on_tick(late)
    assert lost_events(actions) == [] and s.counters.late_ticks == 1
    # Silent from then on, with the timer on time: lost about peer_timeout_s after
    # the last heartbeat plus the stall, not later.
    now, events = late, list[str]()
    while not events:
        now = due
        actions, due = s.on_tick(now)
        events = lost_events(actions)
    assert events == ["lost"]
    assert now <= FAST.peer_timeout_s + 2 * LATE_TICK_S + FAST.heartbeat_s + 1e-3


def test_a_call_slightly_late_is_jitter_not_a_stall() -> None:
    s, due = session_hearing_b()
    s.on_tick(due + LATE_TICK_S / 2)
    assert s.counters.late_ticks == 0


def retransmitted(actions: list[Any]) -> list[wire.Trigger]:
    return [a.message for a in actions if isinstance(getattr(a, "message", None), wire.Trigger)]


def test_a_stalled_timer_waits_before_resending_what_may_have_been_acknowledged() -> None:
    s, _ = session_hearing_b()
    sent = s.on_send(wire.Trigger(MISSION, "A", "B", "a", "b", (0,), "done"), 0.0)
    assert retransmitted(sent)  # the first transmission
    _, due = s.on_tick(0.0)
    # Frozen past the retransmission timeout: this late call resends nothing yet ...
    late = due + 10 * FAST.rto_max_s
    actions, due = s.on_tick(late)
    assert retransmitted(actions) == [] and s.counters.retransmissions == 0
    assert due >= late + LATE_TICK_S - 1e-9
    # ... and, still unacknowledged once the loop runs on time, it is resent.
    now = late
    while not s.counters.retransmissions:
        assert now < late + 2 * FAST.rto_max_s
        now = due
        actions, due = s.on_tick(now)
    assert [m.iteration for m in retransmitted(actions)] == [(0,)]
