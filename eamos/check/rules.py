"""The checks of one explored run: action failures, termination, deadlock, separation.

Each rule reads the virtual run (records, final states, what still waited at the
time limit) and the recorded tracks, and returns located findings.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import PurePath
from typing import Any

from ..actors.messages import ActionRecord
from ..program.format import DroneProgram, ProgramNode
from ..virtual import VirtualRun
from .findings import Finding, Place
from .separation import Conflict, conflicts
from .tracks import Track


@dataclass(frozen=True)
class NodeIndex:
    """Every native node of every program by (drone, node key), and where blocks are written.

    ``files`` maps a block (a node's ``block``, a library block's copy named
    ``package.Block(arguments)``) to the library file it is written in; a block of
    the mission file itself is not in it.
    """

    nodes: Mapping[tuple[str, str], ProgramNode]
    files: Mapping[str, str] = field(default_factory=dict)

    def get(self, key: tuple[str, str]) -> ProgramNode | None:
        """The node of (drone, node key), if native to that drone."""
        return self.nodes.get(key)


def node_index(
    programs: Mapping[str, DroneProgram], files: Mapping[str, str] | None = None
) -> NodeIndex:
    """Every native node of every program; ``files``: each library block's file."""
    return NodeIndex(
        {(drone, n.key): n for drone, p in programs.items() for n in p.nodes if n.native},
        dict(files or {}),
    )


def block_files(blocks: Mapping[str, Any]) -> dict[str, str]:
    """The library file of each block written in one (a compiled mission's ``blocks``)."""
    return {name: b.loc.file for name, b in blocks.items() if b.loc.file}


def place(nodes: NodeIndex, drone: str, key: str) -> Place:
    """Where a node is written: the mission text, or the library file of its block."""
    n = nodes.get((drone, key))
    if n is None:
        return Place(drone, key, key, 0, 0)
    return Place(drone, key, n.label, n.line, n.col, nodes.files.get(n.block, ""))


def _fmt(p: tuple[float, ...]) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in p) + ")"


def _line(pl: Place) -> str:
    """``line 15``, or ``line 15 of shapes.go`` for a line in a library file."""
    return f"line {pl.line}" + (f" of {PurePath(pl.file).name}" if pl.file else "")


def _what(pl: Place) -> str:
    return f"{pl.drone}.{pl.label} ({_line(pl)})"


def failed_actions(run: VirtualRun, nodes: NodeIndex, branch: str) -> list[Finding]:
    """An action that fails (busy, not flying, rejected, timed out) fails the mission."""
    out = []
    for drone, outcome in sorted(run.drones.items()):
        for rec in outcome.actions:
            if rec.result == "failed":
                pl = place(nodes, drone, rec.node)
                out.append(
                    Finding(
                        "error",
                        "action",
                        f"{drone}.{pl.label} fails at {rec.end:.2f} s: {rec.reason}",
                        (pl,),
                        rec.end,
                        branch=branch,
                    )
                )
    return out


def _last_action(outcome_actions: tuple[ActionRecord, ...]) -> ActionRecord | None:
    ran = [a for a in outcome_actions if a.result != "failed"] or list(outcome_actions)
    return max(ran, key=lambda a: (a.end, a.start)) if ran else None


def termination(
    run: VirtualRun, nodes: NodeIndex, tracks: Mapping[str, Track], branch: str
) -> list[Finding]:
    """Every drone must end landed and disarmed; else name it, its last action, where it is."""
    out = []
    for drone, outcome in sorted(run.drones.items()):
        final = outcome.final
        if final is None or (final.landed and not final.armed):
            continue
        state = "hovering armed" if not final.landed else "on the ground armed"
        track = tracks.get(drone)
        hint = _termination_hint(drone, final.landed, track) if not outcome.blocked else ""
        pos = (
            track.points[-1].position
            if track and track.points
            else (final.x_m, final.y_m, final.z_m)
        )
        last = _last_action(outcome.actions)
        if last is None:
            places: tuple[Place, ...] = ()
            after = "before any action"
        else:
            pl = place(nodes, drone, last.node)
            places = (pl,)
            after = (
                f"after its last action {pl.drone}.{pl.label} ({last.result} at {last.end:.2f} s)"
            )
        blocked = outcome.blocked
        why = (
            f"; blocked: {', '.join(place(nodes, drone, k).label for k in blocked)}"
            if blocked
            else ""
        )
        out.append(
            Finding(
                "error",
                "termination",
                f"{drone} is left {state} at {_fmt(pos)} {after}{why}{hint}",
                places,
                run.duration_s,
                ((drone, pos),),
                branch,
            )
        )
    return out


