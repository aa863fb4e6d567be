"""An in-memory network of :class:`~eamos.net.session.ReliableSession` s in virtual time.

No thread, socket or clock: :class:`Fleet` carries out the sessions' actions
itself (a Send puts the message "on the wire" to every participant that
subscribes to its topic, where a test may lose, duplicate or reorder it),
delivers what is on the wire in batches (each batch followed by
``on_batch_end``, as the In-Bridge does) and advances time from one session
deadline to the next.  A whole protocol scenario runs in milliseconds.
"""

from __future__ import annotations

import random
from collections.abc import Callable, Iterable
from typing import Any

from eamos.net import wire
from eamos.net.effects import (
    Deliver,
    PeerChanged,
    PeerStatus,
    Send,
    SessionEffect,
    TelemetryStale,
    Wake,
)
from eamos.net.session import ReliableSession
from eamos.net.settings import LinkSettings

MISSION = "mission-link"

FAST = LinkSettings(
    heartbeat_s=0.1,
    peer_timeout_s=0.6,
    telemetry_stale_s=0.5,
    telemetry_max_hz=20.0,
    rto_min_s=0.25,
    rto_max_s=1.0,
    rto_initial_s=0.3,
)

Rule = Callable[[str, str, wire.Message], bool]
"""(sender, recipient, message) -> whether it applies to this copy on the wire."""

NEVER: Rule = lambda sender, to, msg: False  # noqa: E731


