"""The browser monitor on the command line: ``--monitor`` options and ``eamos monitor RUN_DIR``.

``eamos run MISSION --monitor [--port P] [--open]`` (and ``eamos start RUN_DIR
--monitor``) serve the live page while the mission flies; ``eamos monitor
RUN_DIR`` serves the same page for a finished run, driven by its logs with a
time slider, until Ctrl-C.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import BadInput, command
from .exits import EXIT_OK
from .options import add_verbose

if TYPE_CHECKING:
    from eamos.ground import Display, RunSummary
    from eamos.monitor.server import MonitorServer


@dataclass(frozen=True)
class MonitorOptions:
    """``--monitor``, ``--port``, ``--open``."""

    port: int = 0  # 0: any free port
    open_browser: bool = False
    host: str = "127.0.0.1"

    @classmethod
    def of(cls, args: argparse.Namespace) -> MonitorOptions | None:
        """The options given on the command line (None: no ``--monitor``)."""
        if not getattr(args, "monitor", False):
            return None
        return cls(port=args.port or 0, open_browser=args.open)


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 0..65535, not {value}")
    return value


def add_port_options(parser: argparse.ArgumentParser) -> None:
    """``--port P`` and ``--open``."""
    parser.add_argument(
        "--port",
        type=_port,
        metavar="P",
        help="the monitor's port on 127.0.0.1 (default: any free)",
    )
    parser.add_argument("--open", action="store_true", help="open the monitor in a web browser")


def add_monitor_options(parser: argparse.ArgumentParser) -> None:
    """``--monitor``, ``--port P``, ``--open`` (docs/monitor.md)."""
    parser.add_argument(
        "--monitor",
        action="store_true",
        help="watch the mission live in a browser: the address (with the run's token, which "
        "allows Abort) is printed",
    )
    add_port_options(parser)


@dataclass
class Monitored:
    """What a run gets from :func:`live_monitor`: its display and the end of the run."""

    display: Display
    server: MonitorServer | None = None

    def finish(self, summary: RunSummary) -> None:
        """The page shows the summary's final states and outcome word."""
        if self.server is not None:
            self.server.hub.finish(summary)


@contextlib.contextmanager
def live_monitor(
    opts: MonitorOptions | None,
    run_dir: Path,
    stop: threading.Event,
    display: Display,
    homes: Mapping[str, tuple[float, float]] | None = None,
    amend: Callable[[str], dict[str, Any]] | None = None,
) -> Iterator[Monitored]:
    """``display`` alone, or teed to a live monitor served while the block runs
    (``amend``: judges an amendment uploaded from the page, :func:`.amend.preview`)."""
    if opts is None:
        yield Monitored(display)
        return
    from eamos.monitor import MonitorError
    from eamos.monitor.display import TeeDisplay, start_live_monitor

    try:
        server = start_live_monitor(
            run_dir,
            stop,
            display.say,
            port=opts.port,
            host=opts.host,
            open_browser=opts.open_browser,
            homes=homes,
            amend=amend,
        )
    except MonitorError as exc:
        raise BadInput(str(exc)) from exc
    try:
        yield Monitored(TeeDisplay(display, server.hub), server)
    finally:
        server.stop()


def monitored_drones(run_dir: Path) -> list[str]:
    """The drones of the run folder's programs (for the terminal's table)."""
    from eamos.monitor import MonitorError, load_setup

    try:
        return load_setup(run_dir).drones
    except MonitorError as exc:
        raise BadInput(str(exc)) from exc


_MONITOR_HELP = """\
Serve the browser monitor for a finished run folder (of `eamos run` or `eamos
start`): the same page as `eamos run --monitor`, driven by the run's logs, with
a time slider (play, pause, jump).  Runs until Ctrl-C."""


def add_monitor_parser(sub: Any) -> None:
    """Add ``eamos monitor RUN_DIR`` to the ``eamos`` subcommands."""
    p = sub.add_parser(
        "monitor",
        help="replay a finished run in the browser monitor",
        description=_MONITOR_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="a run folder with summary.json")
    add_port_options(p)
    add_verbose(p)
    command(p, cmd_monitor)


def cmd_monitor(args: argparse.Namespace) -> int:
    """``eamos monitor RUN_DIR``: serve the replay until Ctrl-C (a bad folder: exit 2)."""
    import webbrowser

    from eamos.monitor import MonitorError
    from eamos.monitor.replay import serve_replay

    try:
        server = serve_replay(
            args.run_dir,
            port=args.port or 0,
            on_problem=lambda text: print(f"monitor: {text}", file=sys.stderr, flush=True),
        )
    except MonitorError as exc:
        raise BadInput(str(exc)) from exc
    # Ctrl-C and SIGTERM end it through a handler, not a KeyboardInterrupt that could
    # land anywhere (before the server is stopped, leaving its threads running).
    ended = threading.Event()
    previous = {
        signum: signal.signal(signum, lambda *_: ended.set())
        for signum in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        print(f"monitor (replay of {args.run_dir}): {server.url}  (Ctrl-C ends)", flush=True)
        if args.open:
            webbrowser.open(server.url)
        ended.wait()
    finally:
        server.stop(drain_s=0)
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return EXIT_OK


__all__ = [
    "MonitorOptions",
    "Monitored",
    "add_monitor_options",
    "add_monitor_parser",
    "cmd_monitor",
    "live_monitor",
    "monitored_drones",
]
