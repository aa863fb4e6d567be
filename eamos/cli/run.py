"""``eamos run``: fly a mission on this machine, one ``eamos-node`` process per drone."""

from __future__ import annotations

import argparse
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.cli.exits import EXIT_BAD_INPUT, EXIT_MISSION_FAILED, EXIT_OK
from eamos.compiler import MissionError
from eamos.config import ConfigError, FleetConfig
from eamos.config import positive_number as _positive

if TYPE_CHECKING:  # the runtime is imported only when a mission runs (not for `eamos compile`)
    from eamos.ground import Display, RunSummary

_RUN_HELP = """\
Fly a mission on this machine: compile it, start one eamos-node process per drone
(simulated quadcopters unless the fleet file says otherwise), act as the ground
station, show live progress, and write a run folder with the programs, graphs,
per-drone logs (mission.log, uniform.log, adapter.log) and summary.json.

Exit code 0 when every drone finished its part, 1 otherwise (a failed action, a
timeout, an abort), 2 for a bad mission or fleet file.  Ctrl-C aborts: every
drone lands, then every process ends."""

_RUN_EPILOG = """\
examples:
  eamos run missions/experiment_b.go --speedup 10
  eamos run missions/experiment_d.go --fleet configs/experiment_d_pilot.toml --summary out/d.json"""


def add_run_parser(sub: Any) -> None:
    """Add ``eamos run`` to the ``eamos`` subcommands."""
    run = sub.add_parser(
        "run",
        help="fly a mission on simulated drones (one process per drone)",
        description=_RUN_HELP,
        epilog=_RUN_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument("mission", metavar="MISSION.go", type=Path, help="the mission file")
    run.add_argument(
        "--fleet",
        type=Path,
        metavar="FLEET.toml",
        help="per-drone hardware settings (default: every drone simulated)",
    )
    run.add_argument(
        "--speedup",
        type=_positive,
        metavar="K",
        help="simulated time runs K times faster than real time (default 1)",
    )
    run.add_argument(
        "--summary", type=Path, metavar="PATH", help="also write the summary JSON here"
    )
    run.add_argument(
        "--run-dir",
        type=Path,
        metavar="DIR",
        help="the run folder (default: runs/<mission>-<date-time>/)",
    )
    run.add_argument(
        "--timeout",
        type=_positive,
        default=600.0,
        metavar="SECONDS",
        help="abort (everyone lands) if the mission is not over after this long (600)",
    )
    run.add_argument(
        "--ready-timeout",
        type=_positive,
        default=60.0,
        metavar="SECONDS",
        help="how long drones may take to start and connect (60)",
    )
    run.add_argument(
        "--plain", action="store_true", help="plain progress lines instead of a live table"
    )
    run.add_argument(
        "--no-svg", dest="svg", action="store_false", help="skip drawing graph pictures"
    )
    run.add_argument("-v", "--verbose", action="store_true", help="tracebacks of internal errors")
    run.set_defaults(func=cmd_run)


@dataclass
class RunOptions:
    """What ``eamos run`` was asked to do."""

    mission: Path
    fleet: FleetConfig = field(default_factory=FleetConfig.empty)
    speedup: float | None = None
    summary: Path | None = None
    run_dir: Path | None = None
    timeout_s: float = 600.0
    ready_timeout_s: float = 60.0
    live: bool | None = None  # None: live table when stdout is a terminal
    svg: bool = True


def default_run_dir(mission: str) -> Path:
    """``runs/<mission>-<date-time>/``."""
    return Path("runs") / f"{mission}-{time.strftime('%Y%m%d-%H%M%S')}"


def run_mission(
    opts: RunOptions, stop: threading.Event | None = None, display: Display | None = None
) -> RunSummary:
    """Compile and fly a mission end to end; return the summary (also written to the run folder).

    ``display`` defaults to a live table on a terminal (``opts.live``), plain lines otherwise.
    """
    from eamos.compiler import compile_file, write_artifacts
    from eamos.ground import Limits, LocalMission, fly_local, make_display
    from eamos.program.uniform import GROUND_STATION

    compiled = compile_file(opts.mission)
    run_dir = (opts.run_dir or default_run_dir(compiled.mission.name)).resolve()
    run_dir.mkdir(parents=True, exist_ok=True)
    write_artifacts(compiled, run_dir, svg=opts.svg)
    drones = [n for n in compiled.programs if n != GROUND_STATION]
    summary = fly_local(
        LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
        run_dir,
        opts.fleet,
        Limits(opts.ready_timeout_s, opts.timeout_s),
        stop or threading.Event(),
        speedup=opts.speedup,
        display=display or make_display(opts.live, drones),
    )
    if opts.summary is not None:
        summary.write(opts.summary)
    return summary


def summary_lines(summary: RunSummary) -> list[str]:
    """What ``eamos run`` prints at the end: the outcome, one line per drone, the file."""
    status = "finished" if summary.ok else f"FAILED ({summary.outcome})"
    lines = [f"mission {summary.mission} {status} in {summary.duration_s:.1f} s"]
    for name, result in summary.drones.items():
        report = result.report
        if report is None:
            code = "" if result.exit_code is None else f" (exit code {result.exit_code})"
            lines.append(f"  {name}: not ok, no report{code}")
            continue
        fails = [a for a in report.actions if a.result != "ok"]
        extra = "".join(f"; {a.action} {a.result}: {a.reason}" for a in fails)
        if report.blocked_nodes:
            extra += f"; blocked: {len(report.blocked_nodes)} node(s)"
        lines.append(
            f"  {name}: {'ok' if result.ok else 'not ok'}, "
            f"{len(report.actions)} actions, triggers sent/received "
            f"{report.triggers_sent}/{report.triggers_received}"
            f"{extra}"
        )
    lines.append(f"summary: {summary.run_dir}/summary.json")
    return lines


def cmd_run(args: argparse.Namespace) -> int:
    """``eamos run``."""
    try:
        fleet = FleetConfig.load(args.fleet) if args.fleet else FleetConfig.empty()
    except ConfigError as exc:
        print(f"eamos run: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    from eamos.ground import install_stop_handler

    stop = threading.Event()
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
    )
    try:
        summary = run_mission(opts, stop)
    except MissionError as exc:
        source = None
        try:
            source = Path(args.mission).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            pass
        print(exc.render(str(args.mission), source), file=sys.stderr)
        return EXIT_BAD_INPUT
    except ConfigError as exc:
        print(f"eamos run: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    print("\n".join(summary_lines(summary)))
    return EXIT_OK if summary.ok else EXIT_MISSION_FAILED