class Fleet:
    """Sessions ``names`` joined by an in-memory PUB/SUB network, at virtual time ``now``."""

    def __init__(
        self,
        names: Iterable[str],
        settings: LinkSettings = FAST,
        *,
        seed: int = 1,
        logs: dict[str, Any] | None = None,
        watch: dict[str, list[str]] | None = None,
        telemetry: bool = True,
    ) -> None:
        self.now = 0.0
        self.rng = random.Random(seed)
        names = list(names)
        self.watch = watch or {}
        self.sessions: dict[str, ReliableSession] = {}
        for i, name in enumerate(names):
            log = (logs or {}).get(name)
            session = ReliableSession(
                name,
                MISSION,
                settings,
                log=log,
                rng=random.Random(seed * 1000 + i),
                incarnation=i + 1,
            )
            session.add_peers(names, self.watch.get(name))
            self.sessions[name] = session
        self.settings = settings
        self.logs = logs or {}
        self.telemetry = telemetry
        self.wire: list[tuple[str, wire.Message]] = []  # (recipient, message) in flight
        self.got: dict[str, list[Any]] = {n: [] for n in names}
        self.sent: list[tuple[float, str, wire.Message]] = []  # every Send, before loss
        self.deadline: dict[str, float] = {n: float("-inf") for n in names}
        self.down: set[str] = set()  # not on the network (not subscribed, hears nothing)
        self.closed: set[str] = set()
        self.lose: Rule = NEVER
        self.duplicate: Rule = NEVER
        self.delay: Rule = NEVER  # held back, released later in random order
        self.held: list[tuple[str, wire.Message]] = []
        self.reorder = False  # shuffle each batch on the wire
        self.dropped = 0
        self.dropped_from: dict[str, int] = {n: 0 for n in names}
        self.ticks: dict[str, int] = {n: 0 for n in names}

    # -- the network -------------------------------------------------------------------

    def recipients(self, sender: str, msg: wire.Message) -> list[str]:
        topic = msg.topic
        out: list[str] = []
        if sender in self.down:
            return out
        for name in self.sessions:
            if name == sender or name in self.down or name in self.closed:
                continue
            if topic == wire.TOPIC_ALL or topic == wire.topic_to(name):
                out.append(name)
            elif topic == wire.topic_heartbeat(sender):
                if name not in self.watch or sender in self.watch[name]:
                    out.append(name)
            elif topic == wire.topic_telemetry(sender) and self.telemetry:
                out.append(name)
        return out

    def apply(self, who: str, actions: list[SessionEffect]) -> None:
        """Carry out ``who``'s actions, as the driver does."""
        for action in actions:
            if isinstance(action, Send):
                msg = action.message
                self.sent.append((self.now, who, msg))
                for to in self.recipients(who, msg):
                    if self.lose(who, to, msg):
                        self.dropped += 1
                        self.dropped_from[who] += 1
                        continue
                    if self.delay(who, to, msg):
                        self.held.append((to, msg))
                        continue
                    self.wire.append((to, msg))
                    if self.duplicate(who, to, msg):
                        self.wire.append((to, msg))
            elif isinstance(action, Deliver):
                self.got[who].append(action.item)
            elif isinstance(action, PeerChanged):
                self.got[who].append(action.status)
            elif isinstance(action, Wake):
                self.deadline[who] = min(self.deadline[who], action.at)
            else:  # pragma: no cover - a new action type the harness does not know
                raise AssertionError(f"unknown action {action!r}")

    def pump(self) -> None:
        """Deliver everything on the wire (and what that sends), batch by batch."""
        for _ in range(100_000):
            if not self.wire:
                return
            batch, self.wire = self.wire, []
            if self.reorder:
                self.rng.shuffle(batch)
            heard: list[str] = []
            for to, msg in batch:
                if to in self.closed or to in self.down:
                    continue
                self.apply(to, self.sessions[to].on_receive(msg, self.now))
                if to not in heard:
                    heard.append(to)
            for to in heard:
                self.apply(to, self.sessions[to].on_batch_end(self.now))
        raise AssertionError("the wire never settles")

    # -- time ---------------------------------------------------------------------------

    def run(self, until: float) -> None:
        """Advance to ``until``, ticking each session at its deadlines."""
        self.pump()
        for _ in range(1_000_000):
            live = [n for n in self.sessions if n not in self.closed]
            nxt = min((self.deadline[n] for n in live), default=float("inf"))
            if nxt > until:
                self.now = max(self.now, until)
                return
            self.now = max(self.now, nxt)
            self.release()
            for name in live:
                if self.deadline[name] <= self.now:
                    self.ticks[name] += 1
                    actions, self.deadline[name] = self.sessions[name].on_tick(self.now)
                    self.apply(name, actions)
            self.pump()
        raise AssertionError("time never advances")

    def release(self) -> None:
        """Put about half of what was held back on the wire, in random order."""
        if self.held:
            self.rng.shuffle(self.held)
            keep = self.rng.randrange(len(self.held))
            self.wire += self.held[keep:]
            del self.held[keep:]

    def advance(self, dt: float) -> None:
        self.run(self.now + dt)

    def until(
        self, predicate: Callable[[], bool], limit_s: float = 60.0, step: float = 0.01
    ) -> bool:
        """Advance in ``step`` s until ``predicate`` holds (False after ``limit_s`` virtual s)."""
        end = self.now + limit_s
        while not predicate():
            if self.now >= end:
                return False
            self.run(min(end, self.now + step))
        return True

    # -- participants -------------------------------------------------------------------

    def send(self, who: str, msg: wire.Message) -> None:
        self.apply(who, self.sessions[who].on_send(msg, self.now))
        self.pump()

    def subscribe(self, who: str, topic: bytes, by: str) -> None:
        """``by`` comes on the network and subscribes ``topic`` at ``who``'s Out-Bridge."""
        self.down.discard(by)
        self.apply(who, self.sessions[who].on_subscription(topic, self.now))
        self.run(self.now)  # what is due now (an expedited retransmission), no later

    def close(self, who: str) -> None:
        self.apply(who, self.sessions[who].close())
        self.closed.add(who)
        self.pump()

    def restart(self, who: str, log: Any = None) -> ReliableSession:
        """``who``'s process dies (nothing said) and starts again: a new session, a new incarnation.

        What the old one received is kept in ``got[who]`` under ``who + "#old"``.
        """
        old = self.sessions[who]
        self.got[who + "#old"] = self.got[who]
        self.got[who] = []
        new = ReliableSession(
            who,
            MISSION,
            self.settings,
            log=log if log is not None else self.logs.get(who),
            rng=random.Random(old.incarnation + 7),
            incarnation=old.incarnation + 1000,
        )
        new.add_peers(self.sessions, self.watch.get(who))
        self.sessions[who] = new
        self.deadline[who] = float("-inf")
        self.closed.discard(who)
        self.down.discard(who)
        self.wire = [(to, m) for to, m in self.wire if to != who]  # its sockets are gone
        return new

    def of(self, who: str, cls: type) -> list[Any]:
        return [i for i in self.got[who] if isinstance(i, cls)]

    def statuses(self, who: str) -> list[PeerStatus]:
        return self.of(who, PeerStatus)

    def stale(self, who: str) -> list[TelemetryStale]:
        return self.of(who, TelemetryStale)

    def sent_by(self, who: str, cls: type) -> list[tuple[float, Any]]:
        return [(t, m) for t, s, m in self.sent if s == who and isinstance(m, cls)]


def trig(sender: str, dest: str, n: int) -> wire.Trigger:
    return wire.Trigger(MISSION, sender, dest, "a", "b", (n,), "done")


def sample(sender: str, t: float, x: float = 0.0) -> wire.TelemetrySample:
    return wire.TelemetrySample(
        MISSION, sender, t, x, 0.0, 1.0, 47.0, 8.0, 500.0, 90.0, True, False
    )


def first_transmission_of(seqs: set[int]) -> Rule:
    """A loss rule: lose the first transmission of these trigger seqs (retries get through)."""
    pending = set(seqs)

    def lose(sender: str, to: str, msg: wire.Message) -> bool:
        if isinstance(msg, wire.Trigger) and msg.seq in pending:
            pending.discard(msg.seq)
            return True
        return False

    return lose


def random_rule(rng: random.Random, p: float, types: tuple[type, ...], sender: str = "") -> Rule:
    """Applies to a copy of one of ``types`` (from ``sender``, if given) with probability ``p``."""
    return lambda s, to, m: (
        (not sender or s == sender) and isinstance(m, types) and rng.random() < p
    )
