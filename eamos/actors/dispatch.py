"""Pykka actors on a small shared thread pool (an M:N dispatcher).

A drone program has hundreds of nodes (the paper's stress test: 634 on one
drone).  One OS thread per node actor, as :class:`pykka.ThreadingActor` does,
costs about a millisecond per thread to start on a small companion computer
and a context switch per message.  :class:`PooledActor` keeps Pykka's contract
(``ActorRef.tell``/``ask``, proxies, futures, ``on_start``/``on_stop``, stop
semantics, the registry) but runs on the worker threads of one
:class:`Dispatcher` per runtime: an actor with mail is *scheduled*; a worker
takes it, handles a batch of its messages, and hands it back.  An actor is
never run by two threads at once, so its messages are handled one at a time
and in order, as with a thread of its own.

Failures differ from Pykka on purpose: an exception raised by a ``tell``-ed
message calls :meth:`PooledActor.on_failure` and the actor *lives on* unless
the hook stops it (a mission node must resolve ``failed``, not vanish); the
default hook does what Pykka does (log with the traceback, stop).  A
``BaseException`` (``SystemExit``, ``KeyboardInterrupt`` raised by a handler)
goes to ``on_failure`` the same way and then to the dispatcher's ``on_exit``
hook: a drone runtime's aborts that drone (:mod:`.runtime`).  Pykka would stop
every actor of the process; several drones share one process, so without a hook
the dispatcher stops the actors *it* runs, and no other.  (A real Ctrl-C is
never raised here: Python delivers signals to the main thread, and no actor
runs on it.)

Pykka's internals are used only through :mod:`.pykka_seam`.  Pooled actors
must not block waiting for another pooled actor (no ``ask(...).get()`` between
them): workers are few.  Node actors only ``tell``.

*Caller runs* (:func:`tell_here`): a thread that is not a worker (the
In-Bridge's receive thread handing a trigger to its node) may run the turn of
the actor it just mailed itself, instead of queueing it and waking a worker: a
thread wake-up and a hand-over of the interpreter lock cost more than most
nodes' work.  The caller *hosts* the dispatcher for the length of one call: it
gets a next-actor slot like a worker's, and its own list of lazy mail, and runs
at most :data:`_HOST_TURNS` turns; what is left when it stops goes to the
shared queue and wakes workers.  The actor's scheduled flag is the same, so an
actor still runs on one thread at a time, its messages in order; one that is
running or queued already only gets the mail.  The turns run inside the call,
so they must not block (a node calls only adapters that answer at once, see
:func:`~.uniform_api.answers_at_once`); a failure goes to the actor's
:meth:`~PooledActor.on_failure` as on a worker, never to the caller.  Once the
dispatcher stops, :func:`tell_here` only mails.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections import deque
from collections.abc import Callable
from types import TracebackType
from typing import TYPE_CHECKING, Any

import pykka

from .pykka_seam import ExcInfo, ExternalLoopActor

if TYPE_CHECKING:
    from .pykka_seam import Envelope

__all__ = ["Dispatcher", "ExitHook", "LazyMail", "PooledActor", "RidesAlong", "tell_here"]

logger = logging.getLogger(__name__)

_BATCH = 64  # messages one actor may handle before others get a turn


#: Turns a worker may take from its next-actor slot before it looks at the shared queue.
_SLOT_STREAK = 16

#: Turns a caller that hosts the dispatcher (:func:`tell_here`) may run in one call:
#: the mailed actor, the few it mails in turn, and their lazy news; a longer local
#: chain goes on on a worker (the caller is a receive thread with more to read).
_HOST_TURNS = 4

#: ``hook(actor, exception)``: what a ``BaseException`` in one of a dispatcher's actors
#: means beyond that actor (called on the thread that ran the handler; must not block).
ExitHook = Callable[["PooledActor", BaseException], None]


class _Worker(threading.local):
    """Per thread: is it a worker or a host, the actor it runs next, a host's lazy mail."""

    def __init__(self) -> None:
        self.is_worker = False
        self.hosting = False  # a caller running the actors it mails (see tell_here)
        self.next: PooledActor | None = None
        self.lazy: deque[PooledActor] = deque()  # a host's LazyMail receivers


