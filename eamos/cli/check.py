"""``eamos check``: fly the mission in virtual time before it flies, and report findings.

Exit codes: 0 no error finding (warnings allowed), 1 error findings (the mission
would fail), 2 bad input (a mission with errors, a bad fleet file, an action a drone's
adapter does not implement: each call located, see docs/plugins.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

from .errors import command
from .exits import EXIT_MISSION_FAILED, EXIT_OK
from .options import add_fleet_file, add_mission, add_verbose, positive_number

_HELP = """\
Simulate every drone's program in virtual time, with the kinematic model of its
fleet-file settings (speeds, accelerations, arming delay, battery, scripted pilot),
from its home in the fleet frame, and check every explored run:

  actions      no action fails (busy, not flying, rejected, timed out)
  termination  every drone ends landed and disarmed
  deadlock     no wait stays undecided for ever (reported at --time-limit)
  separation   airborne drones keep the minimum distance horizontally or vertically,
               exactly between samples (closest point of approach)
  duration     the mission's time per run, min and max

Findings are printed as FILE:LINE:COL: error|warning: ... with the run (branch)
they occur in, then one line per run.
Exit code: 0 no error finding, 1 error findings (the mission would fail), 2 bad input
(also: a drone's adapter, sim/px4/ardupilot per the fleet file, lacks an action it calls)."""

_EPILOG = """\
examples:
  eamos check missions/experiment_b.go
  eamos check missions/experiment_d_lands.go --fleet configs/experiment_d_pilot.toml --json
  eamos check missions/experiment_c.go --from runs/latest   # the rest, from its snapshot"""


def add_check_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``eamos check`` on an ``add_subparsers()`` object; returns its parser."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "check",
        help="simulate the mission in virtual time and check separation, termination, ...",
        description=_HELP,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_mission(p)
    add_fleet_file(p, required=False)
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.add_argument(
        "--min-separation",
        type=positive_number,
        metavar="METRES",
        default=None,
        help="minimum separation in metres, horizontal or vertical (default: 2.0)",
    )
    p.add_argument(
        "--time-limit",
        type=positive_number,
        metavar="SECONDS",
        default=None,
        help="virtual seconds after which a run that has not ended is a deadlock (default: 1800)",
    )
    p.add_argument(
        "--max-runs",
        type=int,
        metavar="N",
        default=None,
        help="explore at most N runs (default: 64)",
    )
    p.add_argument(
        "--svg",
        type=Path,
        metavar="OUT.svg",
        default=None,
        help="draw the tracks from above and the altitudes over time, findings marked, "
        "one panel per run with a finding",
    )
    p.add_argument(
        "--from",
        dest="snapshot",
        type=Path,
        metavar="RUN_DIR",
        default=None,
        help="check the rest of the mission from a run's snapshot.json (RUN_DIR or the "
        "file): each drone starts where it was, nothing that had ended flies again",
    )
    add_verbose(p)
    command(p, run_check)
    return p


def run_check(args: argparse.Namespace) -> int:
    """``eamos check``: bad mission or fleet file reach the dispatcher (exit 2)."""
    from eamos.check import CHECK_TIME_LIMIT_S, MAX_RUNS, check_mission
    from eamos.compiler import compile_file
    from eamos.config import FleetConfig

    from .adapter_actions import refuse_adapter_gaps
    from .errors import BadInput

    if args.max_runs is not None and args.max_runs < 1:
        raise BadInput("--max-runs: must be at least 1")
    fleet = FleetConfig.load(args.fleet) if args.fleet else FleetConfig.empty()
    compiled = compile_file(Path(args.mission))
    refuse_adapter_gaps(compiled, fleet)  # an action a drone's adapter lacks: exit 2
    past = None
    if args.snapshot is not None:
        from eamos.virtual import continuation, load_snapshot

        past = continuation(load_snapshot(args.snapshot), str(args.snapshot))
    report = check_mission(
        compiled,
        fleet,
        time_limit_s=args.time_limit or CHECK_TIME_LIMIT_S,
        max_runs=args.max_runs or MAX_RUNS,
        min_separation_m=args.min_separation,
        continuation=past,
    )
    if past is not None and not args.json:
        when = time.strftime("%H:%M:%S", time.localtime(past.taken_at))
        print(f"{args.mission}: the rest of the mission from {args.snapshot} ({past.why}, {when})")
    if args.svg is not None:
        from eamos.check.pictures import svg

        try:
            args.svg.write_text(svg(report), encoding="utf-8")
        except OSError as exc:
            raise BadInput(f"--svg: cannot write {args.svg}: {exc.strerror}") from exc
    if args.json:
        doc = report.to_json()
        doc["file"] = str(args.mission)
        json.dump(doc, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        for line in report.lines(str(args.mission)):
            print(line)
    return EXIT_OK if report.ok else EXIT_MISSION_FAILED


def preflight(
    compiled: Any, fleet: Any, mission: str, say: Any = print, report_file: Path | None = None
) -> Any:
    """The check ``eamos run`` and ``eamos rollout`` do before flying: print its findings.

    Writes the report to ``report_file`` (``check.json`` in the run folder) when
    given; raises :class:`~eamos.cli.errors.Refused` on an error finding.
    """
    from eamos.check import check_mission

    from .adapter_actions import refuse_adapter_gaps
    from .errors import Refused

    refuse_adapter_gaps(compiled, fleet)  # bad input for this fleet (exit 2), before the check
    report = check_mission(compiled, fleet)
    if report_file is not None:
        doc = report.to_json()
        doc["file"] = mission
        report_file.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    for finding in report.findings:
        say(finding.render(mission))
    more = f" ({report.unexplored} more not explored)" if report.unexplored else ""
    say(
        f"pre-flight check: {len(report.runs)} run(s){more}, {len(report.errors)} error(s), "
        f"{len(report.warnings)} warning(s)"
    )
    if not report.ok:
        kept = f" (the whole report: {report_file})" if report_file is not None else ""
        raise Refused(
            f"the pre-flight check found {len(report.errors)} error(s) (above){kept}; fix the "
            "mission or the fleet file, or fly it anyway with --no-check"
        )
    return report


__all__ = ["add_check_parser", "preflight", "run_check"]
