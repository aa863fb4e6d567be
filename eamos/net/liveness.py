"""Peer liveness and telemetry freshness, the part of the session that watches the clock.

:class:`Liveness` decides when a peer is up, lost, back or gone (from what is
heard of it and its goodbye) and when a drone's telemetry is stale, with
deadlines that grow with how late this participant's own timer runs
(:class:`Lateness`);
:class:`TelemetryOut` paces this participant's own telemetry (latest-value:
rate cap, coalescing, refresh).  Both are pure: time is passed in.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final

import eamos.net.wire as wire
from eamos.net.effects import (
    Deliver,
    PeerChanged,
    PeerStatus,
    Send,
    SessionEffect,
    TelemetryStale,
    Wake,
)
from eamos.net.sequence import Peer, Sending, SessionCounters
from eamos.net.settings import LinkSettings

if TYPE_CHECKING:
    from eamos.logs import EventLog

__all__ = [
    "LATENESS_FACTOR",
    "LATENESS_WINDOW_S",
    "LATE_TICK_S",
    "MAX_EXTENSION",
    "Lateness",
    "Liveness",
    "TelemetryOut",
]

LATE_TICK_S: Final = 0.1
"""A timer call later than asked by more than this means this participant's loop stalled
(a busy machine); the driver's own jitter stays far below it."""

LATENESS_WINDOW_S: Final = 30.0
"""How long the lateness of this participant's own timer is remembered (seconds)."""

LATENESS_FACTOR: Final = 2.0
"""A peer's silence is judged against ``peer_timeout_s`` plus this many times the largest
lateness of this participant's own timer within the window: a peer on a machine as busy
sends its heartbeats as late, and two in a row may be."""

MAX_EXTENSION: Final = 2.0
"""The deadlines grow by at most this many times themselves (a lost peer is still found)."""


class Lateness:
    """The largest lateness of this participant's own timer within the last window (pure).

    A sliding-window maximum: the calls kept are those no later call was as late as,
    so it holds a handful of entries whatever the rate of calls.
    """

    def __init__(self, window_s: float = LATENESS_WINDOW_S) -> None:
        self.window_s = window_s
        self._kept: deque[tuple[float, float]] = deque()  # (when, how late), lateness falling

    def note(self, now: float, late_s: float) -> None:
        """The timer, due earlier, was called at ``now``, ``late_s`` seconds late."""
        kept = self._kept
        while kept and kept[-1][1] <= late_s:
            kept.pop()
        kept.append((now, late_s))

    def peak(self, now: float) -> float:
        """The largest lateness noted within the window before ``now`` (0: none)."""
        kept = self._kept
        while kept and kept[0][0] < now - self.window_s:
            kept.popleft()
        return kept[0][1] if kept else 0.0


