"""The fleet commands of ``eamos``: rollout, start, status, abort, logs fetch.

They drive :mod:`eamos.ops` (real drones over SSH).  Exit codes are the table of
:mod:`eamos.cli.exits`: 0 done, 1 the operation failed on the fleet (a mission
not ok, a drone that cannot be used), 2 bad input (mission, fleet file, run
folder), 3 the drones (or the ground station's port) could not be reached.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import BadInput, command
from .exits import EXIT_INTERRUPTED, EXIT_MISSION_FAILED, EXIT_OK
from .monitor import MonitorOptions, add_monitor_options, live_monitor, monitored_drones
from .options import (
    add_check,
    add_fleet_file,
    add_mission,
    add_plain,
    add_run_dir,
    add_seconds,
    add_speedup,
    add_svg,
    add_verbose,
)

if TYPE_CHECKING:  # eamos.ops (SSH, networks, the runtime) loads when a command runs
    from eamos.ops.deployment import Deployment

_ROLLOUT_HELP = """\
Roll a mission out to real drones over SSH (paper V-E, VI-E/F): compile it here
into a run folder, check every drone (reachable, same eamos version, enough
disk), copy each drone only what changed since the last roll-out (its program,
its config), and start eamos-node on every drone, detached, with its logs.
Then `eamos start RUN_DIR` waits until all are ready and starts the mission
(scripts/rollout.sh does both).  Each step and each drone's part is timed.

Nothing is copied or started unless every drone passes the checks."""

_ROLLOUT_EPILOG = """\
examples:
  eamos rollout missions/experiment_b.go configs/fleet_example.toml --run-dir runs/b
  eamos start runs/b
