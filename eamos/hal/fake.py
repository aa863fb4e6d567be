"""The project's only fake vehicle, at the adapter seam, for unit tests of actors.

:class:`FakeAdapter` records every call.  With ``auto=True`` every action
finishes ``ok`` at once (or with the result configured for it in
``results``); otherwise the test decides when and how each action ends::

    fake = FakeAdapter("D1")
    ...                                    # code under test calls fake.run(Arm(), done)
    handle = fake.wait_started("Arm", timeout=10)
    fake.finish(handle, ActionResult("ok"))
    fake.push_telemetry(z_m=5.0, armed=True)

All waiting uses a :class:`threading.Condition`; nothing sleeps.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from eamos.hal.api import (
    ActionHandle,
    ActionResult,
    AdapterError,
    DoneCallback,
    Telemetry,
    TelemetryCallback,
)
from eamos.hal.settings import COMMON_KEYS, check_keys, field_error, require_mapping
from eamos.program.plugins import EMPTY_PLUGINS, PluginRegistry, discover_plugins
from eamos.program.uniform import Command

if TYPE_CHECKING:
    from eamos.logs import EventLog


@dataclass(slots=True)
class Call:
    """One recorded call: ``method`` is start/run/cancel/abort/close/finish.

    Not frozen: one is made per action on the trigger path of a fake-driven run (the
    benchmarks'), and a frozen dataclass builds itself field by field through
    ``object.__setattr__``; nothing changes a call once recorded."""

    method: str
    action: str = ""
    args: tuple[float, ...] = ()
    handle: ActionHandle | None = None
    # ``run``: the typed command the adapter received (not compared: tests name calls)
    command: Command | None = dataclasses.field(default=None, compare=False)


class FakeAdapter:
    """A scriptable :class:`~eamos.hal.api.Adapter` that records its calls (thread-safe)."""

    def __init__(
        self,
        drone: str = "D1",
        *,
        auto: bool = False,
        results: Mapping[str, ActionResult] | None = None,
        run_errors: Mapping[str, Exception] | None = None,
        start_error: AdapterError | None = None,
        plugins: PluginRegistry = EMPTY_PLUGINS,
    ) -> None:
        """Create a fake for ``drone``.

        ``auto``: finish every action at once (with ``results[action]`` if
        given, else ``ok``).  ``run_errors``: ``run`` raises this exception for
        these actions (to test callers' error handling).  ``start_error``:
        ``start`` raises it (an unreachable vehicle).
        """
        self.drone = drone
        # It stands in for the simulator: the plugin actions it accepts (the uniform
        # API decodes them with these parameter lists) are recorded like any action.
        self.family = "sim"
        self.plugins = plugins
        self.auto = auto
        self._results = dict(results or {})
        self._run_errors = dict(run_errors or {})
        self._start_error = start_error
        self._cond = threading.Condition()
        self._calls: list[Call] = []
        self._started: list[ActionHandle] = []
        self._running: dict[int, tuple[ActionHandle, DoneCallback]] = {}
        self._finished: dict[int, ActionResult] = {}
        self._on_telemetry: TelemetryCallback | None = None
        self._last = Telemetry(
            drone=drone,
            time_s=time.time(),
            x_m=0.0,
            y_m=0.0,
            z_m=0.0,
            lat_deg=46.6103,
            lon_deg=14.2640,
            alt_m=0.0,
            battery_pct=100.0,
            armed=False,
            landed=True,
        )
        self.closed = False

    # -- Adapter protocol ----------------------------------------------------

    def start(self, on_telemetry: TelemetryCallback) -> None:
        """Record the call, remember the callback and send one initial sample."""
        with self._cond:
            self._record(Call("start"))
            if self._start_error is not None:
                raise self._start_error
            self._on_telemetry = on_telemetry
            sample = self._last = dataclasses.replace(self._last, time_s=time.time())
        on_telemetry(sample)

    def run(self, command: Command, done: DoneCallback) -> ActionHandle:
        """Record and start ``command``; with ``auto`` it finishes before returning."""
        handle = ActionHandle.of(command)
        action = command.action
        with self._cond:
            self._record(Call("run", action, command.args, handle, command))
            error = self._run_errors.get(action)
            if error is not None:
                raise error
            self._started.append(handle)
            self._running[handle.id] = (handle, done)
            self._cond.notify_all()
        if self.auto:
            # _complete, not finish(): a concurrent cancel may have won the race.
            self._complete(handle, self._results.get(action, ActionResult("ok")))
        return handle

    def cancel(self, handle: ActionHandle) -> None:
        """Record; a running action finishes ``cancelled``."""
        with self._cond:
            self._record(Call("cancel", handle.action, handle.args, handle))
            running = handle.id in self._running
        if running:
            self._complete(handle, ActionResult("cancelled", "cancelled"))

    def abort(self) -> None:
        """Record; every running action finishes ``cancelled`` ("aborted")."""
        with self._cond:
            self._record(Call("abort"))
            handles = [h for h, _ in self._running.values()]
        for handle in handles:
            self._complete(handle, ActionResult("cancelled", "aborted"))

    def close(self) -> None:
        """Record (every time) and mark closed."""
        with self._cond:
            self._record(Call("close"))
            self.closed = True

    # -- test controls -------------------------------------------------------

    def finish(self, which: ActionHandle | str, result: ActionResult | None = None) -> ActionHandle:
        """Finish a running action (a handle, or the oldest running one with that name).

        Raises :class:`LookupError` if no such action is running.
        """
        result = result if result is not None else ActionResult("ok")
        with self._cond:
            handle = self._find_running(which)
            if handle is None:
                raise LookupError(f"no running action {which!r}")
        self._complete(handle, result)
        return handle

    def push_telemetry(self, **fields: Any) -> Telemetry:
        """Send a sample: the previous one with ``fields`` changed and a fresh time."""
        with self._cond:
            fields.setdefault("time_s", time.time())
            sample = self._last = dataclasses.replace(self._last, **fields)
            callback = self._on_telemetry
        if callback is None:
            raise RuntimeError("push_telemetry before start()")
        callback(sample)
        return sample

    def wait_started(self, action: str, timeout: float, count: int = 1) -> ActionHandle:
        """Wait until ``action`` has been started ``count`` times; return that run's handle.

        Raises :class:`TimeoutError` after ``timeout`` seconds.
        """

        def nth() -> ActionHandle | None:
            matches = [h for h in self._started if h.action == action]
            return matches[count - 1] if len(matches) >= count else None

        with self._cond:
            if not self._cond.wait_for(lambda: nth() is not None, timeout):
                raise TimeoutError(f"{action} not started {count} time(s) within {timeout} s")
            handle = nth()
            assert handle is not None
            return handle

    def wait_for(self, predicate: Callable[[FakeAdapter], bool], timeout: float) -> None:
        """Wait until ``predicate(self)`` holds (re-checked on every call); TimeoutError."""
        with self._cond:
            if not self._cond.wait_for(lambda: predicate(self), timeout):
                raise TimeoutError(f"condition not met within {timeout} s")

    @property
    def calls(self) -> list[Call]:
        """Every recorded call, oldest first."""
        with self._cond:
            return list(self._calls)

    def calls_of(self, method: str) -> list[Call]:
        """Recorded calls of one method (``"run"``, ``"cancel"`` ...)."""
        return [c for c in self.calls if c.method == method]

    @property
    def running(self) -> list[ActionHandle]:
        """Actions started and not finished yet."""
        with self._cond:
            return [h for h, _ in self._running.values()]

    def result_of(self, handle: ActionHandle) -> ActionResult | None:
        """How ``handle`` finished, or None while it runs."""
        with self._cond:
            return self._finished.get(handle.id)

    # -- internals -----------------------------------------------------------

    def _record(self, call: Call) -> None:
        self._calls.append(call)
        self._cond.notify_all()

    def _find_running(self, which: ActionHandle | str) -> ActionHandle | None:
        if isinstance(which, ActionHandle):
            entry = self._running.get(which.id)
            return entry[0] if entry else None
        for handle, _ in self._running.values():  # dicts keep start order: oldest first
            if handle.action == which:
                return handle
        return None

    def _complete(self, handle: ActionHandle, result: ActionResult) -> None:
        with self._cond:
            entry = self._running.pop(handle.id, None)
            if entry is None:
                return  # finished meanwhile: done must be called only once
            self._finished[handle.id] = result
            self._record(Call("finish", handle.action, handle.args, handle))
        # Outside the lock: done may call back into the fake.
        entry[1](result)


def fake_adapter_from_settings(
    drone: str, settings: Mapping[str, Any], adapter_log: EventLog | None = None
) -> FakeAdapter:
    """A :class:`FakeAdapter` from ``hal`` settings (only ``auto``, a bool, is accepted).

    Like the simulator it stands for, it accepts the installed plugin actions.
    """
    settings = require_mapping(settings, "hal")
    check_keys(settings, COMMON_KEYS | {"auto"}, "hal")
    auto = settings.get("auto", True)
    if not isinstance(auto, bool):
        raise field_error("hal.auto", f"expected true or false, got {auto!r}")
    return FakeAdapter(drone, auto=auto, plugins=discover_plugins())