class LazyMail:
    """A message that may wait until a worker of the receiver's dispatcher is free.

    Sent from one of that dispatcher's workers, it wakes no other thread: the
    receiver runs on this worker when it next has nothing in its slot, or after
    :data:`_SLOT_STREAK` slot turns (news for the executive, which nobody waits
    for while a chain of nodes runs).  Sent by a caller hosting the dispatcher
    (:func:`tell_here`), the caller runs the receiver once its slot is empty, or
    hands it to the workers when its turns are spent.  From any other thread it
    is ordinary mail.
    """


class RidesAlong:
    """A message that wakes nobody: it waits in the receiver's inbox and is handled
    just before the receiver's next ordinary message (or ask).

    For a count that matters only when read (the executive's triggers received):
    whoever reads it asks, and the ask is mail that comes after, so the reader
    always sees every count told before.  Waking a worker for each would cost the
    In-Bridge's thread and the node it hands the trigger to a thread switch.
    """


class Dispatcher:
    """A few worker threads running every :class:`PooledActor` of one runtime.

    An actor that a worker's own actor gives mail to (a trigger along a chain of
    nodes) goes to that worker's *next* slot instead of the shared queue: the
    worker runs it right after the current slice, with no other thread woken
    (a thread hop costs more than most nodes' work).  Only one actor fits in the
    slot; others go to the shared queue and wake a worker, and after
    :data:`_SLOT_STREAK` slot turns in a row a worker serves the shared queue
    first, so nothing waits behind a long chain.  A thread that is not a worker
    gets such a slot for the length of one :meth:`tell_here` call (it *hosts*
    the dispatcher): see :func:`tell_here`.

    ``on_exit`` (:data:`ExitHook`) is told when a handler of one of its actors raises
    a ``BaseException``, after the actor's own ``on_failure``; without it the
    dispatcher stops every actor it runs (Pykka's reaction, scoped to them).
    """

    def __init__(
        self, workers: int = 2, name: str = "eamos", on_exit: ExitHook | None = None
    ) -> None:
        self._on_exit = on_exit
        self._actors: weakref.WeakSet[PooledActor] = weakref.WeakSet()  # for actor_exited
        self._actors_lock = threading.Lock()
        self._ready: deque[PooledActor] = deque()
        self._lazy: deque[PooledActor] = deque()  # scheduled by LazyMail: no worker woken
        self._cond = threading.Condition()
        self._stopping = False
        self._local = _Worker()
        self._threads = [
            threading.Thread(target=self._work, name=f"{name}-worker-{i}", daemon=True)
            for i in range(workers)
        ]
        for thread in self._threads:
            thread.start()

    def adopt(self, actor: PooledActor) -> None:
        """Count ``actor`` among the actors this dispatcher runs (when it starts)."""
        with self._actors_lock:
            self._actors.add(actor)

    def actor_exited(self, actor: PooledActor, exc: BaseException) -> None:
        """``actor``'s handler raised ``exc`` (a ``BaseException``): the ``on_exit`` hook,
        or else stop every actor of this dispatcher (without waiting: this runs on a
        worker, which the actors need to handle their stop message)."""
        if self._on_exit is not None:
            try:
                self._on_exit(actor, exc)
            except Exception:
                logger.exception("dispatcher: the exit hook raised for %s", actor)
            return
        logger.error("dispatcher: %r in %s: stopping this dispatcher's actors", exc, actor)
        with self._actors_lock:
            actors = list(self._actors)
        for other in actors:
            if not other.actor_stopped.is_set():
                try:
                    other.actor_ref.stop(block=False)
                except pykka.ActorDeadError:
                    continue

    def schedule(self, actor: PooledActor) -> None:
        """Queue ``actor`` for a worker (it has mail, or has not started yet)."""
        local = self._local
        if (local.is_worker or local.hosting) and local.next is None:
            local.next = actor  # this thread runs it next: no thread woken
            return
        with self._cond:
            self._ready.append(actor)
            self._cond.notify()

    def schedule_lazy(self, actor: PooledActor) -> None:
        """Queue ``actor`` for this worker's next free moment (see :class:`LazyMail`)."""
        local = self._local
        if local.hosting:
            local.lazy.append(actor)
        elif not local.is_worker:
            self.schedule(actor)
        else:
            with self._cond:
                self._lazy.append(actor)

    def tell_here(self, ref: Any, message: Any) -> None:
        """``ref.tell(message)``, then run the turns it made ready on this thread (see
        :func:`tell_here`).  From a worker, or once stopping, only the tell."""
        local = self._local
        if local.is_worker or local.hosting or self._stopping:
            ref.tell(message)  # a worker's slot does the same; a host does not nest
            return
        local.hosting = True
        try:
            ref.tell(message)  # an idle actor lands in this thread's slot
            for _ in range(_HOST_TURNS):
                actor = local.next
                if actor is not None:
                    local.next = None
                elif local.lazy:
                    actor = local.lazy.popleft()
                else:
                    return
                self._run(actor)
        finally:
            local.hosting = False
            if local.next is not None or local.lazy:
                self._hand_over(local)

    def _hand_over(self, local: _Worker) -> None:
        """A host's slot and lazy mail to the workers (its turns are spent)."""
        left = list(local.lazy)
        local.lazy.clear()
        if local.next is not None:
            left.insert(0, local.next)
            local.next = None
        if left:
            with self._cond:
                self._ready.extend(left)
                self._cond.notify(len(left))

    def _take(self, streak: int) -> tuple[PooledActor | None, bool]:
        """The next actor for this worker (None: stopping), and whether it came from
        the slot; may wait for one."""
        local = self._local
        actor, local.next = local.next, None
        if actor is not None and (streak < _SLOT_STREAK or not (self._ready or self._lazy)):
            return actor, True
        with self._cond:
            self._ready.extend(self._lazy)  # lazy mail's turn: this worker is free
            self._lazy.clear()
            if actor is not None:  # its turn comes after those waiting in the queue
                self._ready.append(actor)
            while not self._ready and not self._stopping:
                self._cond.wait()
            if not self._ready:
                return None, False
            return self._ready.popleft(), False

    def _work(self) -> None:
        self._local.is_worker = True
        streak = 0
        while True:
            actor, from_slot = self._take(streak)
            if actor is None:
                return
            streak = streak + 1 if from_slot else 0
            self._run(actor)

    @staticmethod
    def _run(actor: PooledActor) -> None:
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


