"""Helpers for link-driver tests: links on loopback, and loss injected at the sender.

Each :class:`~eamos.net.link.Link` gets its own ZeroMQ context, as each
participant has in its own process (and as CURVE needs: one ZAP handler per
context).  Loss is injected by wrapping a link's ``out.send``: the message is
"lost on the wire" (never handed to the socket), which is what a TCP reconnect
does to PUB/SUB traffic; every wait is bounded.
"""

from __future__ import annotations

import itertools
import random
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import zmq

from eamos.ground import free_ports
from eamos.net import wire
from eamos.net.keys import FleetKeys, create_fleet_keys
from eamos.net.link import Link, LinkSettings
from eamos.net.timers import TimerHost

from .session_helpers import FAST, MISSION, sample, trig

__all__ = [
    "FAST",
    "MISSION",
    "WAIT_S",
    "Inbox",
    "Lossy",
    "Net",
    "eventually",
    "fail_one_tick",
    "free_port",
    "network",
    "sample",
    "trig",
]

WAIT_S = 30.0


def free_port() -> int:
    return free_ports(1)[0]


class Inbox:
    """``on_message`` that records and lets tests wait (Condition, bounded)."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.items: list[Any] = []

    def __call__(self, item: Any) -> None:
        with self.cond:
            self.items.append(item)
            self.cond.notify_all()

    def of(self, cls: type) -> list[Any]:
        with self.cond:
            return [i for i in self.items if isinstance(i, cls)]

    def wait(self, predicate: Callable[[list[Any]], bool], timeout: float = WAIT_S) -> bool:
        with self.cond:
            return self.cond.wait_for(lambda: predicate(self.items), timeout)

    def wait_type(self, cls: type, count: int = 1, timeout: float = WAIT_S) -> bool:
        return self.wait(lambda items: sum(isinstance(i, cls) for i in items) >= count, timeout)


class Lossy:
    """Wraps ``link.out.send``: drops (or duplicates) chosen messages, seeded."""

    def __init__(self, link: Link, seed: int = 1) -> None:
        self.link = link
        self.real = link.out.send
        self.rng = random.Random(seed)
        self.drop: Callable[[wire.Message], bool] = lambda m: False
        self.duplicate: Callable[[wire.Message], bool] = lambda m: False
        self.dropped = 0
        link.out.send = self.send  # type: ignore[method-assign]

    def send(self, msg: wire.Message) -> bool:
        if self.drop(msg):
            self.dropped += 1
            return True
        ok = self.real(msg)
        if self.duplicate(msg):
            self.real(msg)
        return ok

    def random(self, p: float, types: tuple[type, ...]) -> Callable[[wire.Message], bool]:
        return lambda m: isinstance(m, types) and self.rng.random() < p


class Net:
    """Makes links (and their contexts) and closes them all."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.links: list[Link] = []
        self.contexts: list[zmq.Context[Any]] = []
        self.endpoints: dict[str, str] = {}
        self.keys_dir: Path | None = None

    def keys(self, names: list[str]) -> Path:
        self.keys_dir = create_fleet_keys(self.tmp / "keys", names, force=True)
        return self.keys_dir

    def link(
        self,
        name: str,
        peers: list[str],
        on_message: Callable[[Any], None] | None = None,
        *,
        settings: LinkSettings = FAST,
        secure: bool = False,
        connect: bool = True,
        topics: tuple[bytes, ...] = (),
        log: Any = None,
        clock: Callable[[], float] = time.monotonic,
        timers: TimerHost | None = None,
    ) -> Link:
        for n in [name, *peers]:
            self.endpoints.setdefault(n, f"tcp://127.0.0.1:{free_port()}")
        ctx: zmq.Context[Any] = zmq.Context()
        self.contexts.append(ctx)
        keys = None
        if secure:
            assert self.keys_dir is not None
            keys = FleetKeys.load(self.keys_dir / name, name)
        link = Link(
            ctx,
            name,
            MISSION,
            self.endpoints[name],
            log,
            keys=keys,
            settings=settings,
            clock=clock,
            timers=timers,
        )
        self.links.append(link)
        if connect:
            link.connect(
                {p: self.endpoints[p] for p in peers}, topics, on_message or (lambda m: None)
            )
        return link

    def close(self) -> None:
        for link in reversed(self.links):
            link.close()
        for ctx in self.contexts:
            ctx.destroy(linger=0)


@contextmanager
def network(tmp: Path) -> Iterator[Net]:
    net = Net(tmp)
    try:
        yield net
    finally:
        net.close()


def fail_one_tick(link: Link, which: int = 2) -> None:
    """Make the ``which``-th (0-based) tick of ``link``'s session raise, once."""
    real_tick = link.session.on_tick
    ticks = itertools.count()

    def on_tick(now: float) -> Any:
        if next(ticks) == which:
            raise RuntimeError("a tick's bug")
        return real_tick(now)

    link.session.on_tick = on_tick  # type: ignore[method-assign]


def eventually(predicate: Callable[[], bool], timeout: float = WAIT_S) -> bool:
    """Poll ``predicate`` (every 20 ms, bounded) for state that nothing notifies about."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()
