"""Pykka actors on a small shared thread pool (an M:N dispatcher).

A drone program has hundreds of nodes (the paper's stress test: 634 on one
drone).  One OS thread per node actor, as :class:`pykka.ThreadingActor` does,
costs about a millisecond per thread to start on a small companion computer
and a context switch per message.  :class:`PooledActor` keeps Pykka's whole
contract (``ActorRef.tell``/``ask``, proxies, futures, ``on_start``/``on_stop``/
``on_failure``, stop semantics, the registry) but runs on the worker threads
of one :class:`Dispatcher` per runtime: an actor with mail is *scheduled*; a
worker takes it, handles a batch of its messages, and hands it back.  An actor
is never run by two workers at once, so its messages are handled one at a
time and in order, as with a thread of its own.

Pooled actors must not block waiting for another pooled actor (no ``ask(...)
.get()`` between them): workers are few.  Node actors only ``tell``.
"""

from __future__ import annotations

import logging
import sys
import threading
from collections import deque
from typing import Any

import pykka
from pykka import ActorDeadError, messages
from pykka._envelope import Envelope

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
            actor._run_slice()

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


class PooledActor(pykka.Actor):
    """A Pykka actor that runs on a :class:`Dispatcher` instead of its own thread.

    Subclasses take ``dispatcher`` as their first constructor argument and pass
    it to ``super().__init__(dispatcher)``.
    """

    def __init__(self, dispatcher: Dispatcher, *args: Any, **kwargs: Any) -> None:
        self._dispatcher = dispatcher
        self._started = False
        super().__init__(*args, **kwargs)

    def _create_actor_inbox(self) -> _Inbox:  # type: ignore[override]
        return _Inbox(self)

    @staticmethod
    def _create_future() -> pykka.Future[Any]:
        return pykka.ThreadingFuture()

    def _start_actor_loop(self) -> None:
        # on_start runs on a worker, before any message, like a thread's first step.
        inbox: _Inbox = self.actor_inbox  # type: ignore[assignment]
        with inbox._lock:
            inbox._scheduled = True
        self._dispatcher.schedule(self)

    def _run_slice(self) -> None:
        inbox: _Inbox = self.actor_inbox  # type: ignore[assignment]
        if not self._started:
            self._started = True
            self._actor_loop_setup()
        for envelope in inbox.take_batch():
            if self.actor_stopped.is_set():
                self._reject(envelope)
                continue
            self._handle(envelope)
        if self.actor_stopped.is_set():
            while not inbox.empty():
                self._reject(inbox.get())
        if inbox.release():
            self._dispatcher.schedule(self)

    def _handle(self, envelope: Envelope[Any]) -> None:
        # The body of pykka.Actor._actor_loop_running for one envelope.
        try:
            response = self._handle_receive(envelope.message)
            if envelope.reply_to is not None:
                envelope.reply_to.set(response)
        except Exception:
            if envelope.reply_to is not None:
                envelope.reply_to.set_exception()
            else:
                self._handle_failure(*sys.exc_info())
                try:
                    self.on_failure(*sys.exc_info())
                except Exception:
                    self._handle_failure(*sys.exc_info())

    def _reject(self, envelope: Envelope[Any]) -> None:
        if envelope.reply_to is None:
            return
        if isinstance(envelope.message, messages._ActorStop):
            envelope.reply_to.set(None)
        else:
            envelope.reply_to.set_exception(
                exc_info=(
                    ActorDeadError,
                    ActorDeadError(f"{self.actor_ref} stopped before handling the message"),
                    None,
                )
            )