def tell_here(ref: Any, message: Any) -> None:
    """Tell ``ref`` ``message``; if that made its pooled actor ready, run its turn now,
    on this thread (*caller runs*, see the module's docstring).

    For a thread that is not a worker and must not wait long (the In-Bridge's):
    the actor's turn, and the turns of the actors it mails, run before this
    returns, at most :data:`_HOST_TURNS` of them; the rest goes to the workers.
    An actor that is running or queued already just gets the mail.  Not a pooled
    actor (or anything else with a ``tell``): a plain ``tell``.  Raises
    :class:`pykka.ActorDeadError` as ``tell`` does.
    """
    inbox = getattr(ref, "actor_inbox", None)  # public on a Pykka ActorRef
    if type(inbox) is _Inbox:
        inbox.dispatcher.tell_here(ref, message)
    else:
        ref.tell(message)


class _Inbox:
    """A Pykka actor inbox that schedules its actor when mail arrives."""

    def __init__(self, actor: PooledActor) -> None:
        self._actor = actor
        self.dispatcher = actor._dispatcher
        self._queue: deque[Envelope[Any]] = deque()
        self._lock = threading.Lock()
        self._scheduled = False

    def put(self, item: Envelope[Any], block: bool = True, timeout: float | None = None) -> None:
        with self._lock:
            self._queue.append(item)
            if self._scheduled or isinstance(item.message, RidesAlong):
                return
            self._scheduled = True
        if isinstance(item.message, LazyMail):
            self._actor._dispatcher.schedule_lazy(self._actor)
        else:
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
        queue = self._queue
        with self._lock:
            if len(queue) <= _BATCH:  # the usual case: all of it (one message, mostly)
                batch = list(queue)
                queue.clear()
                return batch
            return [queue.popleft() for _ in range(_BATCH)]

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
        self._dispatcher.adopt(self)
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

    def exited(self, exc_info: ExcInfo) -> None:
        """A ``BaseException`` in a handler: :meth:`on_failure` as for an exception (if
        the actor still runs), then the dispatcher's reaction
        (:meth:`Dispatcher.actor_exited`: its ``on_exit`` hook, or stop its actors)."""
        if not self.actor_stopped.is_set():
            self.failed(exc_info)
        self._dispatcher.actor_exited(self, exc_info[1])

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