class Liveness:
    """Who is up, lost, back or gone, and whose telemetry is fresh (one per session).

    ``serial`` numbers the peer events of one session, so a handler that sees
    them out of order (they come from two threads) keeps the highest.
    """

    def __init__(self, settings: LinkSettings, log: EventLog) -> None:
        self.settings = settings
        self.log = log
        self._serial = 0
        self.tick_due = float("inf")  # when the session's timer asked to be called next
        self.lateness = Lateness()

    def margin_s(self, deadline_s: float, now: float) -> float:
        """How much later than ``deadline_s`` a silence counts, the machine as busy as it is:
        :data:`LATENESS_FACTOR` times the peak lateness, at most :data:`MAX_EXTENSION` times
        ``deadline_s``."""
        return min(MAX_EXTENSION * deadline_s, LATENESS_FACTOR * self.lateness.peak(now))

    def event(self, peer: Peer, state: str, silent_s: float) -> PeerChanged:
        """Report ``peer`` ``state`` (lost, back, left, restarted): ``mission.peer.<state>``."""
        self._serial += 1
        status = PeerStatus(peer.name, state, round(silent_s, 3), self._serial)
        level = self.log.warning if state in ("lost", "restarted") else self.log.info
        level(f"mission.peer.{state}", peer=peer.name, silent_s=status.silent_s)
        return PeerChanged(status)

    def heard(self, peer: Peer, now: float) -> PeerChanged | None:
        """Something came from ``peer``: the ``back`` event if it had been lost."""
        silent = 0.0 if peer.heard is None else now - peer.heard
        peer.heard = now
        peer.forgiven_s = 0.0
        if not peer.watched:
            return None  # no heartbeats from it: its silence would mean nothing
        if peer.state == "left":
            return None  # stragglers after its goodbye (a heartbeat from a restart revives it)
        if peer.state == "lost":
            peer.state = "up"
            return self.event(peer, "back", silent)
        if peer.state != "up":
            peer.state = "up"
            self.log.debug("net.peer.up", peer=peer.name)
        return None

    def goodbye(self, peer: Peer) -> PeerChanged | None:
        """``peer`` said it is leaving: the ``left`` event, once."""
        if peer.state == "left":
            return None
        peer.state = "left"
        return self.event(peer, "left", 0.0)

    def alive(self, peer: Peer) -> None:
        """A heartbeat (not a goodbye) from ``peer``: one that left has started again."""
        if peer.state == "left":
            peer.state = "up"
            self.log.info("net.peer.up", peer=peer.name, rejoined=True)

    def fresh(self, peer: Peer, msg: wire.TelemetrySample, now: float) -> bool:
        """Whether ``msg`` is news (latest-value: a sample older than one seen is not)."""
        if peer.tel_time is not None and msg.time_s < peer.tel_time:
            return False
        peer.tel_time = msg.time_s
        peer.tel_heard = now
        if peer.tel_stale:
            peer.tel_stale = False
            self.log.info("mission.telemetry.fresh", drone=peer.name)
        return True

    def stalled(
        self, now: float, peers: Iterable[Peer], counters: SessionCounters, broadcasts: Sending
    ) -> None:
        """The timer is called at ``now``: if later than it asked, credit the stall to ``peers``.

        The retransmission timers wait the stall too: the acknowledgements that
        came meanwhile are still unread, on the receive thread that stalled
        with this one; resending now would only repeat what arrived.
        """
        late = now - self.tick_due
        if late > 0.0:
            self.lateness.note(now, late)
        if late > LATE_TICK_S:
            counters.late_ticks += 1
            counters.stalled_s += late
            peers = list(peers)
            self.forgive(peers, late, now)
            for tx in [broadcasts, *(p.tx for p in peers)]:
                if tx.due is not None:  # and the receive thread gets its turn first
                    tx.due = max(tx.due + late, now + LATE_TICK_S)

    def receive_stalled(self, now: float, peers: Iterable[Peer], stalled_s: float) -> None:
        """The receive loop took ``stalled_s`` over one turn (a burst to handle, a busy
        machine): what the other peers sent meanwhile waited unread, so that time is not
        their silence either, and this participant's deadlines grow as for a late timer."""
        if stalled_s <= LATE_TICK_S:
            return
        self.lateness.note(now, stalled_s)
        # Bounded per silence: a loop that is always busy must not hide a dead peer.
        most = MAX_EXTENSION * self.settings.peer_timeout_s
        for peer in peers:
            give = min(stalled_s, max(0.0, most - peer.forgiven_s))
            if give > 0.0:
                peer.forgiven_s += give
                self.forgive([peer], give, now)

    def forgive(self, peers: Iterable[Peer], stalled_s: float, now: float) -> None:
        """This participant's own loop stalled ``stalled_s``: that time is not the peers' silence.

        On a busy machine the timer (and the receive thread with it) may run
        seconds late; what peers sent meanwhile waits unread in the sockets.
        Counting the stall as their silence declared healthy peers lost and
        had everything unacknowledged resent, which made the machine busier
        still.  So a peer is lost only after ``peer_timeout_s`` of silence
        measured while this loop ran.
        """
        for peer in peers:
            if peer.heard is not None:
                peer.heard = min(now, peer.heard + stalled_s)
            if peer.tel_heard is not None:
                peer.tel_heard = min(now, peer.tel_heard + stalled_s)

    def check(self, peer: Peer, now: float, effects: list[SessionEffect]) -> float:
        """Report ``peer`` lost or its telemetry stale if due; return the next deadline.

        Both deadlines (``peer_timeout_s``, ``telemetry_stale_s``) grow by the
        :meth:`margin_s` this machine's load calls for: peers on a machine as busy
        are as late, and load is not a lost peer.
        """
        s = self.settings
        deadline = float("inf")
        if peer.watched and peer.state == "up" and peer.heard is not None:
            silent = now - peer.heard
            timeout = s.peer_timeout_s + self.margin_s(s.peer_timeout_s, now)
            if silent > timeout:
                peer.state = "lost"
                effects.append(self.event(peer, "lost", silent))
            else:
                deadline = peer.heard + timeout + 1e-3
        if peer.tel_heard is not None and not peer.tel_stale:
            age = now - peer.tel_heard
            stale = s.telemetry_stale_s + self.margin_s(s.telemetry_stale_s, now)
            if age > stale:
                peer.tel_stale = True
                self.log.warning("mission.telemetry.stale", drone=peer.name, age_s=round(age, 3))
                effects.append(Deliver(TelemetryStale(peer.name, round(age, 3))))
            else:
                deadline = min(deadline, peer.tel_heard + stale + 1e-3)
        return deadline


@dataclass
class TelemetryOut:
    """Latest-value telemetry going out: at most one sample per ``interval``, the
    latest always (a burst is coalesced), repeated every ``refresh`` when idle."""

    interval: float
    refresh: float
    latest: wire.TelemetrySample | None = None
    sent_at: float = float("-inf")
    pending: bool = False  # a newer sample waits for the end of the interval

    def offer(self, msg: wire.TelemetrySample, now: float) -> list[SessionEffect]:
        self.latest = msg
        if now >= self.sent_at + self.interval:
            self.sent_at = now
            self.pending = False
            return [Send(msg)]
        if self.pending:
            return []
        self.pending = True  # the timer sends the latest at the end of the interval
        return [Wake(self.sent_at + self.interval)]

    def repeat(self, now: float) -> list[SessionEffect]:
        if self.latest is None:
            return []
        self.sent_at = now
        return [Send(self.latest)]

    def tick(self, now: float) -> tuple[list[SessionEffect], float]:
        # Compared as ``now >= sent_at + period``, the very sum returned as the
        # deadline: ``now - sent_at`` may round below the period at that instant.
        if self.latest is None:
            return [], float("inf")
        effects: list[SessionEffect] = []
        if self.pending and now >= self.sent_at + self.interval:
            self.pending = False
            effects = self.repeat(now)
        elif not self.pending and now >= self.sent_at + self.refresh:
            # Nothing new: repeat the latest, so peers know it is still current.
            effects = self.repeat(now)
        return effects, self.sent_at + (self.interval if self.pending else self.refresh)
