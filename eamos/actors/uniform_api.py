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

The bookkeeping (which actions run, one answer each) is :class:`UniformSpace`,
safe to call from any thread: the adapter's completion callback (on an adapter
thread, or inside ``adapter.run``) answers the asker directly, with no hop back
through this actor.  With an adapter that answers at once (the simulator, the
fake: :func:`answers_at_once`) node actors call the space themselves, so a
zero-duration action costs no thread hop at all; an adapter that may block (a
MAVLink autopilot) is called from this actor's thread only.

The pilot's hand: once the adapter says a pilot has taken the vehicle
(:func:`~eamos.hal.api.taken_over`), nothing here commands it again: every action
fails with "taken over by the pilot (MODE)" without reaching the adapter, a cancel
or an abort (land) is not passed on, and an actor failure does not land it
(:meth:`UniformSpace.pilot_has_it`).  What the adapter tells the operator
(:func:`~eamos.hal.api.adapter_notices`: a takeover, slow telemetry) goes to
``on_notice`` (the runtime sends it to the ground station).

A node that calls the space directly may ask for the ``uniform.result`` line of an
action answered inline to be written late (``run(..., later=True)``), once its
triggers to other drones are out: the uniform log (:class:`UniformLog`) writes such
held lines before any other line of its own, so the file keeps the order of events.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace
from types import TracebackType

import pykka

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    Adapter,
    AdapterError,
    AdapterNotice,
    TakenOver,
    Telemetry,
    adapter_notices,
    taken_over,
)
from eamos.logs import EventLog
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry
from eamos.program.uniform import ACTIONS, Command, CommandError, ReturnHome, decode_command

from .failure import tell_operator
from .messages import Mailbox
from .operator import (
    RELEASED,
    TAKEN_OUT,
    Operate,
    adapter_time_s,
    remaining_command,
    suspendable,
)
from .uniform_log import UniformLog, jsonable, result_fields


@dataclass(frozen=True)
class RunAction:
    """Start ``action(*args)``; the answer goes to ``reply_to`` as :class:`ActionFinished`.

    ``token`` identifies the request for :class:`CancelAction` and in the reply;
    the sender picks it and keeps it unique among its running actions.
    """

    token: Hashable
    action: str
    args: tuple[float, ...]
    reply_to: Mailbox[ActionFinished]


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


@dataclass
class _Running:
    """An action the adapter runs: its request, start, serial number and handle."""

    request: RunAction
    start_s: float
    serial: int
    handle: ActionHandle | None = None
    # Set while adapter.run() runs on ``caller``: a done() inside it is kept here,
    # and run() returns the reply instead of sending it (no message to itself).
    caller: int = 0
    inline: ActionResult | None = None
    # The operator's pause (.operator): the command, when it was last issued (adapter
    # clock), how long it ran before, where the vehicle was when it was asked for.
    command: Command | None = None
    issued_s: float = 0.0
    ran_s: float = 0.0
    start_xyz: tuple[float, float, float] | None = None
    suspended: bool = False


#: Adapter families whose calls never block: ``run`` queues the action under a
#: lock and returns, ``done`` comes later from the adapter's thread (or at once).
NON_BLOCKING_FAMILIES = frozenset({"sim"})


def answers_at_once(adapter: Adapter) -> bool:
    """True if node actors may call ``adapter`` directly, without the uniform-API actor's hop.

    An adapter says so with an ``answers_at_once`` attribute; otherwise its family
    decides (:data:`NON_BLOCKING_FAMILIES`: the simulator and the fake).  A MAVLink
    adapter waits for the autopilot: it keeps the actor.
    """
    declared = getattr(adapter, "answers_at_once", None)
    if isinstance(declared, bool):
        return declared
    return getattr(adapter, "family", "") in NON_BLOCKING_FAMILIES


