"""``eamos-node --config drone1.toml``: run one participant's part of a mission.

``eamos-node --config d1.toml --config d2.toml ...`` runs several drones that
share a machine in one process, each in a thread of its own with its own
runtime, sockets, keys and logs (``eamos run --drones-per-process``): one
interpreter and one set of imports instead of one per drone, one thread writing
the logs and one clock stepping the simulated drones.  A real drone
runs one config per process.  Each drone's exit code is written to
``<log_dir>/exit_code``; the process exits with the worst of them.

Given a drone's program, it runs the drone (:func:`eamos.actors.drone.run_drone`):
reports ready once every participant it sends to listens, executes until the
ground station declares the mission complete (or aborts), sends its report
and exits.  SIGINT/SIGTERM abort the mission on this drone: the vehicle lands
before the process exits.

Given the ground station's program (``drone = "GCS"``), it is the ground
station (:func:`eamos.ground.run_ground_node`): the same run loop and the
same progress lines as ``eamos run``, and ``summary.json`` in its log folder.

Exit codes (:mod:`eamos.cli.exits`): 0 mission part done, 1 mission failed
or aborted, 2 bad config or program, 3 the vehicle or network could not be
used, 4 internal error.
"""

from __future__ import annotations

import argparse
import gc
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from eamos import __version__
from eamos.cli.errors import run_reported
from eamos.cli.exits import EXIT_CONNECT, EXIT_INTERNAL, EXIT_MISSION_FAILED, EXIT_OK

if TYPE_CHECKING:
    from eamos.actors.drone import DroneEnd, ProcessShare
    from eamos.config import NodeConfig

# The runtime (ZeroMQ, Pykka, structlog, the HAL) is imported where a node runs, not at
# the top: ``eamos-node --help`` and ``--version`` answer without loading it.


def exit_code(end: DroneEnd) -> int:
    """The process's exit code for how a drone's part ended."""
    from eamos.actors.drone import DroneEnd

    return {
        DroneEnd.DONE: EXIT_OK,
        DroneEnd.FAILED: EXIT_MISSION_FAILED,
        DroneEnd.UNREACHABLE: EXIT_CONNECT,
        DroneEnd.REFUSED: EXIT_MISSION_FAILED,  # restarted mid-mission, refuses to rejoin
    }[end]


#: What ``eamos-node --help`` says about the config (every key: docs/operations.md).
NODE_CONFIG_HELP = """\
The config (TOML; `eamos run` and `eamos rollout` write one per drone):

  drone = "Drone1"                        # must match the program
  program = "programs/Drone1.program.json"  # paths relative to this file
  log_dir = "logs/Drone1"
  [net]
  bind = "tcp://127.0.0.1:6001"           # this drone's out-bridge
  keys = "keys/Drone1"                    # from `eamos keys`
  [net.peers]                             # every other participant's out-bridge
  GCS = "tcp://127.0.0.1:6000"
  [hal]
  adapter = "sim"                         # sim | mavlink | ground | fake

Every key, with units and defaults: docs/operations.md, "The node config".

Exit codes: 0 its part of the mission done, 1 the mission failed or was
aborted, 2 bad config or program, 3 the vehicle or the network could not be
used (e.g. a peer never listened), 4 internal error, 130 interrupted.
"""


def build_parser() -> argparse.ArgumentParser:
    """The ``eamos-node`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="eamos-node",
        description="Run one drone's part of an EAMOS mission (its compiled drone program).",
        epilog=NODE_CONFIG_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--config",
        required=True,
        type=Path,
        action="append",
        help="the drone's TOML config file (repeat it to run several drones in this process)",
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks of internal errors"
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    return parser


def run_node(config: NodeConfig, stop: threading.Event, shared: ProcessShare | None = None) -> int:
    """Run the participant ``config`` names until the mission ends; return the exit code.

    ``shared``: what the drones of this process share, when several do.
    """
    from eamos.actors.drone import load_node_program, run_drone
    from eamos.program.uniform import GROUND_STATION

    program = load_node_program(config)
    if program.drone == GROUND_STATION:
        from eamos.ground import run_ground_node

        summary = run_ground_node(config, program, stop)
        return EXIT_OK if summary.ok else EXIT_MISSION_FAILED
    return exit_code(run_drone(config, program, stop, shared))


def load_group(paths: list[Path]) -> list[NodeConfig]:
    """The configs of drones to run in one process; ConfigError if they cannot share it."""
    from eamos.config import ConfigError, NodeConfig
    from eamos.program.uniform import GROUND_STATION

    configs = [NodeConfig.load(p) for p in paths]
    names = [c.drone for c in configs]
    if GROUND_STATION in names and len(configs) > 1:
        raise ConfigError("the ground station runs in a process of its own (one --config)")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ConfigError(f"drone {', '.join(twice)} given twice")
    return configs


def run_group(configs: list[NodeConfig], stop: threading.Event, verbose: bool) -> int:
    """Run each drone of ``configs`` in its own thread; the worst exit code of them."""
    codes: dict[str, int] = {}
    # One log writer, one simulation clock, one ZeroMQ context and its ZAP handler for
    # all of them, not one each.
    from eamos.actors.drone import ProcessShare
    from eamos.config import EXIT_CODE_FILE

    shared = ProcessShare.open()

    def one(config: NodeConfig) -> None:
        code = guarded(lambda: run_node(config, stop, shared), verbose, config.drone)
        codes[config.drone] = code
        try:
            (config.log_dir / EXIT_CODE_FILE).write_text(f"{code}\n")
        except OSError:
            pass  # the process's own exit code still tells

    threads = [threading.Thread(target=one, args=(c,), name=f"node-{c.drone}") for c in configs]
    for thread in threads:
        thread.start()
    for thread in threads:
        # Bounded waits so that the main thread still takes signals (they set ``stop``).
        while thread.is_alive():
            thread.join(0.5)
    shared.close()
    return max(codes.values(), default=EXIT_INTERNAL)


def guarded(body: Callable[[], int], verbose: bool, who: str = "") -> int:
    """``body()``'s exit code, or the exit code of the error it raised (said once on stderr:
    :func:`eamos.cli.errors.run_reported`, the table of every entry point)."""
    return run_reported(f"eamos-node {who}" if who else "eamos-node", body, verbose=verbose)


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos-node``."""
    args = build_parser().parse_args(argv)  # --help, --version: answered, nothing loaded
    from eamos.actors.drone import NodeStop
    from eamos.config import NodeConfig

    # What is loaded by now (modules, classes, functions: tens of thousands of objects)
    # lives as long as the process.  Frozen, the cyclic collector leaves it out of every
    # later collection, which would otherwise walk all of it again, holding the GIL,
    # while the node's threads carry triggers.  Here, in the process's entry point, not
    # at import: what the collector does is the whole process's business.
    gc.freeze()
    stop = NodeStop()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.signal(signal.Signals(signum).name)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    if len(args.config) > 1:
        return guarded(lambda: run_group(load_group(args.config), stop, args.verbose), args.verbose)
    return guarded(lambda: run_node(NodeConfig.load(args.config[0]), stop), args.verbose)


if __name__ == "__main__":
    sys.exit(main())
