"""Separation between two piecewise-linear tracks, exactly (not only at samples).

Two airborne drones conflict when their horizontal distance AND their vertical
distance are both below the minimum ("horizontal-or-vertical" separation: being
far enough apart in either sense is enough).  Over a time interval where both
tracks are straight, the relative position is linear in time, so the set of
times with horizontal distance below the minimum is one interval (the roots of
a quadratic) and the set with vertical distance below it is another (a linear
inequality); a conflict is their non-empty intersection.  Each conflict episode
(consecutive conflicting intervals) is reported once, at its closest point.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

from .proximity import candidate_pairs
from .tracks import Track

_EPS = 1e-12


@dataclass(frozen=True)
class Conflict:
    """Two drones closer than the minimum: when, the closest point, the distances."""

    a: str
    b: str
    start_s: float
    end_s: float
    t_s: float  # the time of the smallest horizontal distance within the episode
    horizontal_m: float
    vertical_m: float
    position_a: tuple[float, float, float]
    position_b: tuple[float, float, float]


def _interval_quadratic(qa: float, qb: float, qc: float) -> tuple[float, float] | None:
    """Where ``qa s^2 + qb s + qc < 0`` for s in [0, 1] (qa >= 0), or None."""
    if qa <= _EPS:
        if abs(qb) <= _EPS:
            return (0.0, 1.0) if qc < 0 else None
        root = -qc / qb
        lo, hi = (-math.inf, root) if qb > 0 else (root, math.inf)
    else:
        disc = qb * qb - 4 * qa * qc
        if disc <= 0:
            return None
        r = math.sqrt(disc)
        lo, hi = (-qb - r) / (2 * qa), (-qb + r) / (2 * qa)
    lo, hi = max(lo, 0.0), min(hi, 1.0)
    return (lo, hi) if lo < hi else None


def _interval_linear(c: float, d: float, m: float) -> tuple[float, float] | None:
    """Where ``|c + d s| < m`` for s in [0, 1], or None."""
    if abs(d) <= _EPS:
        return (0.0, 1.0) if abs(c) < m else None
    a, b = (-m - c) / d, (m - c) / d
    lo, hi = max(min(a, b), 0.0), min(max(a, b), 1.0)
    return (lo, hi) if lo < hi else None


def _pieces(ta: Track, tb: Track) -> list[float]:
    """The union of both tracks' point times within the span both cover (none if they
    cover no common span: one track ends before the other begins)."""
    start = max(ta.points[0].t_s, tb.points[0].t_s)
    end = min(ta.points[-1].t_s, tb.points[-1].t_s)
    if end < start:
        return []
    times = {p.t_s for p in ta.points if start <= p.t_s <= end}
    times |= {p.t_s for p in tb.points if start <= p.t_s <= end}
    times |= {start, end}
    return sorted(times)


class _Cursor:
    """Walks one track forward in time: position and airborne flag at increasing times."""

    def __init__(self, track: Track) -> None:
        self.pts = track.points
        self.i = 0

    def at(self, t: float) -> tuple[tuple[float, float, float], bool]:
        pts = self.pts
        while self.i + 1 < len(pts) and pts[self.i + 1].t_s <= t:
            self.i += 1
        a = pts[self.i]
        if self.i + 1 >= len(pts) or t <= a.t_s:
            return a.position, a.airborne
        b = pts[self.i + 1]
        f = (t - a.t_s) / (b.t_s - a.t_s)
        pos = (
            a.north_m + f * (b.north_m - a.north_m),
            a.east_m + f * (b.east_m - a.east_m),
            a.up_m + f * (b.up_m - a.up_m),
        )
        return pos, a.airborne or b.airborne


def pair_conflicts(ta: Track, tb: Track, min_separation_m: float) -> list[Conflict]:
    """Every conflict episode of two tracks (see the module doc)."""
    if not ta.points or not tb.points:
        return []
    m = min_separation_m
    ca, cb = _Cursor(ta), _Cursor(tb)
    times = _pieces(ta, tb)
    if not times:
        return []
    out: list[Conflict] = []
    episode: list[tuple[float, float, float, float, tuple[float, ...], tuple[float, ...]]] = []
    pa0, air_a0 = ca.at(times[0])
    pb0, air_b0 = cb.at(times[0])
    for t0, t1 in itertools.pairwise(times):
        pa1, air_a1 = ca.at(t1)
        pb1, air_b1 = cb.at(t1)
        hit = None
        if (air_a0 or air_a1) and (air_b0 or air_b1):
            hit = _segment(t0, t1, pa0, pa1, pb0, pb1, m)
        if hit is not None:
            episode.append(hit)
        elif episode:
            out.append(_close(ta.drone, tb.drone, episode))
            episode = []
        pa0, pb0, air_a0, air_b0 = pa1, pb1, air_a1, air_b1
    if episode:
        out.append(_close(ta.drone, tb.drone, episode))
    return out


def _segment(
    t0: float,
    t1: float,
    pa0: tuple[float, float, float],
    pa1: tuple[float, float, float],
    pb0: tuple[float, float, float],
    pb1: tuple[float, float, float],
    m: float,
) -> tuple[float, float, float, float, tuple[float, ...], tuple[float, ...]] | None:
    """The conflict within one straight piece: (start, end, t, h, pos a, pos b) or None."""
    # Relative position r(s) = a + b s, s in [0, 1] over [t0, t1].
    ax, ay, az = pb0[0] - pa0[0], pb0[1] - pa0[1], pb0[2] - pa0[2]
    bx = (pb1[0] - pa1[0]) - ax
    by = (pb1[1] - pa1[1]) - ay
    bz = (pb1[2] - pa1[2]) - az
    horiz = _interval_quadratic(
        bx * bx + by * by, 2 * (ax * bx + ay * by), ax * ax + ay * ay - m * m
    )
    if horiz is None:
        return None
    vert = _interval_linear(az, bz, m)
    if vert is None:
        return None
    lo, hi = max(horiz[0], vert[0]), min(horiz[1], vert[1])
    if lo >= hi:  # open sets: touching ends are not a conflict
        return None
    bb = bx * bx + by * by
    s = -(ax * bx + ay * by) / bb if bb > _EPS else lo
    s = min(max(s, lo), hi)
    h = math.hypot(ax + bx * s, ay + by * s)
    dt = t1 - t0
    pos_a = tuple(u + (v - u) * s for u, v in zip(pa0, pa1, strict=True))
    pos_b = tuple(u + (v - u) * s for u, v in zip(pb0, pb1, strict=True))
    return (t0 + lo * dt, t0 + hi * dt, t0 + s * dt, h, pos_a, pos_b)


def _close(
    a: str,
    b: str,
    episode: list[tuple[float, float, float, float, tuple[float, ...], tuple[float, ...]]],
) -> Conflict:
    # The earliest point within a millimetre of the closest: where the drones got there.
    closest = min(e[3] for e in episode)
    best = next(e for e in episode if e[3] <= closest + 1e-3)
    pa, pb = best[4], best[5]
    return Conflict(
        a=a,
        b=b,
        start_s=episode[0][0],
        end_s=episode[-1][1],
        t_s=best[2],
        horizontal_m=best[3],
        vertical_m=abs(pb[2] - pa[2]),
        position_a=(pa[0], pa[1], pa[2]),
        position_b=(pb[0], pb[1], pb[2]),
    )


def conflicts(tracks: list[Track], min_separation_m: float) -> list[Conflict]:
    """Every conflict episode between every pair of tracks, in time order.

    Only the pairs that can come near each other (:func:`~.proximity.candidate_pairs`)
    are tested exactly; the others have no conflict to find.
    """
    out: list[Conflict] = []
    for i, j in sorted(candidate_pairs(tracks, min_separation_m)):
        out.extend(pair_conflicts(tracks[i], tracks[j], min_separation_m))
    return sorted(out, key=lambda c: (c.t_s, c.a, c.b))


__all__ = ["Conflict", "conflicts", "pair_conflicts"]