class UniformSpace:
    """The uniform API's bookkeeping over one adapter, safe to call from any thread.

    The uniform-API actor calls it from its own thread; with an adapter that
    :func:`answers_at_once`, node actors call :meth:`run` and :meth:`cancel`
    directly (no hop through the actor).  Every :class:`RunAction` gets exactly
    one :class:`ActionFinished`: returned by :meth:`run` when the adapter finished
    it inside ``adapter.run`` on the calling thread (or it never reached the
    adapter), else sent to ``reply_to`` when the adapter's ``done`` comes, or by
    :meth:`finish_all` when the actor stops or fails.  The lock guards only the
    table of running actions; the adapter is never called with it held.
    """

    def __init__(self, adapter: Adapter, uniform_log: EventLog) -> None:
        self.adapter = adapter
        self.drone = adapter.drone
        self._log = self.log = (
            uniform_log if isinstance(uniform_log, UniformLog) else UniformLog(uniform_log)
        )
        self._lock = threading.Lock()
        self._running: dict[Hashable, _Running] = {}
        self._serials = itertools.count(1)
        self._closed = False
        # The plugin actions this adapter knows (an adapter without ``plugins`` knows
        # none; docs/plugins.md), read only when a plugin action comes: a registry looks
        # entry points up on first use, and a mission without plugin actions never pays
        # for importlib.metadata.
        self._plugins: PluginRegistry = getattr(adapter, "plugins", EMPTY_PLUGINS)
        #: Told each notice the adapter has for the operator (the runtime: to the ground).
        self.on_notice: Callable[[AdapterNotice], None] | None = None
        self._has_notices = callable(getattr(adapter, "notices", None))
        #: Told the autopilot's own mode and new (severity, STATUSTEXT)s as they change.
        self.on_status: Callable[[str, list[tuple[int, str]]], None] | None = None
        # The operator's (.operator); _retired: adapter runs a suspension ended.
        self._paused = False
        self._out = ""
        self._released: TakenOver | None = None
        self._going_home = False
        self._retired: set[int] = set()
        self._here: tuple[float, float, float] | None = None

    # -- the pilot's hand ----------------------------------------------------------------

    def pilot_has_it(self, call: str) -> TakenOver | None:
        """The adapter's takeover, if a pilot has the vehicle: then ``call`` (an action,
        a cancel, an abort) is not passed on, and that is logged."""
        taken = taken_over(self.adapter) or self._released
        if taken is not None:
            self.forward_notices()
            self._log.warning("uniform.taken_over", call=call, reason=taken.reason())
        return taken

    def forward_notices(self) -> None:
        """Hand what the adapter has for the operator to ``on_notice`` (any thread)."""
        if not self._has_notices:
            return
        for notice in adapter_notices(self.adapter):
            self._log.warning("uniform.notice", kind=notice.kind, text=notice.text)
            if self.on_notice is not None:
                try:
                    self.on_notice(notice)
                except Exception as exc:  # the operator's line must not cost the drone
                    self._log.exception("uniform.callback_error", error=repr(exc))

    def run(self, req: RunAction, later: bool = False) -> ActionFinished | None:
        """Start ``req`` on the adapter; its :class:`ActionFinished` if already known.

        ``later``: the ``uniform.result`` line of an action answered here is held
        until :meth:`write_results` (or the log's next line): the caller's urgent
        work (triggers to other drones) goes first.
        """
        start_s = time.time()
        self._log.info(
            "uniform.call", token=jsonable(req.token), action=req.action, args=list(req.args)
        )
        with self._lock:
            refusal = (
                ActionResult("cancelled", "uniform API stopped")
                if self._closed
                # Never displace the running entry: its reply would be lost.
                else ActionResult("failed", "duplicate token")
                if req.token in self._running
                else None
            )
        if refusal is not None:
            return self._finished(req, start_s, refusal)
        try:
            # Decoded once, here: adapters dispatch on the command's class.
            specs = None if req.action in ACTIONS else self._plugins.specs()
            command = decode_command(req.action, req.args, specs)
        except CommandError as exc:
            return self._finished(req, start_s, ActionResult("failed", str(exc)))
        taken = self.pilot_has_it(req.action)
        if taken is not None:  # never command a vehicle a pilot has
            return self._finished(req, start_s, ActionResult("failed", taken.reason()))
        running = _Running(
            req, start_s, next(self._serials), caller=threading.get_ident(), command=command
        )
        running.issued_s = adapter_time_s(self.adapter)
        with self._lock:  # tokens are unique per asker: nobody took it since the check
            out = self._out
            if not out:
                self._running[req.token] = running
                running.start_xyz = self._here
                running.suspended = self._paused and suspendable(command)
        if out:  # taken out of the mission by the operator
            return self._finished(req, start_s, ActionResult("failed", out))
        if running.suspended:  # paused: it starts on resume
            self._log.info("uniform.suspended", token=jsonable(req.token), queued=True)
            return None
        try:
            handle = self.adapter.run(command, self._done_callback(req.token, running.serial))
        except Exception as exc:  # an adapter bug must not kill the drone's actor
            with self._lock:
                self._running.pop(req.token, None)
            running.caller = 0
            return self._finished(req, start_s, self._internal_error(req.action, exc))
        running.caller = 0
        running.handle = handle
        if running.inline is not None:
            return self._finished(req, start_s, running.inline, later)
        if running.suspended:  # a pause came while the adapter took it
            _cancel_quietly(self.adapter, self._log, handle)
        return None

    def write_results(self) -> None:
        """Write the ``uniform.result`` lines ``run(..., later=True)`` held."""
        self._log.write_held()

    def _done_callback(self, token: Hashable, serial: int) -> Callable[[ActionResult], None]:
        def done(result: ActionResult) -> None:
            # Runs on an adapter thread, or inside adapter.run() itself.
            with self._lock:
                if serial in self._retired:  # ended by a suspension or a take-out
                    self._retired.discard(serial)
                    return
                running = self._running.get(token)
                if running is None or running.serial != serial:
                    stray = not self._closed
                    running = None
                else:
                    del self._running[token]
            if running is None:
                if stray:  # a second done for one run (an adapter bug)
                    self._log.warning("uniform.stray_result", token=jsonable(token))
                return  # else: late, after stop; finish_all already answered the caller
            if running.caller == threading.get_ident():
                running.inline = result  # run() returns it
                return
            self._send(running.request, running.start_s, result)
            self.forward_notices()

        return done

    def cancel(self, token: Hashable) -> None:
        """Cancel the action started with ``token`` (unknown or finished: nothing happens)."""
        with self._lock:
            running = self._running.get(token)
            if running is not None and running.suspended:  # paused: it ends here, now
                del self._running[token]
        self._log.info("uniform.cancel", token=jsonable(token), running=running is not None)
        if running is not None and running.suspended:
            self._send(running.request, running.start_s, ActionResult("cancelled", "cancelled"))
            return
        if running is None or running.handle is None:
            return  # unknown or finished: nothing to cancel
        taken = self.pilot_has_it("cancel")
        if taken is not None:  # no braking, no hold: the action just ends
            with self._lock:
                mine = self._running.pop(token, None) is running
            if mine:
                self._send(running.request, running.start_s, ActionResult("failed", taken.reason()))
            return
        try:
            self.adapter.cancel(running.handle)
        except Exception as exc:  # the action's state is unknown: it ends failed, once
            with self._lock:
                mine = self._running.pop(token, None) is running
            if mine:
                self._send(running.request, running.start_s, self._internal_error("cancel", exc))

    def abort(self) -> None:
        """Cancel every running action and land (the adapter's ``abort``)."""
        with self._lock:
            count = len(self._running)
        self._log.info("uniform.abort", running=count)
        self.abort_vehicle()

    def abort_vehicle(self) -> None:
        """The adapter's ``abort`` (land), unless a pilot has the vehicle; never raises."""
        taken = self.pilot_has_it("abort")
        if taken is not None:  # no landing, no disarm: the running actions just end
            self.finish_all(ActionResult("failed", taken.reason()), close=False)
            return
        if self._going_home:  # the operator sent it home: it lands there
            self._log.info("uniform.abort.going_home")
            return
        try:
            self.adapter.abort()
        except Exception as exc:
            self._log.exception("uniform.adapter_error", action="abort", error=repr(exc))

    def finish_all(self, result: ActionResult, close: bool) -> None:
        """Answer every running action with ``result``; ``close``: close the adapter first
        (its late done callbacks are then dropped, so each caller gets one answer)."""
        if close:
            with self._lock:
                self._closed = True
            self.close_adapter()
        with self._lock:
            running, self._running = list(self._running.values()), {}
        for entry in running:
            self._send(entry.request, entry.start_s, result)

    # -- the operator's commands (.operator) ------------------------------------------------

    @property
    def released(self) -> TakenOver | None:
        """The operator released the vehicle to a pilot, where (until a ``resume``)."""
        return self._released

    def note_sample(self, sample: Telemetry) -> None:  # where an action asked for now starts
        self._here = (sample.x_m, sample.y_m, sample.z_m)

    def operate(self, command: str) -> None:
        """Carry out the operator's ``command`` (:data:`~.operator.COMMANDS`) on this vehicle."""
        if command in ("pause", "hold"):
            self.suspend(command)
        elif command == "resume":
            self.resume()
        elif command in TAKEN_OUT:
            self.take_out(command)

    def suspend(self, why: str = "pause") -> None:
        """Suspend every running move and timed wait: the vehicle holds (the adapter's
        cancel), the nodes keep waiting; what is asked for meanwhile waits too."""
        if self.pilot_has_it(why) is not None:
            return
        now = adapter_time_s(self.adapter)
        handles: list[ActionHandle] = []
        with self._lock:
            self._paused = True
            for entry in self._running.values():
                if entry.suspended or entry.command is None or not suspendable(entry.command):
                    continue
                entry.suspended = True
                self._retired.add(entry.serial)
                entry.ran_s += max(0.0, now - entry.issued_s)
                if entry.handle is not None:
                    handles.append(entry.handle)
        self._log.info("uniform.suspend", why=why, actions=len(handles))
        for handle in handles:
            _cancel_quietly(self.adapter, self._log, handle)

    def resume(self) -> None:
        """Hand a released vehicle back; issue every suspended action for what is left."""
        if self._released is not None:
            self._released = None
            self._log.warning("uniform.handed_back")
        with self._lock:
            self._paused = False
            entries = [e for e in self._running.values() if e.suspended]
            for entry in entries:
                entry.suspended = False
                entry.serial = next(self._serials)
        for entry in entries:
            assert entry.command is not None
            command = remaining_command(entry.command, entry.ran_s, entry.start_xyz)
            token = entry.request.token
            self._log.info(
                "uniform.resume",
                token=jsonable(token),
                action=entry.request.action,
                issued=command.action,
                args=list(command.args),
            )
            entry.issued_s = adapter_time_s(self.adapter)
            try:
                entry.handle = self.adapter.run(command, self._done_callback(token, entry.serial))
            except Exception as exc:
                with self._lock:
                    mine = self._running.pop(token, None) is entry
                if mine:
                    self._send(entry.request, entry.start_s, self._internal_error("resume", exc))

    def take_out(self, how: str) -> None:
        """Take the vehicle out of the mission (``land``, ``return-home``, ``release``):
        every action, running or later, fails with :data:`~.operator.TAKEN_OUT`."""
        reason = TAKEN_OUT[how]
        taken = self.pilot_has_it(how)
        with self._lock:
            if self._out:
                return
            self._out, self._paused = reason, False
            entries, self._running = list(self._running.values()), {}
            self._retired.update(e.serial for e in entries)
        self._log.warning("uniform.taken_out", how=how, actions=len(entries))
        for entry in entries:
            self._send(entry.request, entry.start_s, ActionResult("failed", reason))
        if taken is not None:
            return  # a pilot has it: nothing is commanded
        if how == "land":
            self.abort_vehicle()
            return
        for entry in entries:
            if entry.handle is not None and not entry.suspended:
                _cancel_quietly(self.adapter, self._log, entry.handle)  # it holds
        if how == "release":
            x, y, z = self._here or (None, None, None)
            self._released = replace(RELEASED, x_m=x, y_m=y, z_m=z)
            return
        self._going_home = True

        def home(result: ActionResult) -> None:  # then an abort may land it
            self._going_home = False

        try:
            self.adapter.run(ReturnHome(), home)
        except Exception as exc:
            self._going_home = False
            self._internal_error("ReturnHome", exc)
            self.abort_vehicle()

    def close_adapter(self) -> None:
        """Close the adapter; an exception is logged, never raised."""
        try:
            self.adapter.close()
        except Exception as exc:
            self._log.exception("uniform.adapter_error", action="close", error=repr(exc))

    def _internal_error(self, call: str, exc: Exception) -> ActionResult:
        """Log an adapter's exception once, with its traceback; the action's failure."""
        self._log.exception("uniform.adapter_error", call=call, error=repr(exc))
        return ActionResult("failed", f"internal error in the adapter: {exc!r}")

    def _finished(
        self, req: RunAction, start_s: float, result: ActionResult, later: bool = False
    ) -> ActionFinished:
        end_s = time.time()
        finished = ActionFinished(req.token, req.action, req.args, result, start_s, end_s)
        if later:
            self._log.hold(finished)
        else:
            self._log.info("uniform.result", **result_fields(finished))
        return finished

    def _send(self, req: RunAction, start_s: float, result: ActionResult) -> None:
        """Send the reply to the one who asked (a stopped asker is logged, not raised)."""
        _tell_reply(req.reply_to, self._finished(req, start_s, result), self._log)


