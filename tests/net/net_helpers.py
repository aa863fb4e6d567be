"""Helpers shared by the network-layer tests (a uniquely named module, not conftest,
so ``import`` cannot pick up another package's conftest)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import zmq

from eamos.net import InBridge, Message, OutBridge

MISSION = "mission-test"
WAIT_S = 30.0  # upper bound for anything that should take milliseconds


class Collector:
    """An ``on_message`` callback that records messages and lets tests wait on them."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._messages: list[Message] = []

    def __call__(self, msg: Message) -> None:
        with self._cond:
            self._messages.append(msg)
            self._cond.notify_all()

    @property
    def messages(self) -> list[Message]:
        with self._cond:
            return list(self._messages)

    def wait_for(self, predicate: Callable[[list[Message]], bool], timeout: float = WAIT_S) -> bool:
        with self._cond:
            return self._cond.wait_for(lambda: predicate(self._messages), timeout)

    def wait_count(self, count: int, timeout: float = WAIT_S) -> bool:
        return self.wait_for(lambda msgs: len(msgs) >= count, timeout)

    def wait_type(self, cls: type, count: int = 1, timeout: float = WAIT_S) -> bool:
        return self.wait_for(lambda msgs: sum(isinstance(m, cls) for m in msgs) >= count, timeout)


@dataclass
class Bridges:
    """Makes started bridges on ``ctx`` and closes them all at teardown."""

    ctx: zmq.Context[Any]
    made: list[OutBridge | InBridge] = field(default_factory=list)

    def out(self, bind: str = "tcp://127.0.0.1:0", log: Any = None, **kw: Any) -> OutBridge:
        bridge = OutBridge(self.ctx, bind, log, **kw)
        self.made.append(bridge)
        bridge.start()
        return bridge

    def inb(
        self,
        connect: Mapping[str, str],
        subscribe: Iterable[bytes],
        on_message: Callable[[Message], None],
        mission: str = MISSION,
        log: Any = None,
        start: bool = True,
        **kw: Any,
    ) -> InBridge:
        bridge = InBridge(self.ctx, connect, subscribe, on_message, mission, log, **kw)
        self.made.append(bridge)
        if start:
            bridge.start()
        return bridge

    def close_all(self) -> None:
        for bridge in reversed(self.made):
            bridge.close()
