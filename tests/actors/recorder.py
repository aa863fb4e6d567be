"""A stand-in for an actor in node tests: records what it is told (one for every test)."""

from __future__ import annotations

import threading
from typing import Any

from eamos.actors.node import ExecutiveNews

WAIT_S = 30.0


class Recorder:
    """Records what it is told; with ``unpack_news`` a node's ``ExecutiveNews`` (one per
    message it handles) is recorded as the items it carries."""

    def __init__(self, unpack_news: bool = False) -> None:
        self.messages: list[Any] = []
        self.changed = threading.Condition()
        self.unpack_news = unpack_news

    def tell(self, message: Any) -> None:
        with self.changed:
            if self.unpack_news and isinstance(message, ExecutiveNews):
                self.messages.extend(message.items)
            else:
                self.messages.append(message)
            self.changed.notify_all()

    def wait_for(self, kind: type, timeout_s: float = WAIT_S) -> Any:
        """The first message of type ``kind`` (waits for it)."""
        with self.changed:
            assert self.changed.wait_for(
                lambda: any(isinstance(m, kind) for m in self.messages), timeout_s
            ), self.messages
            return next(m for m in self.messages if isinstance(m, kind))

    def wait_count(self, count: int) -> list[Any]:
        """Every message so far, once there are at least ``count``."""
        with self.changed:
            assert self.changed.wait_for(lambda: len(self.messages) >= count, WAIT_S), self.messages
            return list(self.messages)