def _termination_hint(drone: str, landed: bool, track: Track | None) -> str:
    """What would end the drone landed and disarmed, from how its run went."""
    if not landed:
        return f": nothing lands it (end with {drone}.Land())"
    flew = track is not None and any(p.airborne for p in track.points)
    if flew:
        # The simulated drone disarms by itself after landing unless its type says not to.
        return (
            ": it landed, but its drone type does not disarm by itself after landing "
            f"([hal] disarm_after_landing_s = 0): end with {drone}.Disarm()"
        )
    return f": it never took off (take off, or end with {drone}.Disarm())"


def deadlock(run: VirtualRun, nodes: NodeIndex, time_limit_s: float, branch: str) -> list[Finding]:
    """A run that never ends: the waits undecided at the time limit, and what waits on them."""
    if not run.timed_out:
        return []
    waits = [w for w in run.waiting if "condition" in w.why]
    others = [w for w in run.waiting if "condition" not in w.why]
    involved = tuple(place(nodes, w.drone, w.node) for w in waits + others)
    if waits:
        names = "; ".join(
            f"{w.drone}: {w.label} ({_line(place(nodes, w.drone, w.node))})" for w in waits
        )
        message = f"deadlock: a wait never ends (still waiting after {time_limit_s:g} s): {names}"
    else:
        names = "; ".join(f"{w.drone}: {w.label} ({w.why})" for w in others[:5])
        message = f"the run does not end within {time_limit_s:g} s: {names}"
    if others and waits:
        message += f"; {len(others)} node(s) wait behind {'them' if len(waits) > 1 else 'it'}"
    return [Finding("error", "deadlock", message, involved, run.duration_s, branch=branch)]


def _running_at(run: VirtualRun, drone: str, t_s: float) -> ActionRecord | None:
    acts = run.drones[drone].actions
    covering = [a for a in acts if a.start <= t_s <= a.end]
    if covering:
        return max(covering, key=lambda a: a.start)
    before = [a for a in acts if a.end <= t_s]
    return max(before, key=lambda a: a.end) if before else None


def separation(
    run: VirtualRun,
    nodes: NodeIndex,
    tracks: Mapping[str, Track],
    min_separation_m: float,
    branch: str,
) -> list[Finding]:
    """Every pair of airborne drones keeps ``min_separation_m`` horizontally or vertically."""
    out = []
    found: list[Conflict] = conflicts([tracks[d] for d in sorted(tracks)], min_separation_m)
    for c in found:
        places = []
        for drone in (c.a, c.b):
            # The actions running when the conflict begins are the ones bringing it about.
            rec = _running_at(run, drone, c.start_s)
            if rec is not None:
                places.append(place(nodes, drone, rec.node))
        doing = " while " + " and ".join(_what(p) for p in places) if places else ""
        out.append(
            Finding(
                "error",
                "separation",
                f"{c.a} and {c.b} come within {c.horizontal_m:.2f} m horizontally and "
                f"{c.vertical_m:.2f} m vertically (minimum {min_separation_m:g} m) at "
                f"{c.t_s:.2f} s (from {c.start_s:.2f} to {c.end_s:.2f} s), "
                f"at {_fmt(c.position_a)} and {_fmt(c.position_b)}{doing}",
                tuple(places),
                c.t_s,
                ((c.a, c.position_a), (c.b, c.position_b)),
                branch,
            )
        )
    return out


__all__ = [
    "NodeIndex",
    "block_files",
    "deadlock",
    "failed_actions",
    "node_index",
    "place",
    "separation",
    "termination",
]
