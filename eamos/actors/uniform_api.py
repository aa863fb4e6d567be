"""The uniform-API actor (paper Figure 4): one per drone, owning that drone's adapter.

Other actors talk to it only with the typed messages below.  It starts uniform
actions on the adapter, relays cancellations and aborts, and answers every
:class:`RunAction` with exactly one :class:`ActionFinished` sent to its
``reply_to``, whatever happens: unknown action, adapter exception, vehicle
failure or the actor stopping.

Each action is decoded once, here, into a typed
:class:`~eamos.program.uniform.Command` (:func:`~eamos.program.uniform.decode_command`);
a plugin action (docs/plugins.md) is decoded with the parameter list of the plugin the
adapter's ``plugins`` registry provides, into a
:class:`~eamos.program.uniform.PluginAction`.  A call that does not decode fails without
reaching the adapter.  Failure
policy: an exception raised by the adapter's ``run`` or ``cancel`` ends that
action ``failed`` ("internal error in the adapter: ..."), logged once with its
traceback in the uniform log, and the actor keeps serving.

The adapter's completion callback runs on an adapter thread (or even inside
``adapter.run``), so it only posts a private message back to this actor; all
bookkeeping happens on the actor's thread.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any

import pykka

from eamos.hal.api import ActionHandle, ActionResult, Adapter, AdapterError, Telemetry
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry
from eamos.program.uniform import CommandError, decode_command

from .failure import tell_operator


@dataclass(frozen=True)
class RunAction:
    """Start ``action(*args)``; the answer goes to ``reply_to`` as :class:`ActionFinished`.

    ``token`` identifies the request for :class:`CancelAction` and in the reply;
    the sender picks it and keeps it unique among its running actions.
    """

    token: Hashable
    action: str
    args: tuple[float, ...]
    reply_to: pykka.ActorRef[Any]


@dataclass(frozen=True)
class CancelAction:
    """Cancel the action started with ``token``; unknown or finished tokens are ignored."""

    token: Hashable


@dataclass(frozen=True)
class Abort:
    """Cancel every running action and land the vehicle (the adapter's ``abort``)."""


@dataclass(frozen=True)
class ActionFinished:
    """The one reply to a :class:`RunAction`; times are epoch seconds (``time.time()``)."""

    token: Hashable
    action: str
    args: tuple[float, ...]
    result: ActionResult
    start_s: float
    end_s: float


@dataclass(frozen=True)
class _AdapterDone:
    """Private: the adapter's done callback, posted back to the actor's own thread."""

    token: Hashable
    serial: int  # which run of this token (tokens may be reused after they finish)
    result: ActionResult


@dataclass
class _Running:
    request: RunAction
    start_s: float
    serial: int
    handle: ActionHandle | None = None


class UniformAPI(pykka.ThreadingActor):
    """The uniform-API actor of one drone (see module docstring)."""

    def __init__(
        self,
        adapter: Adapter,
        uniform_log: Any,
        on_telemetry: Callable[[Telemetry], None],
        on_start_error: Callable[[AdapterError], None] | None = None,
    ) -> None:
        """Own ``adapter``; ``on_telemetry`` receives every sample (on adapter threads).

        ``on_start_error`` (optional) is told when ``adapter.start`` fails, before
        the actor stops: pykka only logs exceptions raised in ``on_start``, so
        this is how a runtime learns why the drone is unusable.
        """
        super().__init__()
        self.adapter = adapter
        self.drone = adapter.drone
        self._log = uniform_log
        self._on_telemetry = on_telemetry
        self._on_start_error = on_start_error
        self._running: dict[Hashable, _Running] = {}
        self._serials = itertools.count(1)
        # The plugin actions this adapter knows, with their parameter lists (an
        # adapter without ``plugins`` knows none; docs/plugins.md).
        plugins: PluginRegistry = getattr(adapter, "plugins", EMPTY_PLUGINS)
        self._plugin_specs = plugins.specs()

    # -- lifecycle -----------------------------------------------------------

    def on_start(self) -> None:
        """Start the adapter; an :class:`AdapterError` is logged and re-raised."""
        self._log.info("uniform.start", drone=self.drone)
        try:
            self.adapter.start(self._on_telemetry)
        except AdapterError as exc:
            self._log.error("uniform.start_failed", error=str(exc))
            if self._on_start_error is not None:
                try:
                    self._on_start_error(exc)
                except Exception as cb_exc:
                    self._log.exception("uniform.callback_error", error=repr(cb_exc))
            self._close_adapter()  # on_stop is not called when on_start fails
            raise

    def on_stop(self) -> None:
        """Close the adapter; answer actions still running with ``cancelled``."""
        self._shutdown(ActionResult("cancelled", "uniform API stopped"))
        self._log.info("uniform.stop", drone=self.drone)

    def on_failure(self, exception_type: Any, exception_value: Any, traceback: Any) -> None:
        """A bug killed the actor: answer running actions ``failed``, and land the vehicle.

        The adapter stays open (the runtime closes it when it stops), so the
        landing can finish: land must be reachable whatever actor died.
        """
        self._log.error("uniform.failure", error=repr(exception_value))
        tell_operator(self.drone, f"internal error in the uniform API: {exception_value!r}: lands")
        result = ActionResult("failed", f"uniform API crashed: {exception_value!r}")
        for token, running in list(self._running.items()):
            self._reply(token, running, result)
        try:
            self.adapter.abort()
        except Exception as exc:
            self._log.exception("uniform.adapter_error", action="abort", error=repr(exc))

    def _shutdown(self, result: ActionResult) -> None:
        # Close first: the adapter's late done callbacks then meet a dead actor
        # and are dropped, so every caller gets exactly one answer (this one).
        self._close_adapter()
        for token, running in list(self._running.items()):
            self._reply(token, running, result)

    # -- messages ------------------------------------------------------------

    def on_receive(self, message: Any) -> Any:
        """Dispatch one of :class:`RunAction`, :class:`CancelAction`, :class:`Abort`."""
        match message:
            case RunAction():
                self._run(message)
            case CancelAction(token=token):
                self._cancel(token)
            case Abort():
                self._abort()
            case _AdapterDone():
                self._done(message)
            case _:
                self._log.warning("uniform.unknown_message", message=repr(message))
        return None

    def _run(self, req: RunAction) -> None:
        start_s = time.time()
        self._log.info(
            "uniform.call", token=_jsonable(req.token), action=req.action, args=list(req.args)
        )
        if req.token in self._running:
            # Never displace the running entry: its reply would be lost.
            self._reply_now(req, start_s, ActionResult("failed", "duplicate token"))
            return
        try:
            # Decoded once, here: adapters dispatch on the command's class.
            command = decode_command(req.action, req.args, self._plugin_specs)
        except CommandError as exc:
            self._reply_now(req, start_s, ActionResult("failed", str(exc)))
            return
        running = self._running[req.token] = _Running(req, start_s, next(self._serials))
        try:
            handle = self.adapter.run(command, self._done_callback(req.token, running.serial))
        except Exception as exc:  # an adapter bug must not kill the drone's actor
            self._running.pop(req.token, None)
            self._reply_now(req, start_s, self._internal_error(req.action, exc))
            return
        running.handle = handle

    def _done_callback(self, token: Hashable, serial: int) -> Callable[[ActionResult], None]:
        actor_ref = self.actor_ref

        def done(result: ActionResult) -> None:
            # Runs on an adapter thread, or inside adapter.run() itself: either
            # way the result is handled later, in order, on the actor's thread.
            try:
                actor_ref.tell(_AdapterDone(token, serial, result))
            except pykka.ActorDeadError:
                pass  # the actor stopped; on_stop already answered the caller

        return done

    def _done(self, msg: _AdapterDone) -> None:
        running = self._running.get(msg.token)
        if running is None or running.serial != msg.serial:
            # A second done for one run (an adapter bug) or a late one after stop.
            self._log.warning("uniform.stray_result", token=_jsonable(msg.token))
            return
        self._reply(msg.token, running, msg.result)

    def _cancel(self, token: Hashable) -> None:
        running = self._running.get(token)
        self._log.info("uniform.cancel", token=_jsonable(token), running=running is not None)
        if running is None or running.handle is None:
            return  # unknown or finished: nothing to cancel
        try:
            self.adapter.cancel(running.handle)
        except Exception as exc:  # the action's state is unknown: it ends failed, once
            self._reply(token, running, self._internal_error("cancel", exc))

    def _abort(self) -> None:
        self._log.info("uniform.abort", running=len(self._running))
        try:
            self.adapter.abort()
        except Exception as exc:
            self._log.exception("uniform.adapter_error", action="abort", error=repr(exc))

    # -- helpers -------------------------------------------------------------

    def _internal_error(self, call: str, exc: Exception) -> ActionResult:
        """Log an adapter's exception once, with its traceback; the action's failure."""
        self._log.exception("uniform.adapter_error", call=call, error=repr(exc))
        return ActionResult("failed", f"internal error in the adapter: {exc!r}")

    def _reply(self, token: Hashable, running: _Running, result: ActionResult) -> None:
        self._running.pop(token, None)
        self._reply_now(running.request, running.start_s, result)

    def _reply_now(self, req: RunAction, start_s: float, result: ActionResult) -> None:
        end_s = time.time()
        self._log.info(
            "uniform.result",
            token=_jsonable(req.token),
            action=req.action,
            args=list(req.args),
            status=result.status,
            reason=result.reason,
            start_s=round(start_s, 6),
            end_s=round(end_s, 6),
            duration_s=round(end_s - start_s, 6),
        )
        try:
            req.reply_to.tell(
                ActionFinished(req.token, req.action, req.args, result, start_s, end_s)
            )
        except pykka.ActorDeadError:
            self._log.warning("uniform.reply_to_dead", token=_jsonable(req.token))

    def _close_adapter(self) -> None:
        try:
            self.adapter.close()
        except Exception as exc:
            self._log.exception("uniform.adapter_error", action="close", error=repr(exc))


def _jsonable(token: Hashable) -> Any:
    """Tokens go into JSON logs; keep simple ones as they are, stringify the rest."""
    return token if isinstance(token, str | int | float) else repr(token)
