"""``eamos-node --config drone1.toml``: run one participant's part of a mission.

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
import signal
import sys
import threading
import traceback
from pathlib import Path
from types import FrameType

from eamos import __version__
from eamos.actors.drone import DroneEnd, load_node_program, run_drone
from eamos.actors.runtime import DroneRuntimeError
from eamos.cli.exits import (
    EXIT_BAD_INPUT,
    EXIT_CONNECT,
    EXIT_INTERNAL,
    EXIT_MISSION_FAILED,
    EXIT_OK,
)
from eamos.config import ConfigError, NodeConfig
from eamos.hal import AdapterError
from eamos.program.format import ProgramError
from eamos.program.uniform import GROUND_STATION

EXITS = {
    DroneEnd.DONE: EXIT_OK,
    DroneEnd.FAILED: EXIT_MISSION_FAILED,
    DroneEnd.UNREACHABLE: EXIT_CONNECT,
}


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
    parser.add_argument("--config", required=True, type=Path, help="the drone's TOML config file")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks of internal errors"
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    return parser


def run_node(config: NodeConfig, stop: threading.Event) -> int:
    """Run the participant ``config`` names until the mission ends; return the exit code."""
    program = load_node_program(config)
    if program.drone == GROUND_STATION:
        from eamos.ground import run_ground_node

        summary = run_ground_node(config, program, stop)
        return EXIT_OK if summary.ok else EXIT_MISSION_FAILED
    return EXITS[run_drone(config, program, stop)]


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos-node``."""
    args = build_parser().parse_args(argv)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        return run_node(NodeConfig.load(args.config), stop)
    except (ConfigError, ProgramError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except (AdapterError, DroneRuntimeError) as exc:
        print(f"eamos-node: {exc}", file=sys.stderr)
        return EXIT_CONNECT
    except Exception as exc:  # an internal error: one line, the trace only with -v
        if args.verbose:
            traceback.print_exc()
        print(f"eamos-node: internal error: {exc!r} (run with -v for details)", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