see docs/operations.md for the fleet file ([ground], [drones.NAME.ssh])"""

_START_HELP = """\
Be the ground station of a rolled-out mission: wait until every drone reports
ready (with the program the roll-out deployed), send the start trigger, show
progress, declare completion, write RUN_DIR/summary.json.  If a drone never
becomes ready, the mission is not started and the others are told to abort.
Ctrl-C (or `eamos abort RUN_DIR`) aborts: every drone lands."""

_STATUS_HELP = """\
Show every drone of a rolled-out mission: whether its eamos-node runs, its
program, the action in progress and its position (live telemetry, else the
last logged position)."""

_ABORT_HELP = """\
Every drone lands now.  If `eamos start` runs for this run folder it is told
to abort (it broadcasts the abort); otherwise this command takes the ground
station's endpoint itself, broadcasts the abort and waits for the drones to
report they landed."""

_LOGS_HELP = """\
Collect every drone's logs (mission.log, uniform.log, adapter.log, node.out,
report.json) over SSH into RUN_DIR/logs/<Drone>/."""


def _source_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "source",
        metavar="RUN_DIR|FLEET.toml",
        type=Path,
        help="the roll-out's run folder, or the fleet file (then the drones say what they have)",
    )
    parser.add_argument(
        "--mission", metavar="NAME", help="with a fleet file: which rolled-out mission"
    )
    add_verbose(parser)


def add_fleet_commands(sub: Any) -> None:
    """Add ``rollout``, ``start``, ``status``, ``abort`` and ``logs``."""
    fmt = argparse.RawDescriptionHelpFormatter
    p = sub.add_parser(
        "rollout",
        help="compile a mission and deploy it to real drones over SSH",
        description=_ROLLOUT_HELP,
        epilog=_ROLLOUT_EPILOG,
        formatter_class=fmt,
    )
    add_mission(p)
    add_fleet_file(p, required=True)
    add_run_dir(p)
    add_speedup(p)
    add_svg(p, default=False)
    add_check(p)
    add_verbose(p)
    command(p, cmd_rollout)

    p = sub.add_parser(
        "start",
        help="start a rolled-out mission (the ground station)",
        description=_START_HELP,
        formatter_class=fmt,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="the roll-out's run folder")
    add_seconds(
        p,
        "--timeout",
        "abort (everyone lands) if the mission is not over after this long",
        default=600.0,
    )
    add_seconds(
        p,
        "--ready-timeout",
        "how long the drones may take to be ready",
        default_text="[ground] ready_timeout_s of the fleet file",
    )
    add_plain(p)
    add_monitor_options(p)
    add_verbose(p)
    command(p, cmd_start)

    p = sub.add_parser(
        "status",
        help="show the drones of a rolled-out mission",
        description=_STATUS_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    add_seconds(p, "--listen", "how long to listen for live telemetry", default=2.0)
    command(p, cmd_status)

    p = sub.add_parser(
        "abort",
        help="land every drone of a mission now (a roll-out's or an `eamos run` folder)",
        description=_ABORT_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    p.add_argument("--reason", default="aborted by the operator", help="logged by every drone")
    add_seconds(p, "--timeout", "how long to wait for the drones to land", default=180.0)
    command(p, cmd_abort)

    logs = sub.add_parser("logs", help="drone logs of a rolled-out mission", description=_LOGS_HELP)
    logs_sub = logs.add_subparsers(dest="logs_command", required=True, metavar="ACTION")
    p = logs_sub.add_parser(
        "fetch",
        help="copy every drone's logs into the run folder",
        description=_LOGS_HELP,
        formatter_class=fmt,
    )
    _source_arg(p)
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        metavar="RUN_DIR",
        help="run folder to fill (default: the RUN_DIR given; required with a fleet file)",
    )
    command(p, cmd_logs_fetch)


def _say(text: str) -> None:
    # One write per line: the drones' steps run in threads, and print() writes the
    # text and its newline separately, which interleaves lines.
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def cmd_rollout(args: argparse.Namespace) -> int:
    """``eamos rollout``."""
    from eamos.ops.record import paper_table
    from eamos.ops.rollout import RolloutOptions, rollout

    def check_first(compiled: Any, fleet: Any, run_dir: Path) -> None:
        from eamos.cli.check import preflight

        preflight(compiled, fleet, str(args.mission), _say, run_dir / "check.json")

    opts = RolloutOptions(
        args.mission,
        args.fleet,
        args.run_dir,
        args.speedup,
        args.svg,
        preflight=check_first if args.check else None,
    )
    result = rollout(opts, _say)
    rows = paper_table(result.durations)
    print(
        f"roll-out done in {result.durations.get('rollout', 0):.2f} s "
        f"(compilation {rows[0][1]:.2f} s, deployment {rows[1][1]:.2f} s); "
        f"every drone's eamos-node is waiting for the ground station"
    )
    print(f"next: eamos start {result.run_dir}")
    return EXIT_OK


def print_table7(durations: dict[str, float]) -> None:
    """The paper's Table 7 roll-out rows."""
    from eamos.ops.record import paper_table

    print("roll-out (paper Table 7):")
    for row, value in paper_table(durations):
        print(f"  {row:<20} {value:8.2f} s")


def _rollout_homes(run_dir: Path, drones: list[str]) -> dict[str, tuple[float, float]] | None:
    """The drones' homes on the monitor's map: the roll-out's fleet file's, as ``eamos run``.

    None (every drone at the origin) when the fleet file is gone or no longer reads:
    the map is then wrong, but the mission must not stop for a picture.
    """
    import json

    from eamos.config import ConfigError, FleetConfig

    try:
        doc = json.loads((run_dir / "rollout.json").read_text(encoding="utf-8"))
        fleet_file = doc.get("fleet_file") if isinstance(doc, dict) else None
        if not isinstance(fleet_file, str):
            return None
        return FleetConfig.load(Path(fleet_file)).homes(drones)
    except (OSError, ValueError, ConfigError):
        return None