class UniformAPI(pykka.ThreadingActor):
    """The uniform-API actor of one drone (see module docstring)."""

    def __init__(
        self,
        adapter: Adapter,
        uniform_log: EventLog,
        on_telemetry: Callable[[Telemetry], None],
        on_start_error: Callable[[AdapterError], None] | None = None,
        space: UniformSpace | None = None,
    ) -> None:
        """Own ``adapter``; ``on_telemetry`` receives every sample (on adapter threads).

        ``on_start_error`` (optional) is told when ``adapter.start`` fails, before
        the actor stops: pykka only logs exceptions raised in ``on_start``, so
        this is how a runtime learns why the drone is unusable.  ``space``: the
        bookkeeping node actors also call directly (built here when not given).
        """
        super().__init__()
        self.adapter = adapter
        self.drone = adapter.drone
        self._on_telemetry = on_telemetry
        self._on_start_error = on_start_error
        self.space = space if space is not None else UniformSpace(adapter, uniform_log)
        self._log = self.space.log  # one log object: held result lines keep their place
        # The autopilot's mode and STATUSTEXTs (an adapter with ``autopilot_status``).
        status = getattr(adapter, "autopilot_status", None)
        self._read_status: Callable[[], tuple[str, int, list[tuple[int, str]]]] | None = (
            status if callable(status) else None
        )
        self._status_seen: tuple[str, int] = ("", 0)

    # -- lifecycle -----------------------------------------------------------

    def on_start(self) -> None:
        """Start the adapter; an :class:`AdapterError` is logged and re-raised."""
        self._log.info("uniform.start", drone=self.drone)
        try:
            self.adapter.start(self._sample)
        except AdapterError as exc:
            self._start_failed(exc)
            raise
        except Exception:
            raise
        except BaseException as exc:  # SystemExit ... from the adapter's code: Pykka would
            # let it end this actor's thread unstopped, and the start would wait for ever.
            error = AdapterError(f"{self.drone}: the adapter raised {exc!r} while starting")
            self._start_failed(error)
            raise error from exc

    def _sample(self, sample: Telemetry) -> None:
        """A telemetry sample (adapter thread): to the board, with the adapter's notices."""
        self.space.note_sample(sample)
        self.space.forward_notices()
        self._forward_status()
        self._on_telemetry(sample)

    def _forward_status(self) -> None:
        """The autopilot's mode and new STATUSTEXTs, when they changed, to ``on_status``."""
        tell = self.space.on_status
        if self._read_status is None or tell is None:
            return
        mode, serial, texts = self._read_status()
        seen_mode, seen = self._status_seen
        if (mode, serial) == (seen_mode, seen):
            return
        self._status_seen = (mode, serial)
        try:
            tell(mode, texts[len(texts) - min(len(texts), serial - seen) :])
        except Exception as exc:  # the operator's page must not cost the drone
            self._log.exception("uniform.callback_error", error=repr(exc))

    def _start_failed(self, exc: AdapterError) -> None:
        self._log.error("uniform.start_failed", error=str(exc))
        if self._on_start_error is not None:
            try:
                self._on_start_error(exc)
            except Exception as cb_exc:
                self._log.exception("uniform.callback_error", error=repr(cb_exc))
        self.space.close_adapter()  # on_stop is not called when on_start fails

    def on_stop(self) -> None:
        """Close the adapter; answer actions still running with ``cancelled``."""
        self.space.finish_all(ActionResult("cancelled", "uniform API stopped"), close=True)
        self._log.info("uniform.stop", drone=self.drone)

    def on_failure(
        self,
        exception_type: type[BaseException] | None,
        exception_value: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        """A bug killed the actor: answer running actions ``failed``, and land the vehicle.

        The adapter stays open (the runtime closes it when it stops), so the
        landing can finish: land must be reachable whatever actor died.
        """
        self._log.error("uniform.failure", error=repr(exception_value))
        tell_operator(self.drone, f"internal error in the uniform API: {exception_value!r}: lands")
        result = ActionResult("failed", f"uniform API crashed: {exception_value!r}")
        self.space.finish_all(result, close=False)
        self.space.abort_vehicle()  # lands it, unless a pilot has it

    # -- messages ------------------------------------------------------------

    def on_receive(self, message: object) -> None:
        """Dispatch one of :class:`RunAction`, :class:`CancelAction`, :class:`Abort`.

        A ``BaseException`` from the adapter (``SystemExit``, ``KeyboardInterrupt``
        raised by its code: a real Ctrl-C reaches only the main thread) becomes this
        actor's failure (:meth:`on_failure`: the vehicle lands): Pykka would stop
        every actor of the process, the other drones' with them.
        """
        try:
            self._handle(message)
        except Exception:
            raise
        except BaseException as exc:
            raise RuntimeError(f"{exc!r} in the adapter") from exc
        return None

    def _handle(self, message: object) -> None:
        match message:
            case RunAction():
                finished = self.space.run(message)
                if finished is not None:
                    # Told from the actor's thread: a reply that raises is a bug of
                    # the actor (its failure policy lands the vehicle).
                    _tell_reply(message.reply_to, finished, self._log)
            case CancelAction(token=token):
                self.space.cancel(token)
            case Abort():
                self.space.abort()
            case Operate(command=command):
                self.space.operate(command)
            case _:
                self._log.warning("uniform.unknown_message", message=repr(message))


def start_uniform_api(
    space: UniformSpace, on_telemetry: Callable[[Telemetry], None]
) -> tuple[pykka.ActorRef[UniformAPI], AdapterError | None]:
    """Start the uniform-API actor over ``space``'s adapter and wait until it started it.

    Returns the actor and, when the adapter could not start (the actor then
    stopped), the adapter's error.
    """
    start_error: list[AdapterError] = []
    ref = UniformAPI.start(space.adapter, space.log, on_telemetry, start_error.append, space=space)
    try:
        # Answered only after on_start ran: the adapter is up, or the actor died.
        ref.proxy().drone.get(timeout=60)
    except pykka.ActorDeadError:
        pass
    if start_error or not ref.is_alive():
        return ref, start_error[0] if start_error else AdapterError("the adapter did not start")
    return ref, None


def _cancel_quietly(adapter: Adapter, log: EventLog, handle: ActionHandle) -> None:
    """The adapter's cancel (a suspension: the vehicle holds); an exception is logged."""
    try:
        adapter.cancel(handle)
    except Exception as exc:
        log.exception("uniform.adapter_error", action="cancel", error=repr(exc))


def _tell_reply(reply_to: Mailbox[ActionFinished], finished: ActionFinished, log: EventLog) -> None:
    try:
        reply_to.tell(finished)
    except pykka.ActorDeadError:
        log.warning("uniform.reply_to_dead", token=jsonable(finished.token))
