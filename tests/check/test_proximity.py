"""Spatial pruning before the exact closest-approach test finds what testing every pair finds.

``conflicts`` tests exactly only the pairs ``candidate_pairs`` lets through; these
tests compare it with the exact test on every pair (the brute force it replaced):
random tracks, and the tracks of real missions flown in virtual time, including a
crowd that meets at one point and the 100-drone fleet example.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.check import Conflict, Track, TrackPoint, conflicts, pair_conflicts
from eamos.check.explore import run_once
from eamos.check.proximity import MIN_CELL_M, candidate_pairs
from eamos.compiler import compile_file, compile_mission
from eamos.config import FleetConfig, fleet_order
from eamos.config.fleet import HOME_SPACING_M
from eamos.hal.sim import SimSettings

REPO = Path(__file__).resolve().parents[2]


def brute_force(tracks: list[Track], m: float) -> list[Conflict]:
    """Every pair tested exactly, as ``conflicts`` did before it pruned."""
    out: list[Conflict] = []
    for i, ta in enumerate(tracks):
        for tb in tracks[i + 1 :]:
            out.extend(pair_conflicts(ta, tb, m))
    return sorted(out, key=lambda c: (c.t_s, c.a, c.b))


def conflicting_pairs(tracks: list[Track], m: float) -> set[tuple[int, int]]:
    names = {t.drone: i for i, t in enumerate(tracks)}
    return {(names[c.a], names[c.b]) for c in brute_force(tracks, m)}


coordinate = st.floats(-30, 30, allow_nan=False)
point = st.tuples(st.floats(0.0, 5.0), coordinate, coordinate, st.floats(0, 10), st.booleans())


@st.composite
def tracks_of(draw: st.DrawFn) -> list[Track]:
    out = []
    for d in range(draw(st.integers(2, 9))):
        raw = draw(st.lists(point, min_size=1, max_size=7))
        t, pts = 0.0, []
        for dt, n, e, u, air in raw:
            t += dt  # non-decreasing times, zero-length pieces included
            pts.append(TrackPoint(t, n, e, u, air, True, 100.0))
        out.append(Track(f"D{d}", tuple(pts)))
    return out


@settings(max_examples=300, deadline=None)
@given(tracks_of(), st.sampled_from([0.3, 1.0, 2.0, 5.0, 12.0]))
def test_pruning_keeps_every_conflict_of_random_tracks(tracks: list[Track], m: float) -> None:
    assert conflicting_pairs(tracks, m) <= candidate_pairs(tracks, m)
    assert conflicts(tracks, m) == brute_force(tracks, m)


def test_far_apart_or_never_together_in_the_air_is_pruned() -> None:
    def line(name: str, east: float, t0: float, t1: float, air: bool = True) -> Track:
        return Track(
            name,
            (
                TrackPoint(t0, 0.0, east, 3.0, air, True, 100.0),
                TrackPoint(t1, 100.0, east, 3.0, air, True, 100.0),
            ),
        )

    tracks = [
        line("A", 0.0, 0.0, 10.0),
        line("B", 30.0, 0.0, 10.0),  # far east of A the whole time
        line("C", 0.5, 20.0, 30.0),  # A's path, but after A
        line("D", 0.5, 0.0, 10.0, air=False),  # beside A, on the ground
        line("E", 1.0, 0.0, 10.0),  # beside A, in the air: a conflict
    ]
    assert candidate_pairs(tracks, 2.0) == {(0, 4)}
    (c,) = conflicts(tracks, 2.0)
    assert (c.a, c.b) == ("A", "E")


def test_a_long_leg_crossing_many_cells_is_not_missed() -> None:
    # A crosses 1 km diagonally; B hovers on its path, so they meet mid-leg.
    a = Track(
        "A",
        (
            TrackPoint(0.0, 0.0, 0.0, 5.0, True, True, 100.0),
            TrackPoint(100.0, 1000.0, 1000.0, 5.0, True, True, 100.0),
        ),
    )
    b = Track(
        "B",
        (
            TrackPoint(0.0, 437.0, 437.5, 5.5, True, True, 100.0),
            TrackPoint(100.0, 437.0, 437.5, 5.5, True, True, 100.0),
        ),
    )
    assert 1000 / MIN_CELL_M > 100  # many cells
    assert candidate_pairs([a, b], 1.0) == {(0, 1)}
    assert conflicts([a, b], 1.0) == brute_force([a, b], 1.0) != []


def test_without_a_positive_separation_every_pair_is_a_candidate() -> None:
    t = [
        Track(f"D{i}", (TrackPoint(0.0, 100.0 * i, 0.0, 1.0, True, True, 100.0),)) for i in range(3)
    ]
    assert candidate_pairs(t, 0.0) == {(0, 1), (0, 2), (1, 2)}
    assert candidate_pairs(t, math.nan) == {(0, 1), (0, 2), (1, 2)}


# Every drone flies to the same point at its own height, then home: all pairs meet there.
# (FlyToXYZ is in each drone's frame, from its home: homes lie HOME_SPACING_M apart east.)
def crowd(drones: int) -> str:
    names = [f"D{i}" for i in range(1, drones + 1)]
    lines = [f"var {n} Quadcopter" for n in names]
    lines += ["func SEQ_Main() {", "\tPAR_Arm()", "\tPAR_Up()", "\tPAR_Meet()", "\tPAR_Home()"]
    lines += ["\tPAR_Land()", "}"]
    lines.append("func PAR_Arm() {" + "; ".join(f"{n}.Arm()" for n in names) + "}")
    lines.append(
        "func PAR_Up() {"
        + "; ".join(f"{n}.Takeoff({2 + 0.7 * i:g})" for i, n in enumerate(names))
        + "}"
    )
    lines.append(
        "func PAR_Meet() {"
        + "; ".join(
            f"{n}.FlyToXYZ(10, {10 - HOME_SPACING_M * i:g}, {2 + 0.7 * i:g})"
            for i, n in enumerate(names)
        )
        + "}"
    )
    lines.append(
        "func PAR_Home() {"
        + "; ".join(f"{n}.FlyToXYZ(0, 0, {2 + 0.7 * i:g})" for i, n in enumerate(names))
        + "}"
    )
    lines.append("func PAR_Land() {" + "; ".join(f"{n}.Land()" for n in names) + "}")
    return "\n".join(lines) + "\n"


def relay(drones: int) -> str:
    import sys

    sys.path.insert(0, str(REPO / "scripts"))
    from bench_scale import relay_mission

    return relay_mission(drones)


MISSIONS: dict[str, str | Path] = {
    **{p.stem: p for p in sorted((REPO / "missions").glob("*.go"))},
    "fleet100": REPO / "missions" / "fleets" / "fleet100.go",
    "crowd12": crowd(12),
    "relay40": relay(40),
}


def mission_tracks(source: str | Path) -> list[Track]:
    compiled = compile_file(source) if isinstance(source, Path) else compile_mission(source, "t.go")
    drones = fleet_order(compiled.programs)
    homes = FleetConfig.empty().homes(drones)
    sims = {d: SimSettings(home_m=homes[d]) for d in drones}
    _, tracks = run_once(compiled, sims, homes, 1800.0)
    return [tracks[d] for d in sorted(tracks)]


@pytest.mark.timeout(600)
@pytest.mark.parametrize("mission", sorted(MISSIONS))
def test_pruning_finds_what_every_pair_finds_on_real_missions(mission: str) -> None:
    tracks = mission_tracks(MISSIONS[mission])
    for m in (2.0, 8.0):
        pruned, every = conflicts(tracks, m), brute_force(tracks, m)
        assert pruned == every, (mission, m)
    if mission == "crowd12":
        assert len({(c.a, c.b) for c in conflicts(tracks, 2.0)}) >= 11  # they do meet
    if mission in ("fleet100", "relay40"):
        n = len(tracks)
        assert len(candidate_pairs(tracks, 2.0)) < n * (n - 1) / 2 / 4  # pruned, mostly