def cmd_start(args: argparse.Namespace) -> int:
    """``eamos start``."""
    from eamos.ground import StopRequest, install_stop_handler
    from eamos.ops.start import StartOptions, fly_rollout

    stop = StopRequest()  # Ctrl-C aborts and lands; a second one stops waiting
    install_stop_handler(stop)
    opts = StartOptions(
        args.run_dir, args.timeout, args.ready_timeout, live=False if args.plain else None
    )
    monitor = MonitorOptions.of(args)
    if monitor is None:
        summary = fly_rollout(opts, stop)
    else:
        from eamos.ground import make_display

        run_dir = Path(args.run_dir).resolve()
        drones = monitored_drones(run_dir)
        shown = make_display(opts.live, drones)
        homes = _rollout_homes(run_dir, drones)
        with live_monitor(monitor, run_dir, stop, shown, homes) as monitored:
            summary = fly_rollout(opts, stop, display=monitored.display)
            monitored.finish(summary)
    status = summary.word + (f" ({summary.detail})" if summary.detail else "")
    print(f"mission {summary.mission} {status} in {summary.duration_s:.1f} s")
    for name, result in summary.drones.items():
        report = result.report
        if report is None:
            seen = f"; {result.last_seen.describe()}" if result.last_seen is not None else ""
            print(f"  {name} ({result.host}): no report{seen}")
            continue
        print(
            f"  {name} ({result.host}): {'ok' if result.ok else 'not ok'}, "
            f"{report.action_count} actions, triggers sent/received "
            f"{report.triggers_sent}/{report.triggers_received} "
            f"(MDG external arcs out/in {report.external_out}/{report.external_in})"
        )
    print_table7((summary.rollout or {}).get("durations", {}))
    print(f"summary: {summary.run_dir}/summary.json; logs: eamos logs fetch {args.run_dir}")
    if stop.hurry.is_set():
        return EXIT_INTERRUPTED  # the summary is written; the operator did not wait
    return EXIT_OK if summary.ok else EXIT_MISSION_FAILED


def _deployment(args: argparse.Namespace) -> Deployment:
    from eamos.ops.deployment import resolve

    return resolve(args.source, args.mission)


def cmd_status(args: argparse.Namespace) -> int:
    """``eamos status``: 1 when a drone could not be asked."""
    from eamos.ops.localrun import is_local_run, local_deployment
    from eamos.ops.status import fleet_status, format_status, local_status

    src = Path(args.source)
    if is_local_run(src) and not (src / "rollout.json").exists():
        # An `eamos run` folder: its drones are processes on this machine.
        dep = local_deployment(src)
        rows = local_status(dep)
    else:
        dep = _deployment(args)
        rows = fleet_status(dep, args.listen)
    print(format_status(dep, rows))
    return EXIT_MISSION_FAILED if any(r.error for r in rows) else EXIT_OK


def cmd_abort(args: argparse.Namespace) -> int:
    """``eamos abort``: 1 when a drone did not confirm it landed."""
    from eamos.ops.start import abort

    result = abort(args.source, args.mission, args.reason, args.timeout, _say)
    for name, landed in result.landed.items():
        print(f"  {name}: {'landed' if landed else 'NOT confirmed landed'}")
    for note in result.notes:
        print(f"  {note}")
    return EXIT_OK if result.ok else EXIT_MISSION_FAILED


def cmd_logs_fetch(args: argparse.Namespace) -> int:
    """``eamos logs fetch``: 1 when some logs could not be copied."""
    from eamos.ops.status import fetch_logs

    dep = _deployment(args)
    out = args.output or dep.run_dir
    if out is None:
        raise BadInput("-o RUN_DIR is required with a fleet file")
    print(f"fetching the logs of {', '.join(dep.drones)} into {Path(out) / 'logs'}")
    result = fetch_logs(dep, Path(out), _say)
    for err in result.errors:
        print(f"  {err}", file=sys.stderr)
    return EXIT_MISSION_FAILED if result.errors else EXIT_OK


__all__ = ["add_fleet_commands"]
