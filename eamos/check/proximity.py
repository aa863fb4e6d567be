"""Which pairs of tracks can come near each other: spatial pruning before the exact test.

Checking every pair of tracks exactly (:func:`~eamos.check.separation.pair_conflicts`)
costs the square of the fleet, whatever the geometry.  Most pairs never come
anywhere near each other, and that is cheap to see from boxes: :func:`candidate_pairs`
cuts every airborne piece of every track into pieces no longer than a grid cell,
puts each piece's bounding box (widened by half the minimum separation on every side,
vertically too) into the cells of a uniform horizontal grid it touches, and, cell by
cell, sweeps the boxes in time order: two tracks are a candidate pair when boxes of
theirs overlap in space and in time.  Two drones closer than the minimum at some
moment are, at that moment, on pieces whose widened boxes overlap, in a cell both
touch: so every pair with a conflict is a candidate, and the exact test on the
candidates finds what it finds on all pairs (``tests/check/test_proximity.py``
compares them on random and real missions).  The work grows with the path flown
and the number of nearby pairs, not with the square of the fleet.
"""

from __future__ import annotations

import itertools
import math
from collections import defaultdict
from collections.abc import Sequence

from .tracks import Track, TrackPoint

#: The grid's cell size is this many minimum separations, and at least MIN_CELL_M.
CELL_SEPARATIONS = 2.0
#: Smallest grid cell (metres): a tiny minimum separation does not cut long flights
#: into thousands of pieces (a larger cell only lets more pairs through).
MIN_CELL_M = 4.0
#: Absolute slack (metres, seconds) on every box: float rounding in the
#: interpolation never prunes a pair the exact test would find in conflict.
_SLACK = 1e-6

#: A piece of a track: (t0, t1, north lo, north hi, east lo, east hi, up lo, up hi, track).
_Box = tuple[float, float, float, float, float, float, float, float, int]


def candidate_pairs(tracks: Sequence[Track], min_separation_m: float) -> set[tuple[int, int]]:
    """The pairs ``(i, j)``, ``i < j``, of ``tracks`` that may come within the minimum.

    Every pair with a conflict is among them (see the module doc); pairs that are
    never both airborne and near each other at the same time are not.
    """
    m = min_separation_m
    if not (m > 0 and math.isfinite(m)):
        # No geometry to prune with: every pair goes to the exact test.
        return {(i, j) for i in range(len(tracks)) for j in range(i + 1, len(tracks))}
    cell = max(CELL_SEPARATIONS * m, MIN_CELL_M)
    pad = 0.5 * m + _SLACK
    grid: defaultdict[tuple[int, int], list[_Box]] = defaultdict(list)
    for index, track in enumerate(tracks):
        for box in _pieces(track, index, cell, pad):
            for ix in range(math.floor(box[2] / cell), math.floor(box[3] / cell) + 1):
                for iy in range(math.floor(box[4] / cell), math.floor(box[5] / cell) + 1):
                    grid[(ix, iy)].append(box)
    pairs: set[tuple[int, int]] = set()
    for boxes in grid.values():
        if len(boxes) > 1:
            _sweep(boxes, pairs)
    return pairs


def _legs(track: Track) -> list[tuple[TrackPoint, TrackPoint, float, bool]]:
    """The track as the exact test reads it between two of its point times.

    Several points at one time (a resting vehicle's skip, then its first step) read
    as the last of them at that time, and as the first of them just before it:
    each leg is ``(start, end, spread, airborne)`` from the last point at one time to
    the first at the next, ``spread`` how far the last point at that next time lies
    from the first (the exact test may head for either), ``airborne`` whether any
    point at either time is in the air (the exact test checks no other piece).
    """
    groups: list[list[TrackPoint]] = []
    for p in track.points:
        if groups and groups[-1][0].t_s == p.t_s:
            groups[-1].append(p)
        else:
            groups.append([p])
    legs = []
    for here, there in itertools.pairwise(groups):
        first, last = there[0], there[-1]
        spread = max(
            abs(last.north_m - first.north_m),
            abs(last.east_m - first.east_m),
            abs(last.up_m - first.up_m),
        )
        airborne = any(p.airborne for p in here) or any(p.airborne for p in there)
        legs.append((here[-1], first, spread, airborne))
    return legs


def _pieces(track: Track, index: int, cell: float, pad: float) -> list[_Box]:
    """The widened boxes of ``track``'s airborne legs, each cut at most ``cell`` across."""
    out: list[_Box] = []
    for a, b, spread, airborne in _legs(track):
        if not airborne:
            continue
        dn, de, du = b.north_m - a.north_m, b.east_m - a.east_m, b.up_m - a.up_m
        dt = b.t_s - a.t_s
        cuts = max(1, math.ceil(max(abs(dn), abs(de)) / cell))
        wide = pad + spread
        t0, n0, e0, u0 = a.t_s, a.north_m, a.east_m, a.up_m
        for k in range(1, cuts + 1):
            if k == cuts:
                t1, n1, e1, u1 = b.t_s, b.north_m, b.east_m, b.up_m
            else:
                f = k / cuts
                t1 = a.t_s + f * dt
                n1, e1, u1 = a.north_m + f * dn, a.east_m + f * de, a.up_m + f * du
            out.append(
                (
                    t0 - _SLACK,
                    t1 + _SLACK,
                    min(n0, n1) - wide,
                    max(n0, n1) + wide,
                    min(e0, e1) - wide,
                    max(e0, e1) + wide,
                    min(u0, u1) - wide,
                    max(u0, u1) + wide,
                    index,
                )
            )
            t0, n0, e0, u0 = t1, n1, e1, u1
    return out


def _sweep(boxes: list[_Box], pairs: set[tuple[int, int]]) -> None:
    """Add to ``pairs`` the tracks of boxes in one cell that overlap in time and space."""
    boxes.sort()
    active: list[_Box] = []
    for box in boxes:
        t0 = box[0]
        if active:
            active = [a for a in active if a[1] >= t0]
        i = box[8]
        for other in active:
            j = other[8]
            if (
                j != i
                and other[2] <= box[3]
                and box[2] <= other[3]
                and other[4] <= box[5]
                and box[4] <= other[5]
                and other[6] <= box[7]
                and box[6] <= other[7]
            ):
                pairs.add((j, i) if j < i else (i, j))
        active.append(box)


__all__ = ["CELL_SEPARATIONS", "MIN_CELL_M", "candidate_pairs"]
