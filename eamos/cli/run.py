"""``eamos run``: fly a mission on this machine, about one ``eamos-node`` process per core."""

from __future__ import annotations

import argparse
import functools
import sys
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.cli.amend import amendment_preview
from eamos.cli.exits import EXIT_INTERRUPTED, EXIT_MISSION_FAILED, EXIT_OK
from eamos.cli.monitor import MonitorOptions, add_monitor_options, live_monitor
from eamos.cli.options import (
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

if TYPE_CHECKING:  # the runtime is imported only when a mission runs (not for `--help`)
    from eamos.compiler import CompiledMission
    from eamos.config import FleetConfig
    from eamos.ground import Display, RunSummary
    from eamos.ground.lookahead import Forecast

_RUN_HELP = """\
Fly a mission on this machine: compile it, start the drones (simulated quadcopters
unless the fleet file says otherwise) in about one eamos-node process per CPU core
(--drones-per-process), act as the ground station, show live progress, and write a
run folder with the programs, graphs, per-drone logs (mission.log, uniform.log,
adapter.log) and summary.json.  The fleet file's [net] ground_telemetry_hz sets how
often each drone's position reaches the ground station (docs/configuration.md).

Exit code 0 when every drone finished its part, landed and disarmed (simulated
drones disarm by themselves after landing, as autopilots do), 1 otherwise (a failed
action, a drone left in the air or armed, a timeout, an abort), 2 for a bad mission
or fleet file.  Ctrl-C aborts: every
drone lands, then every process ends."""

_RUN_EPILOG = """\
examples:
  eamos run missions/experiment_b.go --speedup 10
  eamos run missions/experiment_d_lands.go --fleet configs/experiment_d_pilot.toml
  eamos run missions/experiment_b.go --no-check --summary out/b.json"""


def add_run_parser(sub: Any) -> None:
    """Add ``eamos run`` to the ``eamos`` subcommands."""
    run = sub.add_parser(
        "run",
        help="fly a mission on simulated drones (about one process per core)",
        description=_RUN_HELP,
        epilog=_RUN_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_mission(run)
    add_fleet_file(run, required=False)
    add_speedup(run)
    run.add_argument(
        "--summary", type=Path, metavar="PATH", help="also write the summary JSON here"
    )
    add_run_dir(run)
    add_seconds(
        run,
        "--timeout",
        "abort (everyone lands) if the mission is not over after this long, wall-clock",
        default=600.0,
    )
    add_seconds(
        run, "--ready-timeout", "how long drones may take to start and connect", default=60.0
    )
    run.add_argument(
        "--drones-per-process",
        type=drones_per_process,
        default=None,
        metavar="N|auto",
        help="drones sharing one eamos-node process, each in a thread of its own "
        "(default auto: about one process per CPU core; 1: a process per drone, "
        "so that one drone's process can be stopped alone)",
    )
    add_plain(run)
    add_svg(run, default=True)
    add_check(run)
    add_monitor_options(run)
    add_verbose(run)
    run.set_defaults(func=cmd_run)


def drones_per_process(text: str) -> int | None:
    """``--drones-per-process``: a whole number >= 1, or ``auto`` (None)."""
    if text == "auto":
        return None
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a whole number or 'auto', got {text!r}"
        ) from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _no_fleet_file() -> FleetConfig:
    from eamos.config import FleetConfig

    return FleetConfig.empty()


@dataclass
class RunOptions:
    """What ``eamos run`` was asked to do."""

    mission: Path
    fleet: FleetConfig = field(default_factory=_no_fleet_file)
    speedup: float | None = None
    summary: Path | None = None
    run_dir: Path | None = None
    timeout_s: float = 600.0
    ready_timeout_s: float = 60.0
    live: bool | None = None  # None: live table when stdout is a terminal
    svg: bool = True
    check: bool = True  # the pre-flight check first (eamos check); refuse on an error
    monitor: MonitorOptions | None = None  # serve the live browser monitor (--monitor)
    drones_per_process: int | None = None  # None: about one process per core; 1: one each


def default_run_dir(mission: str) -> Path:
    """A new ``runs/<mission>-<date-time>[-N]/`` folder (made here).

    Runs started in the same second get folders of their own (see
    :func:`eamos.ground.local.new_run_dir`).  It becomes ``runs/latest`` only once
    the drones start (:func:`run_mission`): a run the pre-flight check refuses keeps
    its folder (``check.json``) but ``runs/latest`` still names the newest run that
    flew, which the notebook, ``eamos report`` and ``eamos monitor`` can read.
    """
    from eamos.ground.local import new_run_dir

    return new_run_dir(mission)


def run_mission(
    opts: RunOptions, stop: threading.Event | None = None, display: Display | None = None
) -> RunSummary:
    """Compile and fly a mission end to end; return the summary (also written to the run folder).

    ``display`` defaults to a live table on a terminal (``opts.live``), plain lines otherwise.
    """
    from eamos.compiler import compile_file, write_artifacts
    from eamos.config import fleet_order
    from eamos.ground import Limits, LocalMission, fly_local, make_display, use_run_dir
    from eamos.ground.local import link_latest
    from eamos.program.uniform import GROUND_STATION

    compiled = compile_file(opts.mission)
    # Bound to the mission, each drone's type selects its [types.NAME.hal] settings.
    fleet = opts.fleet.for_mission(compiled.programs, compiled.mission.types)
    run_dir = (opts.run_dir or default_run_dir(compiled.mission.name)).resolve()
    use_run_dir(run_dir)  # --run-dir naming a file: bad input, said with the path
    notes: list[str] = []
    write_artifacts(compiled, run_dir, svg=opts.svg, warnings=notes)
    for note in notes:
        print(f"warning: {note}", file=sys.stderr)
    if opts.check:
        from eamos.cli.check import preflight

        preflight(compiled, fleet, str(opts.mission), report_file=run_dir / "check.json")
    if opts.run_dir is None:
        link_latest(run_dir)  # it flies: the newest run for the notebook, report, monitor
    drones = [n for n in compiled.programs if n != GROUND_STATION]
    stop = stop or threading.Event()
    shown = display or make_display(opts.live, drones)
    # The map's frame: each drone's home as the check and the simulated drones see it.
    homes = fleet.homes(fleet_order(compiled.programs))
    amend = functools.partial(amendment_preview, run_dir, fleet)
    with live_monitor(opts.monitor, run_dir, stop, shown, homes, amend) as monitored:
        summary = fly_local(
            LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
            run_dir,
            fleet,
            Limits(opts.ready_timeout_s, opts.timeout_s),
            stop,
            speedup=opts.speedup,
            display=monitored.display,
            drones_per_process=opts.drones_per_process,
            forecast=forecast(compiled, fleet, opts.speedup, run_dir),
        )
        monitored.finish(summary)
    if opts.summary is not None:
        summary.write(opts.summary)
    return summary


def forecast(
    compiled: CompiledMission,
    fleet: FleetConfig,
    speedup: float | None = None,
    run_dir: Path | None = None,
) -> Forecast:
    """The live look-ahead's forecast of ``compiled`` (``[look_ahead]``, docs/operations.md),
    amended as the run folder ``run_dir`` says amendments were applied (``FlyingMission``).

    Telemetry is stamped with the wall clock; each drone's speed-up (``--speedup`` for a
    simulated one, else its ``hal.speedup``) turns what was measured into vehicle time.
    """
    from eamos.check import FlyingMission
    from eamos.check.lookahead import look_ahead

    speedups: dict[str, float] = {}
    for drone in compiled.programs:
        hal = fleet.hal_for(drone)
        simulated = hal.get("adapter", "sim") == "sim"
        given = speedup if simulated and speedup is not None else hal.get("speedup", 1.0)
        speedups[drone] = float(given)
    if run_dir is None:
        return lambda doc: look_ahead(compiled, fleet, doc, speedups=speedups).to_json()
    flying = FlyingMission(compiled, run_dir)
    return lambda doc: look_ahead(flying.now(), fleet, doc, speedups=speedups).to_json()


def summary_lines(summary: RunSummary) -> list[str]:
    """What ``eamos run`` prints at the end: the outcome, one line per drone, the file."""
    # One outcome word (finished, failed, aborted, timed out), as on the monitor page.
    detail = summary.detail
    status = summary.word + (f" ({detail})" if detail else "")
    lines = [f"mission {summary.mission} {status} in {summary.duration_s:.1f} s"]
    for name, result in summary.drones.items():
        report = result.report
        if report is None:
            code = "" if result.exit_code is None else f" (exit code {result.exit_code})"
            seen = f"; {result.last_seen.describe()}" if result.last_seen is not None else ""
            lines.append(f"  {name}: not ok, no report{code}{seen}")
            continue
        fails = [a for a in report.actions if a.result != "ok"]
        extra = "".join(f"; {a.action} {a.result}: {a.reason}" for a in fails)
        if report.blocked_nodes:
            extra += f"; blocked: {len(report.blocked_nodes)} node(s)"
        if result.left_armed:
            extra += f"; left {result.left_armed}"
        lines.append(
            f"  {name}: {'ok' if result.ok else 'not ok'}, "
            f"{report.action_count} actions, triggers sent/received "
            f"{report.triggers_sent}/{report.triggers_received}"
            f"{extra}"
        )
    lines.append(f"summary: {summary.run_dir}/summary.json")
    return lines


def cmd_run(args: argparse.Namespace) -> int:
    """``eamos run``; a bad mission or fleet file reaches the dispatcher (exit 2)."""
    from eamos.config import FleetConfig

    fleet = FleetConfig.load(args.fleet) if args.fleet else FleetConfig.empty()
    from eamos.ground import StopRequest, hurried, install_stop_handler

    stop = StopRequest()  # Ctrl-C aborts and lands; a second one stops waiting
    install_stop_handler(stop)
    opts = RunOptions(
        mission=args.mission,
        fleet=fleet,
        speedup=args.speedup,
        summary=args.summary,
        run_dir=args.run_dir,
        timeout_s=args.timeout,
        ready_timeout_s=args.ready_timeout,
        live=False if args.plain else None,
        svg=args.svg,
        check=args.check,
        monitor=MonitorOptions.of(args),
        drones_per_process=args.drones_per_process,
    )
    summary = run_mission(opts, stop)
    print("\n".join(summary_lines(summary)))
    if hurried(stop):
        return EXIT_INTERRUPTED  # the summary is written; the operator did not wait
    return EXIT_OK if summary.ok else EXIT_MISSION_FAILED
