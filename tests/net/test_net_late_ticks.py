"""A participant whose own loop stalls does not take the stall for its peers' silence.

Pure: one :class:`ReliableSession` driven with a fake clock.  Its timer called
on time, a silent peer is lost after ``peer_timeout_s``; called late (a busy
machine), the lateness is credited to every peer and counted, and the deadlines
grow by twice the largest lateness of the last 30 s (bounded): a peer on a
machine as busy is as late.
"""

from __future__ import annotations

from typing import Any

import pytest

from eamos.net import wire
from eamos.net.effects import PeerChanged, TelemetryStale
from eamos.net.liveness import LATENESS_FACTOR, LATENESS_WINDOW_S, MAX_EXTENSION, Lateness
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
    # ... but the deadline allows for a peer as late as this loop was.
    margin = LATENESS_FACTOR * 2 * LATE_TICK_S
    assert now > FAST.peer_timeout_s + 2 * LATE_TICK_S + margin
    assert now <= FAST.peer_timeout_s + 2 * LATE_TICK_S + margin + FAST.heartbeat_s + 1e-3


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


def first_resend_at(late_by: float) -> float:
    """A trigger to B, never acknowledged (B heard all along), the timer called ``late_by``
    after each time it asks: when it is first resent."""
    s, _ = session_hearing_b()
    s.on_send(wire.Trigger(MISSION, "A", "B", "a", "b", (0,), "done"), 0.0)
    _, due = s.on_tick(0.0)
    while True:
        now = due + late_by
        s.on_receive(heartbeat_from("B"), now)  # B is up: only the ack is missing
        actions, due = s.on_tick(now)
        if retransmitted(actions):
            assert s.counters.late_ticks == 0  # late, but never a stall
            return now
        assert now < 10 * FAST.rto_max_s


def test_a_timer_running_late_gives_the_acknowledgement_as_much_longer() -> None:
    on_time = first_resend_at(0.0)
    assert on_time == pytest.approx(FAST.rto_initial_s)
    # A machine this late acknowledges as late: the timeout waits twice the lateness more.
    late = 0.8 * LATE_TICK_S
    resent = first_resend_at(late)
    grace = LATENESS_FACTOR * late
    assert FAST.rto_initial_s + grace <= resent <= FAST.rto_initial_s + grace + late + 1e-9


def silent_until_lost(s: ReliableSession, due: float, late_by: float) -> float:
    """Call the timer ``late_by`` after each time it asks, until B is lost: when."""
    start = due
    while True:
        now = due + late_by
        actions, due = s.on_tick(now)
        if lost_events(actions):
            return now
        assert now - start < 100 * FAST.peer_timeout_s


def test_a_timer_running_late_gives_a_silent_peer_as_much_longer() -> None:
    # Late by less than a stall: nothing is credited, yet the deadline grows with it.
    late = 0.8 * LATE_TICK_S
    s, due = session_hearing_b()
    lost_at = silent_until_lost(s, due, late)
    assert s.counters.late_ticks == 0
    timeout = FAST.peer_timeout_s + LATENESS_FACTOR * late
    assert timeout < lost_at <= timeout + FAST.heartbeat_s + late + 1e-3
    # On time, the same peer is lost at peer_timeout_s (the first test): load is not silence.


def test_the_extension_is_bounded_and_forgotten_after_the_window() -> None:
    s, due = session_hearing_b()
    _, due = s.on_tick(due + 100.0)  # frozen 100 s: forgiven, remembered as lateness
    s.on_receive(heartbeat_from("B"), due)
    # Silent from here, the timer on time: lost within the bounded deadline.
    lost_at = silent_until_lost(s, due, 0.0)
    limit = (1 + MAX_EXTENSION) * FAST.peer_timeout_s
    assert FAST.peer_timeout_s < lost_at - due <= limit + FAST.heartbeat_s + 1e-3
    # Once the window has passed with the timer on time, the plain deadline holds again.
    _, due = s.on_tick(lost_at)
    while due < lost_at + LATENESS_WINDOW_S + 1.0:
        _, due = s.on_tick(due)
    heard = due
    s.on_receive(heartbeat_from("B"), heard)
    _, due = s.on_tick(heard)
    lost_again = silent_until_lost(s, due, 0.0)
    assert lost_again - heard <= FAST.peer_timeout_s + FAST.heartbeat_s + 1e-3


def test_stale_telemetry_waits_as_long_as_the_timer_runs_late() -> None:
    late = 0.8 * LATE_TICK_S
    s, due = session_hearing_b()
    sample = wire.TelemetrySample(MISSION, "B", 0.0, 0, 0, 0, 0, 0, 0, 100.0, False, True)
    s.on_receive(sample, 0.0)
    now, stale_at = 0.0, None
    while stale_at is None:
        now = due + late
        actions, due = s.on_tick(now)
        if any(isinstance(getattr(a, "item", None), TelemetryStale) for a in actions):
            stale_at = now
        assert now < 100 * FAST.telemetry_stale_s
    assert stale_at > FAST.telemetry_stale_s + LATENESS_FACTOR * late


def test_lateness_keeps_the_largest_of_the_window() -> None:
    w = Lateness(10.0)
    assert w.peak(0.0) == 0.0
    w.note(1.0, 0.5)
    w.note(2.0, 0.2)
    w.note(3.0, 0.3)
    assert w.peak(3.0) == 0.5
    assert w.peak(11.5) == 0.3  # the 0.5 of t = 1 s is out of the window
    assert w.peak(13.5) == 0.0
    for k in range(1000):  # rising lateness keeps one entry
        w.note(20.0 + k, k / 1000)
    assert len(w._kept) == 1


def test_a_stalled_receive_loop_does_not_make_a_peer_lost() -> None:
    # The timer runs on time, but one turn of the receive loop took long (a burst of
    # triggers on a fan-in drone): B's heartbeats waited unread meanwhile.
    s, due = session_hearing_b()
    stall = FAST.peer_timeout_s * 0.9
    s.on_receive_stall(stall, stall)
    now, events = 0.0, list[str]()
    while now < FAST.peer_timeout_s + stall * 0.5 and not events:
        now = due
        actions, due = s.on_tick(now)
        events = lost_events(actions)
    assert events == []  # without the stall credited, B was lost by now


def test_receive_stalls_cannot_hide_a_dead_peer_for_ever() -> None:
    # A receive loop that is always busy: B never speaks again, and is still lost,
    # once the credit for the stalls reaches its bound.
    s, due = session_hearing_b()
    now, events = 0.0, list[str]()
    limit = (1 + 3 * MAX_EXTENSION) * FAST.peer_timeout_s + FAST.heartbeat_s
    while now < 10 * limit and not events:
        now = due
        s.on_receive_stall(2 * LATE_TICK_S, now)
        actions, due = s.on_tick(now)
        events = lost_events(actions)
    assert events == ["lost"]
    assert now <= limit, now
