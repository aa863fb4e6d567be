"""The checks of one explored run: action failures, termination, deadlock, separation.

Each rule reads the virtual run (records, final states, what still waited at the
time limit) and the recorded tracks, and returns located findings.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..actors.messages import ActionRecord
from ..program.format import DroneProgram, ProgramNode
from ..virtual import VirtualRun
from .findings import Finding, Place
from .separation import Conflict, conflicts
from .tracks import Track

NodeIndex = Mapping[tuple[str, str], ProgramNode]


def node_index(programs: Mapping[str, DroneProgram]) -> dict[tuple[str, str], ProgramNode]:
    """Every native node of every program by (drone, node key)."""
    return {(drone, n.key): n for drone, p in programs.items() for n in p.nodes if n.native}


def place(nodes: NodeIndex, drone: str, key: str) -> Place:
    """Where a node is written in the mission text."""
    n = nodes.get((drone, key))
    if n is None:
        return Place(drone, key, key, 0, 0)
    return Place(drone, key, n.label, n.line, n.col)


def _fmt(p: tuple[float, ...]) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in p) + ")"


def _what(pl: Place) -> str:
    return f"{pl.drone}.{pl.label} (line {pl.line})"


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
                f"{drone} is left {state} at {_fmt(pos)} {after}{why}",
                places,
                run.duration_s,
                ((drone, pos),),
                branch,
            )
        )
    return out


def deadlock(run: VirtualRun, nodes: NodeIndex, time_limit_s: float, branch: str) -> list[Finding]:
    """A run that never ends: the waits undecided at the time limit, and what waits on them."""
    if not run.timed_out:
        return []
    waits = [w for w in run.waiting if "condition" in w.why]
    others = [w for w in run.waiting if "condition" not in w.why]
    involved = tuple(place(nodes, w.drone, w.node) for w in waits + others)
    if waits:
        names = "; ".join(
            f"{w.drone}: {w.label} (line {place(nodes, w.drone, w.node).line})" for w in waits
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


__all__ = ["deadlock", "failed_actions", "node_index", "place", "separation", "termination"]
