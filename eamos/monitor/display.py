"""The monitor as a display of the run loop: the terminal's display, teed to the hub.

:class:`TeeDisplay` is what :func:`eamos.ground.fly` gets when ``--monitor``
is on: every event goes to the usual display (lines or the live table) and
to the monitor's :class:`~.hub.Hub`; the hub only applies it and returns, so
a browser never slows the ground station.  :func:`start_live_monitor` builds
the hub and the server for a run folder and prints the address.
"""

from __future__ import annotations

import threading
import webbrowser
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.ground.amend import APPLY_TIMEOUT_S, read_applied
from eamos.ground.operator import OperatorError, send_command
from eamos.logs import make_logger

from .hub import Hub
from .server import MonitorServer
from .setup import load_setup

if TYPE_CHECKING:
    from eamos.ground.display import Display
    from eamos.ground.station import DroneView, GroundStation


class TeeDisplay:
    """A display that shows everything ``inner`` shows and feeds ``hub`` too."""

    def __init__(self, inner: Display, hub: Hub) -> None:
        self.inner = inner
        self.hub = hub
        self.refresh_s = inner.refresh_s

    def __enter__(self) -> TeeDisplay:
        self.inner.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self.inner.__exit__(*exc)

    def watch(self, station: GroundStation) -> None:
        """The inner display watches ``station``."""
        self.inner.watch(station)

    def event(self, name: str, view: DroneView, msg: Any) -> None:
        """To the terminal, then to the monitor (which never blocks)."""
        self.inner.event(name, view, msg)
        self.hub.event(name, msg)

    def refresh(self) -> None:
        """Redraw the terminal's table."""
        self.inner.refresh()

    def say(self, text: str) -> None:
        """Tell the operator (on the terminal)."""
        self.inner.say(text)

    def forecast(self, record: dict[str, Any]) -> None:
        """The look-ahead's latest cycle: to the page (predicted tracks, findings)."""
        self.inner.forecast(record)
        self.hub.forecast(record)


def start_live_monitor(
    run_dir: Path,
    stop: threading.Event,
    say: Callable[[str], None],
    *,
    port: int = 0,
    host: str = "127.0.0.1",
    open_browser: bool = False,
    homes: Mapping[str, tuple[float, float]] | None = None,
    amend: Callable[[str], dict[str, Any]] | None = None,
) -> MonitorServer:
    """Serve the monitor of the run in ``run_dir`` (its programs and graphs already there).

    An abort with the run's token sets ``stop`` (the run loop aborts: every
    drone lands); it is logged with its origin to ``run_dir/logs/monitor.log`` and told
    with ``say``, as are refused requests, those at a bounded rate (the first three,
    then one line per 10 s with how many more: see :class:`~.server.RefusalLimiter`).
    """
    log = make_logger(run_dir / "logs" / "monitor.log", drone="monitor")
    hub = Hub(load_setup(run_dir, homes))

    def on_abort(origin: str, accepted: bool) -> None:
        if accepted:
            log.warning("monitor.abort", origin=origin)
            say(f"abort requested from the {origin}: every drone lands")
            stop.set()
        else:
            log.warning("monitor.abort.refused", origin=origin, reason="not the run's token")
            say(f"abort refused (not the run's token) from the {origin}")

    def on_problem(text: str) -> None:
        log.warning("monitor.refused", detail=text)
        say(f"monitor: {text}")

    def on_command(command: str, drone: str, origin: str) -> str:
        """A page's command, sent as ``eamos pause`` sends it: through the run's socket.
        ``amend`` N applies the staged amendment N, as ``eamos amend --staged N`` does."""
        log.warning("monitor.command", command=command, drone=drone, origin=origin)
        timeout_s = APPLY_TIMEOUT_S if command == "amend" else 10.0
        try:
            send_command(run_dir, command, drone, origin, timeout_s)
        except OperatorError as exc:
            return str(exc)
        if command == "amend":
            applied = read_applied(run_dir, drone)
            hub.amended(load_setup(run_dir, homes), applied)
            say(f"amendment {drone} applied to {', '.join(applied)}: from the {origin}")
            return ""
        say(f"{command} {drone or 'the mission'}: requested from the {origin}")
        return ""

    def on_amend(text: str, origin: str) -> dict[str, Any]:
        """An amendment uploaded from the page, judged as ``eamos amend`` judges it."""
        assert amend is not None
        log.warning("monitor.amend", origin=origin, chars=len(text))
        doc = amend(text)
        verdict = "accepted" if doc.get("accepted") else "refused" if doc.get("ok") else "bad"
        say(f"amendment from the {origin}: {verdict}")
        return doc

    server = MonitorServer(hub, host=host, port=port, on_abort=on_abort, on_problem=on_problem)
    server.on_command = on_command
    server.on_amend = on_amend if amend is not None else None
    server.start()
    log.info("monitor.start", url=f"http://{host}:{server.port}/")
    say(f"monitor: {server.url}")
    if open_browser:
        webbrowser.open(server.url)
    return server
