"""``eamos amend RUN_DIR NEW_MISSION.go``: check an amendment to a flying mission.

The new text is compiled, renumbered against the programs in the run folder (each
node keeps its number where its place by content is the same), compared drone by
drone, and judged against the run's ``snapshot.json`` (write a fresh one with
``eamos pause RUN_DIR``): a node that has begun may not change, and the rest of the
mission, continued from the snapshot under the amended programs on every branch,
must pass the check (:mod:`eamos.check.amendment`).  An accepted amendment is written
to ``RUN_DIR/amendments/N/`` (its programs and ``amendment.json``).  With ``--apply``
the running ground station first writes a fresh snapshot to judge against, then applies
the accepted amendment to the drones it changes (:mod:`eamos.ground.amend`).

Exit codes: 0 accepted (and applied with ``--apply``), 1 refused (a begun node touched,
a check error, another fleet; with ``--apply``, a drone that refused to switch), 2 bad
input (a mission with errors, a folder that is not a run folder), 3 no ground station
runs the mission (``--apply``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path
from typing import Any

from .errors import BadInput, command
from .exits import EXIT_MISSION_FAILED, EXIT_OK
from .operator import origin
from .options import add_fleet_file, add_verbose

_HELP = """\
Check an amendment to a flying mission before anything changes: compile NEW_MISSION.go,
match its nodes to the running programs by content (block, drone, action), say per drone
what is added, removed and changed and at which node the drone would switch, refuse a
change to a node that has begun (by the run's snapshot.json: `eamos pause RUN_DIR`
writes a fresh one), and check the rest of the mission from the snapshot under the
amended programs (separation, geofence, battery, termination, deadlock), as
`eamos check --from` does.  An accepted amendment is staged in RUN_DIR/amendments/N/.
With --apply, the running ground station writes a fresh snapshot first, and an accepted
amendment is applied to the drones it changes: each switches to its new part while the
others fly on untouched."""

_EPILOG = """\
examples:
  eamos pause runs/latest                               # a fresh snapshot.json
  eamos amend runs/latest amended.go                    # the amended text of its mission
  eamos amend runs/latest amended.go --apply            # checked against now, then flown
  eamos amend runs/latest amended.go --fleet configs/crossing.toml --json"""


def add_amend_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register ``eamos amend``; returns its parser."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "amend",
        help="check an amendment to a flying mission against its snapshot",
        description=_HELP,
        epilog=_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run_dir", metavar="RUN_DIR", type=Path, help="the flying mission's run folder")
    p.add_argument(
        "mission", metavar="NEW_MISSION.go", type=Path, nargs="?", help="the amended mission"
    )
    add_fleet_file(p, required=False)
    p.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    p.add_argument(
        "--force",
        action="store_true",
        help="accept the amendment although the check finds errors (a begun node is "
        "never changed, forced or not)",
    )
    p.add_argument(
        "--apply",
        action="store_true",
        help="judge against a snapshot the running ground station writes now, and apply an "
        "accepted amendment to the drones it changes",
    )
    p.add_argument(
        "--staged",
        metavar="N",
        type=int,
        help="instead of a new text: apply the amendment staged in RUN_DIR/amendments/N/ "
        "(checked when it was staged; a drone refuses it if a node it changes has begun since)",
    )
    add_verbose(p)
    command(p, run_amend)
    return p


def running_programs(run_dir: Path) -> dict[str, Any]:
    """The programs of the run folder, by participant; :class:`BadInput` without them."""
    from eamos.config import fleet_order
    from eamos.ground.amend import read_programs

    programs = read_programs(run_dir / "programs")
    if not programs:
        raise BadInput(f"{run_dir}: not a run folder (no programs/*.program.json)")
    # As the compiler orders them: the ground station, then the drones as declared.
    drones = fleet_order(programs)
    order = [n for n in programs if n not in drones] + drones
    return {name: programs[name] for name in order}


def stage(run_dir: Path, report: Any, text: str, running: Any) -> Path:
    """Write the accepted amendment to the next ``RUN_DIR/amendments/N/``: its text
    (``mission.go``), its renumbered programs and the report (``amendment.json``, with the
    ``running`` programs it was checked against)."""
    from eamos.ground.amend import JUDGED_AGAINST, judged_against

    root = run_dir / "amendments"
    root.mkdir(exist_ok=True)
    number = 1 + max((int(p.name) for p in root.iterdir() if p.name.isdigit()), default=0)
    folder = root / str(number)
    (folder / "programs").mkdir(parents=True)
    for drone, program in report.amended.programs.items():
        program.save(folder / "programs" / f"{drone}.program.json")
    doc = {**report.to_json(), JUDGED_AGAINST: judged_against(running)}
    (folder / "amendment.json").write_text(json.dumps(doc, indent=2) + "\n")
    (folder / "mission.go").write_text(text, encoding="utf-8")
    write_pictures(report.amended, report.touched, folder / "graphs")
    return folder


def write_pictures(compiled: Any, drones: Any, graphs: Path) -> dict[str, str]:
    """The dependency graphs of ``drones`` in ``compiled`` as ``graphs/mdg_<drone>.{dot,svg}``
    (the run folder's ``graphs/`` once applied); the SVG text of each, by drone."""
    from eamos.compiler import render_svg, to_dot

    graphs.mkdir(exist_ok=True)
    svgs = {}
    for drone in drones:
        dot = to_dot(compiled.mdgs[drone], "mdg", fleet=list(compiled.programs))
        svgs[drone] = render_svg(dot)
        (graphs / f"mdg_{drone}.dot").write_text(dot, encoding="utf-8")
        (graphs / f"mdg_{drone}.svg").write_text(svgs[drone], encoding="utf-8")
    return svgs


def amendment_preview(run_dir: Path, fleet: Any, text: str) -> dict[str, Any]:
    """An amendment uploaded from the monitor page, judged and staged as ``eamos amend``
    does: ``{"ok", "accepted", "lines", "report", "staged"}``, or ``{"ok": false,
    "error"}`` for a text that does not compile or a run folder without a snapshot."""
    from eamos.check import check_amendment
    from eamos.compiler import MissionError, compile_mission, render_diagnostics
    from eamos.config import ConfigError
    from eamos.ground.operator import OperatorError, send_command
    from eamos.program.format import ProgramError
    from eamos.virtual import SnapshotError, load_snapshot

    name = "uploaded.go"
    with contextlib.suppress(OperatorError):  # judged against now, not the last pause
        send_command(run_dir, "snapshot", "", "monitor page")
    try:
        running = running_programs(run_dir)
        if not (run_dir / "snapshot.json").is_file():
            raise BadInput("no snapshot.json yet: is the mission flying?")
        compiled = compile_mission(text, str(run_dir / "amendments" / name))
        report = check_amendment(
            running, compiled, load_snapshot(run_dir), fleet, where=f"{run_dir}/snapshot.json"
        )
    except MissionError as exc:
        return {"ok": False, "error": render_diagnostics(exc.diagnostics, name, text)}
    except (BadInput, SnapshotError, ProgramError, ConfigError) as exc:
        return {"ok": False, "error": str(exc)}
    staged = stage(run_dir, report, text, running) if report.accepted and report.touched else None
    graphs: dict[str, str] = {}
    if staged is not None:  # the amended dependency graphs, beside the running ones
        graphs = {
            d: (staged / "graphs" / f"mdg_{d}.svg").read_text(encoding="utf-8")
            for d in report.touched
        }
    return {
        "ok": True,
        "accepted": report.accepted,
        "lines": report.lines(name),
        "report": report.to_json(),
        "staged": None if staged is None else str(staged),
        "number": None if staged is None else int(staged.name),
        "graphs": graphs,
    }


def run_amend(args: argparse.Namespace) -> int:
    """``eamos amend``: 0 accepted (and staged), 1 refused, 2 bad input."""
    from eamos.check import check_amendment
    from eamos.compiler import compile_file
    from eamos.config import FleetConfig
    from eamos.virtual import load_snapshot

    from .adapter_actions import refuse_adapter_gaps

    if not args.run_dir.is_dir():
        raise BadInput(f"{args.run_dir}: not a run folder")
    if (args.staged is None) == (args.mission is None):
        raise BadInput("give either NEW_MISSION.go or --staged N")
    if args.staged is not None:
        staged = args.run_dir / "amendments" / str(args.staged)
        if not (staged / "amendment.json").is_file():
            raise BadInput(f"{staged}: no amendment staged there")
        why = apply_staged(args.run_dir, staged)
        print(f"not applied: {why}" if why else f"applied: amendment {args.staged}")
        return EXIT_MISSION_FAILED if why else EXIT_OK
    running = running_programs(args.run_dir)
    if args.apply:  # judged against the drones as they are now
        from eamos.ground.operator import send_command

        send_command(args.run_dir, "snapshot", "", origin())
    if not (args.run_dir / "snapshot.json").is_file():
        raise BadInput(
            f"{args.run_dir}: no snapshot.json yet: `eamos pause {args.run_dir}` writes one "
            "(a run writes one at its end too)"
        )
    snapshot = load_snapshot(args.run_dir)
    fleet = FleetConfig.load(args.fleet) if args.fleet else FleetConfig.empty()
    compiled = compile_file(args.mission)
    refuse_adapter_gaps(compiled, fleet)
    report = check_amendment(
        running, compiled, snapshot, fleet, force=args.force, where=f"{args.run_dir}/snapshot.json"
    )
    text = args.mission.read_text(encoding="utf-8")  # compiled above: it reads
    staged = (
        stage(args.run_dir, report, text, running) if report.accepted and report.touched else None
    )
    applied = apply_error = None
    if args.apply and staged is not None:
        apply_error = apply_staged(args.run_dir, staged)
        applied = not apply_error
    if args.json:
        doc = report.to_json()
        doc["file"] = str(args.mission)
        doc["staged"] = None if staged is None else str(staged)
        doc["applied"], doc["apply_error"] = applied, apply_error
        json.dump(doc, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        for line in report.lines(str(args.mission)):
            print(line)
        if staged is not None:
            print(f"staged in {staged}")
        if applied:
            print(f"applied: {', '.join(report.touched)} switched to their amended part")
        elif apply_error:
            print(f"not applied: {apply_error}")
    return EXIT_OK if report.accepted and not apply_error else EXIT_MISSION_FAILED


def apply_staged(run_dir: Path, staged: Path) -> str:
    """Have the ground station running ``run_dir`` apply the amendment staged in
    ``staged``: "" when applied, else why not (nothing changed unless it says so)."""
    from eamos.ground.amend import APPLY_TIMEOUT_S
    from eamos.ground.operator import (
        CommandRefused,
        NoGroundStation,
        OperatorError,
        send_command,
    )

    try:
        send_command(run_dir, "amend", staged.name, origin(), timeout_s=APPLY_TIMEOUT_S)
    except NoGroundStation:
        raise  # exit 3: nothing to apply to
    except CommandRefused as exc:
        return exc.reason
    except OperatorError as exc:
        return str(exc)
    return ""


__all__ = ["add_amend_parser", "amendment_preview", "apply_staged", "running_programs"]
