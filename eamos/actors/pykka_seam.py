"""The one place where EAMOS touches Pykka's internals (tested range: :data:`PYKKA_TESTED`).

Pykka's public API lets a program *use* actors; a new kind of actor loop
(Pykka's own :class:`pykka.ThreadingActor` is one) must implement the hooks
Pykka documents as "internal methods for implementors of new actor types":
``_create_actor_inbox``, ``_create_future``, ``_start_actor_loop``, and then
handle what arrives in the inbox: envelopes (``message``, ``reply_to``),
Pykka's private stop message, proxy calls (``_handle_receive``), and failures
(``_handle_failure``).  :mod:`.dispatch` runs actors on a shared
thread pool, so it needs exactly that; an actor library of our own would need
no internals but would lose Pykka's refs, proxies and futures that the rest of
the runtime (the uniform API, the board, the executive) shares with it.

So every such use is here, and nowhere else: :class:`ExternalLoopActor` is a
Pykka actor whose loop is driven from outside, one envelope at a time, with
Pykka's own semantics (reply or exception to an ``ask``; an exception in a
``tell``-ed message goes to ``on_failure``) but one: a ``BaseException``
(``SystemExit``, ``KeyboardInterrupt`` raised by a handler).  Pykka stops every
actor of the process then (``ActorRegistry.stop_all``); one EAMOS process hosts
several drones, so here it ends only what the actor belongs to, as its
subclass says (:meth:`ExternalLoopActor.exited`; by default the actor itself),
and an ``ask`` is answered with an :class:`ActorExit` instead of never.
``pyproject.toml`` pins Pykka to ``>=4.1,<4.6`` (:data:`PYKKA_TESTED`);
``tests/actors/test_dispatch.py`` and ``tests/actors/test_cohosted_drones.py``
test the behaviour each internal used here gives (a newer Pykka must pass them
before the upper bound moves).
"""

from __future__ import annotations

import logging
import sys
from types import TracebackType
from typing import TYPE_CHECKING, Any

import pykka
from pykka import ActorDeadError, messages

if TYPE_CHECKING:
    from pykka._envelope import Envelope as Envelope

__all__ = ["PYKKA_TESTED", "ActorExit", "ExcInfo", "ExternalLoopActor"]

logger = logging.getLogger(__name__)

#: The Pykka range pyproject.toml allows (``>=4.1,<4.6``; keep the two in step).  The
#: test suite ran on 4.5.0; a newer Pykka must pass the behaviour tests before the
#: upper bound moves.
PYKKA_TESTED = (4, 1), (4, 6)

ExcInfo = tuple[type[BaseException], BaseException, TracebackType | None]


class ActorExit(RuntimeError):
    """What an ``ask`` gets when the handler raised a ``BaseException`` (its ``__cause__``).

    An ordinary exception, so that a ``SystemExit`` raised in one actor never ends
    the thread (or the process) of whoever asked it something.
    """


class ExternalLoopActor(pykka.Actor):
    """A Pykka actor whose messages are handed to it by someone else's thread.

    Subclasses provide :meth:`new_inbox` (anything with ``put``/``get``/``empty``)
    and :meth:`loop_started` (called by ``start()`` once the actor is
    registered), then call :meth:`begin` once and :meth:`deliver` for each
    envelope, never two at once.  :meth:`failed` decides what an exception in
    a ``tell``-ed message does (by default what Pykka does: log, stop), and
    :meth:`exited` what a ``BaseException`` does (by default: stop this actor).
    """

    # -- Pykka's hooks for new actor types -------------------------------------------

    def _create_actor_inbox(self) -> Any:  # type: ignore[override]
        return self.new_inbox()

    @staticmethod
    def _create_future() -> pykka.Future[Any]:
        return pykka.ThreadingFuture()

    def _start_actor_loop(self) -> None:
        self.loop_started()

    # -- for subclasses ----------------------------------------------------------------

    def new_inbox(self) -> Any:
        """The actor's inbox (called once, from ``pykka.Actor.__init__``)."""
        raise NotImplementedError

    def loop_started(self) -> None:
        """The actor is registered: arrange for :meth:`begin` and :meth:`deliver` to run."""
        raise NotImplementedError

    def failed(self, exc_info: ExcInfo) -> None:
        """A ``tell``-ed message raised an ``Exception``: Pykka's default, log and stop."""
        self.die(exc_info)
        try:
            self.on_failure(*exc_info)
        except Exception:
            self.die(sys.exc_info())  # type: ignore[arg-type]

    def exited(self, exc_info: ExcInfo) -> None:
        """A handler or ``on_start`` raised a ``BaseException`` (``SystemExit``, ...).

        Pykka would stop every actor of the process; by default this stops only
        this actor (logged with the traceback).  Subclasses decide how far it
        reaches (a drone's dispatcher: that drone, see :mod:`.dispatch`).  Called
        on the thread that ran the handler; the actor may have stopped already
        (``on_start`` failed).
        """
        if not self.actor_stopped.is_set():
            self.die(exc_info)

    # -- the loop, one step at a time ------------------------------------------------------

    def begin(self) -> None:
        """Run ``on_start`` as Pykka does (an exception is logged and stops the actor)."""
        try:
            self._actor_loop_setup()
        except BaseException:  # Pykka's setup catches Exception: the rest ends here
            exc_info: ExcInfo = sys.exc_info()  # type: ignore[assignment]
            self.die(exc_info)
            self.exited(exc_info)

    def deliver(self, envelope: Envelope[Any]) -> None:
        """Handle one envelope as ``pykka.Actor._actor_loop_running`` does, but for a
        ``BaseException`` (see :meth:`exited`)."""
        try:
            response = self._handle_receive(envelope.message)
            if envelope.reply_to is not None:
                envelope.reply_to.set(response)
        except Exception:
            if envelope.reply_to is not None:
                logger.info("Exception returned from %s to caller:", self, exc_info=True)
                envelope.reply_to.set_exception()
            else:
                self.failed(sys.exc_info())  # type: ignore[arg-type]
        except BaseException as exc:
            exc_info: ExcInfo = sys.exc_info()  # type: ignore[assignment]
            if envelope.reply_to is not None:
                # Answered (Pykka leaves the asker waiting): with an ordinary exception.
                answer = ActorExit(f"{exc!r} in {self}")
                answer.__cause__ = exc
                envelope.reply_to.set_exception(exc_info=(ActorExit, answer, exc.__traceback__))
            self.exited(exc_info)

    def refuse(self, envelope: Envelope[Any]) -> None:
        """Answer an envelope that arrived after the actor stopped (Pykka's teardown)."""
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

    def die(self, exc_info: ExcInfo) -> None:
        """Log ``exc_info`` with its traceback, unregister and stop (Pykka's failure path)."""
        self._handle_failure(*exc_info)
