"""``eamos-sim-vehicle``: a MAVLink simulated PX4- or ArduPilot-like vehicle, from the shell."""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from eamos import __version__
from eamos.cli.errors import run_reported
from eamos.cli.exits import EXIT_MISSION_FAILED, EXIT_OK

if TYPE_CHECKING:
    from eamos.hal.sitl.vehicle import VehicleOptions


def _home(text: str) -> tuple[float, float, float]:
    try:
        lat, lon, alt = (float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LAT,LON,ALT, got {text!r}") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise argparse.ArgumentTypeError(f"latitude/longitude out of range: {text!r}")
    return lat, lon, alt


def _delay(text: str) -> float:
    if text.lower() in ("never", "inf"):
        return math.inf
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if value < 0:
        raise argparse.ArgumentTypeError("must be >= 0")
    return value


def _metres(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of metres") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError("must be a finite number >= 0")
    return value


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0:
        raise argparse.ArgumentTypeError("must be > 0")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The ``eamos-sim-vehicle`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="eamos-sim-vehicle",
        description="A simulated quadcopter speaking MAVLink 2 like PX4 SITL (udpout to the "
        "client, as PX4 does on 14540+N) or ArduCopter SITL (TCP server, as on "
        "5760+10N).",
        epilog="examples:\n"
        "  eamos-sim-vehicle --autopilot px4 --connection udpout:127.0.0.1:14540\n"
        "  eamos-sim-vehicle --autopilot ardupilot --connection tcpin:127.0.0.1:5760 "
        "--speedup 5\n"
        "  eamos-sim-vehicle --autopilot px4 --connection udpout:127.0.0.1:14541 "
        "--sysid 2 --reject MAV_CMD_NAV_LAND=FAILED",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--autopilot",
        required=True,
        choices=("px4", "ardupilot"),
        help="which autopilot's MAVLink dialect to speak: px4 (PX4 modes, HEARTBEAT "
        "autopilot PX4, mission uploads) or ardupilot (ArduCopter GUIDED/LAND/RTL modes "
        "and its arming checks)",
    )
    parser.add_argument(
        "--connection",
        required=True,
        help="udpout:HOST:PORT (PX4 style), tcpin:HOST:PORT (ArduPilot style) or udpin:HOST:PORT",
    )
    parser.add_argument("--version", action="version", version=f"eamos {__version__}")
    parser.add_argument("--sysid", type=int, default=1, help="MAVLink system id (1)")
    parser.add_argument(
        "--speedup",
        type=_positive,
        default=1.0,
        help="simulated time runs K times faster than real time (1)",
    )
    parser.add_argument(
        "--prearm-delay",
        type=_delay,
        default=3.0,
        metavar="S",
        help="simulated seconds until pre-arm checks pass (3; 'never' for a "
        "vehicle that never becomes armable; real SITLs take ~40)",
    )
    parser.add_argument(
        "--home",
        type=_home,
        default=(46.6103, 14.2640, 450.0),
        metavar="LAT,LON,ALT",
        help="home position (alt AMSL, metres)",
    )
    parser.add_argument(
        "--reject",
        nargs="+",
        action="extend",
        default=[],
        metavar="CMD",
        help="answer these commands with a failure: MAV_CMD name or number, "
        "optionally =RESULT (DENIED default, FAILED, TEMPORARILY_REJECTED, "
        "UNSUPPORTED)",
    )
    parser.add_argument(
        "--disarm-after",
        type=_positive,
        default=10.0,
        metavar="S",
        help="armed on the ground without taking off, disarm after S simulated "
        "seconds (10, like COM_DISARM_PRFLT / DISARM_DELAY)",
    )
    parser.add_argument(
        "--wander",
        type=_metres,
        default=0.0,
        metavar="M",
        help="the position estimate wanders with this standard deviation in metres, as PX4 "
        "SIH's does (~0.3 while hovering); 0 (default): LOCAL_POSITION_NED is the truth",
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="random seed of the wandering estimate (0)"
    )
    parser.add_argument(
        "--estimator-settle",
        type=_delay,
        default=None,
        metavar="S",
        help="the estimator's flags (ESTIMATOR_STATUS / EKF_STATUS_REPORT) settle S simulated "
        "seconds after start (PX4: 6, after it already accepts arming, as PX4 main does; "
        "ArduPilot: when armable)",
    )
    parser.add_argument(
        "--estimator-bias",
        type=_metres,
        default=0.0,
        metavar="M",
        help="the unsettled estimate is off by M metres at start, shrinking to 0 when it "
        "settles (0, default: no error)",
    )
    parser.add_argument(
        "--signing-key",
        type=Path,
        metavar="FILE",
        help="MAVLink 2 signing: the fleet's key file (eamos keys writes mavlink_signing.key); "
        "sign everything, ignore unsigned messages.  Without it the vehicle accepts a key "
        "sent with SETUP_SIGNING",
    )
    parser.add_argument(
        "--die-after",
        type=_positive,
        metavar="S",
        help="sudden vehicle death: S simulated seconds after leaving the ground it goes "
        "silent and the process exits with status 1 (an autopilot that crashed)",
    )
    parser.add_argument("--log", type=Path, metavar="FILE", help="JSON-lines log of the vehicle")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show tracebacks of internal errors"
    )
    parser.add_argument(
        "--watch-stdin",
        action="store_true",
        help="exit when standard input closes (the parent process died)",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    """Console entry point of ``eamos-sim-vehicle``; SIGTERM/SIGINT stop it cleanly.

    Exit codes (:mod:`eamos.cli.exits`, decided by :func:`eamos.cli.errors.run_reported`):
    0 stopped, 1 died (``--die-after``), 2 bad arguments, 3 the connection could not be
    opened, 4 internal error.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        options = options_from(args)
    except ValueError as exc:
        parser.error(str(exc))
    return run_reported(
        "eamos-sim-vehicle", lambda: fly(options, args.watch_stdin), verbose=args.verbose
    )


def options_from(args: argparse.Namespace) -> VehicleOptions:
    """The vehicle's options from the parsed arguments; ValueError names a bad one."""
    # The vehicle (pymavlink) loads once the arguments are read: --help and --version are quick.
    from eamos.hal.mavlink.signing import read_key
    from eamos.hal.sitl.vehicle import VehicleOptions, parse_reject

    key = read_key(args.signing_key) if args.signing_key is not None else None
    return VehicleOptions(
        autopilot=args.autopilot,
        connection=args.connection,
        sysid=args.sysid,
        speedup=args.speedup,
        prearm_delay_s=args.prearm_delay,
        home=args.home,
        reject=parse_reject(args.reject),
        disarm_after_s=args.disarm_after,
        wander_m=args.wander,
        estimator_settle_s=args.estimator_settle,
        estimator_bias_m=args.estimator_bias,
        seed=args.seed,
        signing_key=key,
        die_after_s=args.die_after,
        log=args.log,
    )


def fly(options: VehicleOptions, watch_stdin: bool) -> int:
    """Run the vehicle until SIGTERM/SIGINT (or standard input closes, ``watch_stdin``).

    Raises :class:`ConnectionError` if its connection cannot be opened.
    """
    from eamos.hal.sitl.vehicle import SimVehicle

    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    if watch_stdin:

        def watch() -> None:
            # Raw reads (no buffered-reader lock to trip over at interpreter exit);
            # b"" is EOF: whoever started us is gone.
            while os.read(sys.stdin.fileno(), 4096):
                pass
            stop.set()

        threading.Thread(target=watch, name="watch-stdin", daemon=True).start()
    vehicle = SimVehicle(options, on_death=stop.set)
    try:
        vehicle.start()
    except OSError as exc:
        raise ConnectionError(f"cannot open {options.connection}: {exc}") from exc
    print(
        f"eamos-sim-vehicle: {options.autopilot} sysid {options.sysid} on "
        f"{options.connection}, speedup {options.speedup:g}",
        flush=True,
    )
    try:
        stop.wait()
    finally:
        vehicle.stop()
    # A simulated autopilot crash (--die-after): not a clean exit.
    return EXIT_MISSION_FAILED if vehicle.dead.is_set() else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
