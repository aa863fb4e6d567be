"""Pykka actors on a small shared thread pool (an M:N dispatcher).

A drone program has hundreds of nodes (the paper's stress test: 634 on one
drone).  One OS thread per node actor, as :class:`pykka.ThreadingActor` does,
costs about a millisecond per thread to start on a small companion computer
and a context switch per message.  :class:`PooledActor` keeps Pykka's contract
(``ActorRef.tell``/``ask``, proxies, futures, ``on_start``/``on_stop``, stop
semantics, the registry) but runs on the worker threads of one
:class:`Dispatcher` per runtime: an actor with mail is *scheduled*; a worker
takes it, handles a batch of its messages, and hands it back.  An actor is
never run by two workers at once, so its messages are handled one at a time
and in order, as with a thread of its own.

Failures differ from Pykka on purpose: an exception raised by a ``tell``-ed
message calls :meth:`PooledActor.on_failure` and the actor *lives on* unless
the hook stops it (a mission node must resolve ``failed``, not vanish); the
default hook does what Pykka does (log with the traceback, stop).  A
``BaseException`` stops the actor and every other one, as in Pykka.

Pykka's internals are used only through :mod:`.pykka_seam`.  Pooled actors
must not block waiting for another pooled actor (no ``ask(...).get()`` between
them): workers are few.  Node actors only ``tell``.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from types import TracebackType
from typing import TYPE_CHECKING, Any

from .pykka_seam import ExcInfo, ExternalLoopActor

if TYPE_CHECKING:
    from .pykka_seam import Envelope

__all__ = ["Dispatcher", "PooledActor"]

logger = logging.getLogger(__name__)

_BATCH = 64  # messages one actor may handle before others get a turn


class Dispatcher:
    """A few worker threads running every :class:`PooledActor` of one runtime."""

    def __init__(self, workers: int = 2, name: str = "eamos") -> None:
        self._ready: deque[PooledActor] = deque()
        self._cond = threading.Condition()
        self._stopping = False
        self._threads = [
            threading.Thread(target=self._work, name=f"{name}-worker-{i}", daemon=True)
            for i in range(workers)
        ]
        for thread in self._threads:
            thread.start()

    def schedule(self, actor: PooledActor) -> None:
        """Queue ``actor`` for a worker (it has mail, or has not started yet)."""
        with self._cond:
            self._ready.append(actor)
            self._cond.notify()

    def _work(self) -> None:
        while True:
            with self._cond:
                while not self._ready and not self._stopping:
                    self._cond.wait()
                if not self._ready:
                    return
                actor = self._ready.popleft()
            try:
                actor._run_slice()
            except BaseException:  # a worker serves every actor: it must survive any one
                logger.exception("dispatcher: %s escaped its actor", actor)

    def shutdown(self, timeout_s: float = 10.0) -> None:
        """Finish the scheduled work, then stop the workers (stop the actors first)."""
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout_s)


class _Inbox:
    """A Pykka actor inbox that schedules its actor when mail arrives."""

    def __init__(self, actor: PooledActor) -> None:
        self._actor = actor
        self._queue: deque[Envelope[Any]] = deque()
        self._lock = threading.Lock()
        self._scheduled = False

    def put(self, item: Envelope[Any], block: bool = True, timeout: float | None = None) -> None:
        with self._lock:
            self._queue.append(item)
            if self._scheduled:
                return
            self._scheduled = True
        self._actor._dispatcher.schedule(self._actor)

    def get(self, block: bool = True, timeout: float | None = None) -> Envelope[Any]:
        with self._lock:
            return self._queue.popleft()

    def empty(self) -> bool:
        with self._lock:
            return not self._queue

    def claim(self) -> None:
        """Mark the actor scheduled (its first slice runs ``on_start``)."""
        with self._lock:
            self._scheduled = True

    def take_batch(self) -> list[Envelope[Any]]:
        with self._lock:
            n = min(_BATCH, len(self._queue))
            return [self._queue.popleft() for _ in range(n)]

    def release(self) -> bool:
        """Done with a slice: True if more mail came and the actor must run again."""
        with self._lock:
            if self._queue:
                return True
            self._scheduled = False
            return False


class PooledActor(ExternalLoopActor):
    """A Pykka actor that runs on a :class:`Dispatcher` instead of its own thread.

    Subclasses take ``dispatcher`` as their first constructor argument and pass
    it to ``super().__init__(dispatcher)``.  Override :meth:`on_failure` to
    decide what an exception in a message handler means for the actor.
    """

    def __init__(self, dispatcher: Dispatcher, *args: Any, **kwargs: Any) -> None:
        self._dispatcher = dispatcher
        self._started = False
        super().__init__(*args, **kwargs)

    def new_inbox(self) -> _Inbox:
        return _Inbox(self)

    def loop_started(self) -> None:
        # on_start runs on a worker, before any message, like a thread's first step.
        self._pooled_inbox.claim()
        self._dispatcher.schedule(self)

    @property
    def _pooled_inbox(self) -> _Inbox:
        inbox = self.actor_inbox
        assert isinstance(inbox, _Inbox)
        return inbox

    def on_failure(
        self,
        exception_type: type[BaseException] | None,
        exception_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """A ``tell``-ed message raised: by default, log it with its traceback and stop.

        Called on the actor's worker with the exception's ``sys.exc_info()``.  An
        override that returns keeps the actor alive (it may stop it itself); one
        that raises stops it, with both tracebacks logged.
        """
        assert exception_type is not None and exception_value is not None
        self.die((exception_type, exception_value, traceback))

    def failed(self, exc_info: ExcInfo) -> None:
        try:
            self.on_failure(*exc_info)
        except Exception as hook_error:
            logger.error("%s: on_failure raised", self, exc_info=exc_info)
            self.die((type(hook_error), hook_error, hook_error.__traceback__))

    def _run_slice(self) -> None:
        inbox = self._pooled_inbox
        if not self._started:
            self._started = True
            self.begin()
        for envelope in inbox.take_batch():
            if self.actor_stopped.is_set():
                self.refuse(envelope)
            else:
                self.deliver(envelope)
        if self.actor_stopped.is_set():
            while not inbox.empty():
                self.refuse(inbox.get())
        if inbox.release():
            self._dispatcher.schedule(self)
