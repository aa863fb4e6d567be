"""The fleet's limits on each track: the geofence polygon, the ceiling, the battery reserve.

Tracks are piecewise linear, so the ceiling is checked at the points (a straight
piece is highest at one of its ends) and the geofence exactly: a piece leaves
the polygon where an end is outside or where it crosses an edge (a polygon need
not be convex).  Only airborne pieces count: a drone standing at its home
outside the fence is the operator's business, a drone flying there is not.
"""

from __future__ import annotations

from collections.abc import Mapping

from ..actors.messages import ActionRecord
from ..config import SafetySettings
from ..virtual import VirtualRun
from .findings import Finding, Place
from .rules import NodeIndex, place
from .tracks import Track, TrackPoint

Polygon = tuple[tuple[float, float], ...]


def inside(polygon: Polygon, north: float, east: float) -> bool:
    """Point in polygon (even-odd rule); points on an edge count as inside."""
    n = len(polygon)
    hit = False
    for i in range(n):
        (an, ae), (bn, be) = polygon[i], polygon[(i + 1) % n]
        if _on_segment(an, ae, bn, be, north, east):
            return True
        if (ae > east) != (be > east):
            cross = an + (east - ae) * (bn - an) / (be - ae)
            if north < cross:
                hit = not hit
    return hit


def _on_segment(an: float, ae: float, bn: float, be: float, n: float, e: float) -> bool:
    cross = (bn - an) * (e - ae) - (be - ae) * (n - an)
    if abs(cross) > 1e-9:
        return False
    return (
        min(an, bn) - 1e-9 <= n <= max(an, bn) + 1e-9
        and min(ae, be) - 1e-9 <= e <= max(ae, be) + 1e-9
    )


def _crossing(
    p: TrackPoint, q: TrackPoint, polygon: Polygon
) -> tuple[float, tuple[float, float, float]] | None:
    """The first point where the straight piece p->q crosses an edge properly, or None."""
    best: tuple[float, tuple[float, float, float]] | None = None
    dn, de = q.north_m - p.north_m, q.east_m - p.east_m
    n = len(polygon)
    for i in range(n):
        (an, ae), (bn, be) = polygon[i], polygon[(i + 1) % n]
        en, ee = bn - an, be - ae
        denom = dn * ee - de * en
        if abs(denom) < 1e-12:
            continue
        s = ((an - p.north_m) * ee - (ae - p.east_m) * en) / denom
        u = ((an - p.north_m) * de - (ae - p.east_m) * dn) / denom
        if 0 < s < 1 and 0 <= u <= 1:
            # Just past the edge: is it outside there (and not merely touching a vertex)?
            s2 = min(1.0, s + 1e-6)
            if not inside(polygon, p.north_m + dn * s2, p.east_m + de * s2) and (
                best is None or s < best[0]
            ):
                pos = (p.north_m + dn * s, p.east_m + de * s, p.up_m + (q.up_m - p.up_m) * s)
                best = (s, pos)
    return best


def _first_exit(track: Track, polygon: Polygon) -> tuple[float, tuple[float, float, float]] | None:
    pts = track.points
    for i, p in enumerate(pts):
        if p.airborne and not inside(polygon, p.north_m, p.east_m):
            return p.t_s, p.position
        if i + 1 < len(pts) and (p.airborne or pts[i + 1].airborne):
            q = pts[i + 1]
            hit = _crossing(p, q, polygon)
            if hit is not None:
                return p.t_s + (q.t_s - p.t_s) * hit[0], hit[1]
    return None


def _last_started(run: VirtualRun, drone: str, t_s: float) -> ActionRecord | None:
    """The action the drone was doing just before ``t_s`` (one starting at ``t_s`` came after)."""
    acts = [a for a in run.drones[drone].actions if a.start < t_s - 1e-9]
    return max(acts, key=lambda a: (a.start, a.end)) if acts else None


def _acting(run: VirtualRun, nodes: NodeIndex, drone: str, t_s: float) -> tuple[Place, ...]:
    last = _last_started(run, drone, t_s)
    return () if last is None else (place(nodes, drone, last.node),)


def _fmt(p: tuple[float, ...]) -> str:
    return "(" + ", ".join(f"{c:.2f}" for c in p) + ")"


def _iteration(run: VirtualRun, drone: str, t_s: float) -> str:
    last = _last_started(run, drone, t_s)
    if last is None or not last.iteration:
        return ""
    return " in loop iteration " + ".".join(str(i + 1) for i in last.iteration)


def geofence(
    run: VirtualRun,
    nodes: NodeIndex,
    tracks: Mapping[str, Track],
    safety: SafetySettings,
    branch: str,
) -> list[Finding]:
    """No airborne track leaves the polygon or climbs above the ceiling (first breach each)."""
    out = []
    for drone, track in sorted(tracks.items()):
        if safety.geofence_m:
            exit_ = _first_exit(track, safety.geofence_m)
            if exit_ is not None:
                t, pos = exit_
                out.append(
                    Finding(
                        "error",
                        "geofence",
                        f"{drone} leaves the geofence at {_fmt(pos)} at {t:.2f} s"
                        f"{_iteration(run, drone, t)}",
                        _acting(run, nodes, drone, t),
                        t,
                        ((drone, pos),),
                        branch,
                    )
                )
        top = safety.max_altitude_m
        if top is not None:
            high = next((p for p in track.points if p.airborne and p.up_m > top + 1e-9), None)
            if high is not None:
                out.append(
                    Finding(
                        "error",
                        "geofence",
                        f"{drone} climbs to {high.up_m:.2f} m, above the ceiling of {top:g} m, "
                        f"at {high.t_s:.2f} s{_iteration(run, drone, high.t_s)}",
                        _acting(run, nodes, drone, high.t_s),
                        high.t_s,
                        ((drone, high.position),),
                        branch,
                    )
                )
    return out


def battery(
    run: VirtualRun,
    nodes: NodeIndex,
    tracks: Mapping[str, Track],
    safety: SafetySettings,
    branch: str,
) -> list[Finding]:
    """No drone lands (or is left flying) below the reserve under the model (first time each)."""
    reserve = safety.battery_reserve_pct
    if reserve is None:
        return []
    out = []
    for drone, track in sorted(tracks.items()):
        pts = track.points
        for i, p in enumerate(pts):
            touchdown = i > 0 and pts[i - 1].airborne and not p.airborne
            left_flying = i == len(pts) - 1 and p.airborne
            if (touchdown or left_flying) and p.battery_pct < reserve - 1e-9:
                how = "lands" if touchdown else "is still flying"
                out.append(
                    Finding(
                        "error",
                        "battery",
                        f"{drone} {how} with {p.battery_pct:.1f} % battery, below the reserve of "
                        f"{reserve:g} %, at {p.t_s:.2f} s{_iteration(run, drone, p.t_s)}",
                        _acting(run, nodes, drone, p.t_s),
                        p.t_s,
                        ((drone, p.position),),
                        branch,
                    )
                )
                break
    return out


__all__ = ["battery", "geofence", "inside"]
