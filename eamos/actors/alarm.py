"""A re-armable alarm on one thread for its owner's whole life.

The executive sends progress at most :data:`~.executive.PROGRESS_INTERVAL_S`
after a batch's first event.  A ``threading.Timer`` per interval started a
new OS thread each time (and ``Thread.start`` waits until the new thread
runs: a thread switch inside the executive's turn, which may run on the
In-Bridge's receive thread while a trigger passes).  An :class:`Alarm` starts
its thread once, on first use, and then only wakes it: arming is a
notification, firing a callback.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

__all__ = ["Alarm"]

Clock = Callable[[], float]


class Alarm:
    """Calls ``fire`` once per :meth:`arm`, ``delay_s`` later, on its own thread.

    Arming again before it fired moves the deadline; :meth:`cancel` forgets it;
    :meth:`stop` ends the thread (a pending deadline never fires, and arming
    afterwards does nothing).  ``fire`` runs without the alarm's lock, so it may
    arm again; an exception from it is passed to ``on_error`` (the thread lives
    on).  ``clock`` is monotonic seconds (injected for tests).
    """

    def __init__(
        self,
        fire: Callable[[], None],
        name: str = "eamos-alarm",
        *,
        on_error: Callable[[BaseException], None] | None = None,
        clock: Clock = time.monotonic,
    ) -> None:
        self._fire = fire
        self._on_error = on_error
        self._clock = clock
        self._name = name
        self._cond = threading.Condition()
        self._due: float | None = None
        self._stopped = False
        self._thread: threading.Thread | None = None
        self.fired = 0  # times ``fire`` was called (for tests and reports)

    @property
    def armed(self) -> bool:
        """Whether a deadline is pending."""
        with self._cond:
            return self._due is not None

    @property
    def thread(self) -> threading.Thread | None:
        """The alarm's thread (None until started or first armed)."""
        return self._thread

    def start(self) -> None:
        """Start the thread now (``Thread.start`` waits for it to run: do it off any
        hot path); :meth:`arm` starts it otherwise.  A no-op if started or stopped."""
        with self._cond:
            self._start()

    def _start(self) -> None:
        if self._thread is None and not self._stopped:
            self._thread = threading.Thread(target=self._run, name=self._name, daemon=True)
            self._thread.start()

    def arm(self, delay_s: float) -> None:
        """Fire ``delay_s`` from now (replacing a pending deadline); a no-op once stopped."""
        with self._cond:
            if self._stopped:
                return
            self._due = self._clock() + max(0.0, delay_s)
            self._start()
            self._cond.notify()

    def cancel(self) -> None:
        """Forget a pending deadline (the thread stays for the next :meth:`arm`)."""
        with self._cond:
            self._due = None

    def stop(self, timeout_s: float = 5.0) -> None:
        """End the thread; a pending deadline does not fire.  Idempotent, any thread
        (from ``fire`` itself too: the thread is then not joined)."""
        with self._cond:
            self._stopped = True
            self._due = None
            self._cond.notify()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout_s)

    def _run(self) -> None:
        with self._cond:
            while not self._stopped:
                if self._due is None:
                    self._cond.wait()
                    continue
                wait = self._due - self._clock()
                if wait > 0:
                    self._cond.wait(wait)
                    continue
                self._due = None
                self.fired += 1
                self._cond.release()
                try:
                    self._fire()
                except Exception as exc:  # the alarm outlives a failing callback
                    if self._on_error is not None:
                        self._on_error(exc)
                finally:
                    self._cond.acquire()
