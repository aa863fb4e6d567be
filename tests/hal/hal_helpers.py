"""Helpers shared by the hardware-layer tests (imported by name, like net_helpers).

Every wait is on an event, queue or condition with a generous timeout: the
test machine is small and shared, and nothing here synchronizes by sleeping.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from typing import Any

import pykka

from eamos.hal.api import ActionResult, Adapter, Telemetry
from eamos.program.uniform import Command, decode_command

#: Generous upper bound for any single wait in these tests.
WAIT_S = 60.0


class Done:
    """A done callback that can be waited on."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.result: ActionResult | None = None
        self.at: float | None = None  # time.monotonic() when done was called
        self.calls = 0

    def __call__(self, result: ActionResult) -> None:
        self.calls += 1
        self.result = result
        self.at = time.monotonic()
        self._event.set()

    def wait(self, timeout: float = WAIT_S) -> ActionResult:
        """The result, once done has been called."""
        assert self._event.wait(timeout), f"action not done within {timeout} s"
        assert self.result is not None
        return self.result

    @property
    def is_done(self) -> bool:
        return self._event.is_set()


def cmd(action: str, *args: float) -> Command:
    """The typed command for ``action(*args)``, decoded as the uniform-API actor does."""
    return decode_command(action, args)


def do(adapter: Adapter, action: str, *args: float, timeout: float = WAIT_S) -> ActionResult:
    """Run one action on ``adapter`` and wait for its result."""
    done = Done()
    adapter.run(cmd(action, *args), done)
    return done.wait(timeout)


class TelemetrySink:
    """Collects telemetry samples (thread-safe) and lets a test wait for one."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.samples: list[Telemetry] = []

    def __call__(self, sample: Telemetry) -> None:
        with self._cond:
            self.samples.append(sample)
            self._cond.notify_all()

    def count(self) -> int:
        with self._cond:
            return len(self.samples)

    def snapshot(self) -> list[Telemetry]:
        with self._cond:
            return list(self.samples)

    def wait_for(self, n: int, timeout: float = WAIT_S) -> list[Telemetry]:
        with self._cond:
            assert self._cond.wait_for(lambda: len(self.samples) >= n, timeout)
            return list(self.samples)

    def wait_last(self, predicate: Callable[[Telemetry], bool], timeout: float = WAIT_S) -> bool:
        """Wait until the latest sample satisfies ``predicate``; False on timeout."""
        with self._cond:
            return self._cond.wait_for(
                lambda: bool(self.samples) and predicate(self.samples[-1]), timeout
            )


class Collector(pykka.ThreadingActor):
    """A reply_to actor putting every message it receives into a queue."""

    def __init__(self, inbox: queue.Queue[Any]) -> None:
        super().__init__()
        self.inbox = inbox

    def on_receive(self, message: Any) -> Any:
        self.inbox.put(message)
        return None


def next_message(inbox: queue.Queue[Any], timeout: float = WAIT_S) -> Any:
    """The next message a :class:`Collector` received (fails after ``timeout``)."""
    try:
        return inbox.get(timeout=timeout)
    except queue.Empty:
        raise AssertionError(f"no message within {timeout} s") from None
