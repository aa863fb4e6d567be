"""``eamos-node --config drone1.toml``: run one drone's mission program.

Loads the config and the program, starts the drone runtime, reports ready to
the ground station once every participant it sends to listens, executes
until the ground station declares the mission complete (or aborts), sends its
report, and exits.  SIGINT/SIGTERM abort the mission on this drone: the
vehicle lands before the process exits.

Exit codes: 0 mission part done, 1 mission failed or aborted, 2 bad config
or program, 3 the vehicle or network could not be used.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import traceback
from pathlib import Path
from types import FrameType

from . import __version__
from .actors.runtime import DroneRuntime, DroneRuntimeError, NetSettings
from .config import ConfigError, NodeConfig
from .hal import AdapterError, make_adapter
from .logs import close_logger, make_logger
from .net import wire
from .program.format import ProgramError, load_program


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="eamos-node",
        description="Run one drone's part of an EAMOS mission (its compiled drone program).",
        epilog="The config names the drone, its program, its out-bridge endpoint, its peers' "
        "endpoints, the hardware adapter and the log folder; see eamos/config.py.",
    )
    parser.add_argument("--config", required=True, type=Path, help="the drone's TOML config file")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks of internal errors"
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    return parser


def run_node(config: NodeConfig, stop: threading.Event | None = None) -> int:
    """Run one drone until the mission completes or is aborted; return the exit code."""
    program = load_program(config.program)
    if program.drone != config.drone:
        raise ConfigError(
            f"{config.path}: drone: is {config.drone!r} but the program is for {program.drone!r}"
        )
    config.log_dir.mkdir(parents=True, exist_ok=True)
    adapter_log = make_logger(config.log_dir / "adapter.log", drone=config.drone)
    adapter = make_adapter(config.drone, config.hal, adapter_log)
    runtime = DroneRuntime(program, adapter, NetSettings(config.bind, config.peers), config.log_dir)
    stop = stop or threading.Event()
    try:
        runtime.start()
        if not runtime.announce_ready(config.ready_timeout_s):
            print(
                f"eamos-node {config.drone}: peers never subscribed: "
                f"{', '.join(runtime.destinations())} "
                f"(waited {config.ready_timeout_s:g} s)",
                file=sys.stderr,
            )
            return 3
        while not (runtime.completed.is_set() or runtime.aborted.is_set()):
            if stop.is_set():
                runtime.abort("stopped by signal")
                break
            # Bounded only so a signal (which sets `stop`) is noticed; the runtime's
            # events are set by the in-bridge thread.
            runtime.completed.wait(0.5)
        if runtime.aborted.is_set():
            landed = runtime.wait_landed(config.land_timeout_s)
            if not landed:
                runtime.log.error("mission.abort.not_landed", timeout_s=config.land_timeout_s)
        report = runtime.report()
        (config.log_dir / "report.json").write_text(json.dumps(report, indent=1) + "\n")
        runtime.send(wire.Report(mission=program.mission_id, sender=config.drone, report=report))
        return 0 if report["ok"] else 1
    finally:
        runtime.stop()
        close_logger(adapter_log)


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos-node``."""
    args = build_parser().parse_args(argv)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        config = NodeConfig.load(args.config)
        return run_node(config, stop)
    except (ConfigError, ProgramError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return 2
    except (AdapterError, DroneRuntimeError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return 3
    except Exception as exc:  # an internal error: one line, the trace only with -v
        if args.verbose:
            traceback.print_exc()
        print(f"eamos-node: internal error: {exc!r} (run with -v for details)", file=sys.stderr)
        return 4


if __name__ == "__main__":
    sys.exit(main())
