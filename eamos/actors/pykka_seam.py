"""The one place where EAMOS touches Pykka's internals (tested range: :data:`PYKKA_TESTED`).

Pykka's public API lets a program *use* actors; a new kind of actor loop
(Pykka's own :class:`pykka.ThreadingActor` is one) must implement the hooks
Pykka documents as "internal methods for implementors of new actor types":
``_create_actor_inbox``, ``_create_future``, ``_start_actor_loop``, and then
handle what arrives in the inbox: envelopes (``message``, ``reply_to``),
Pykka's private stop message, proxy calls (``_handle_receive``), and failures
(``_handle_failure``, ``_stop``).  :mod:`.dispatch` runs actors on a shared
thread pool, so it needs exactly that; an actor library of our own would need
no internals but would lose Pykka's refs, proxies and futures that the rest of
the runtime (the uniform API, the board, the executive) shares with it.

So every such use is here, and nowhere else: :class:`ExternalLoopActor` is a
Pykka actor whose loop is driven from outside, one envelope at a time, with
Pykka's own semantics (reply or exception to an ``ask``; a ``BaseException``
stops the actor and every other actor, as Pykka does).  ``pyproject.toml``
pins Pykka to ``>=4.1,<4.6`` (:data:`PYKKA_TESTED`), and
``tests/actors/test_dispatch.py`` fails if the internals used here change
shape (:func:`shape_problems`) or behaviour.
"""

from __future__ import annotations

import inspect
import logging
import sys
from types import TracebackType
from typing import TYPE_CHECKING, Any

import pykka
from pykka import ActorDeadError, ActorRegistry, messages

if TYPE_CHECKING:
    from pykka._envelope import Envelope as Envelope

__all__ = ["PYKKA_TESTED", "ExcInfo", "ExternalLoopActor", "shape_problems"]

logger = logging.getLogger(__name__)

#: The Pykka range pyproject.toml allows (``>=4.1,<4.6``; keep the two in step).  The
#: test suite ran on 4.5.0; a newer Pykka must pass ``test_dispatch.py`` before the
#: upper bound moves.
PYKKA_TESTED = (4, 1), (4, 6)

ExcInfo = tuple[type[BaseException], BaseException, TracebackType | None]


class ExternalLoopActor(pykka.Actor):
    """A Pykka actor whose messages are handed to it by someone else's thread.

    Subclasses provide :meth:`new_inbox` (anything with ``put``/``get``/``empty``)
    and :meth:`loop_started` (called by ``start()`` once the actor is
    registered), then call :meth:`begin` once and :meth:`deliver` for each
    envelope, never two at once.  :meth:`failed` decides what an exception in
    a ``tell``-ed message does (by default what Pykka does: log, stop).
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

    # -- the loop, one step at a time ------------------------------------------------------

    def begin(self) -> None:
        """Run ``on_start`` as Pykka does (an exception is logged and stops the actor)."""
        try:
            self._actor_loop_setup()
        except BaseException as exc:
            self._stop_everything(exc)

    def deliver(self, envelope: Envelope[Any]) -> None:
        """Handle one envelope exactly as ``pykka.Actor._actor_loop_running`` does."""
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
            self._stop_everything(exc)

    def _stop_everything(self, exc: BaseException) -> None:
        # Pykka's branch for SystemExit, KeyboardInterrupt ...: stop this actor and
        # every other one.  Not blocking: this runs on a shared worker, which the
        # other pooled actors need to handle their stop message.
        logger.debug("%r in %s. Stopping all actors.", exc, self)
        self._stop()
        ActorRegistry.stop_all(block=False)

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


# -- the shape of what is used above ------------------------------------------------------


def _params(func: Any) -> list[str]:
    return [p for p in inspect.signature(func).parameters if p != "self"]


def shape_problems() -> list[str]:
    """What changed in Pykka's internals that this module relies on (empty: nothing)."""
    from importlib import metadata  # here: a node's start-up never needs it (20 ms)

    problems: list[str] = []
    version = tuple(int(p) for p in metadata.version("pykka").split(".")[:2])
    low, high = PYKKA_TESTED
    if not low <= version < high:
        problems.append(f"pykka {version} is outside the tested range {low} .. < {high}")
    abstract = set(getattr(pykka.Actor, "__abstractmethods__", ()))
    if abstract != {"_create_actor_inbox", "_create_future", "_start_actor_loop"}:
        problems.append(f"pykka.Actor's hooks for new actor types are now {sorted(abstract)}")
    expected = {
        "_handle_receive": ["message"],
        "_actor_loop_setup": [],
        "_handle_failure": ["exception_type", "exception_value", "traceback"],
        "_stop": [],
        "on_failure": ["exception_type", "exception_value", "traceback"],
    }
    for name, params in expected.items():
        method = getattr(pykka.Actor, name, None)
        if method is None:
            problems.append(f"pykka.Actor.{name} is gone")
        elif _params(method) != params:
            problems.append(f"pykka.Actor.{name} takes {_params(method)}, not {params}")
    if not isinstance(getattr(messages, "_ActorStop", None), type):
        problems.append("pykka.messages._ActorStop is gone")
    try:
        from pykka._envelope import Envelope as Env

        if set(getattr(Env, "__slots__", ())) != {"message", "reply_to"}:
            problems.append(f"pykka's Envelope now holds {getattr(Env, '__slots__', '?')}")
    except ImportError:
        problems.append("pykka._envelope.Envelope is gone")
    return problems
