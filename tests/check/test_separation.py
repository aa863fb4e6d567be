"""Separation between piecewise-linear tracks is exact, not sampled (pure geometry, no run)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from eamos.check import Track, TrackPoint, pair_conflicts


def track(name: str, *points: tuple[float, float, float, float], airborne: bool = True) -> Track:
    return Track(
        name,
        tuple(TrackPoint(t, n, e, u, airborne, True, 100.0) for t, n, e, u in points),
    )


def test_a_crossing_between_two_samples_is_found_at_its_closest_point():
    # Only the ends are known; the tracks cross at t = 5 s where the ends are 14 m apart.
    a = track("A", (0, 0, -10, 2), (10, 0, 10, 2))
    b = track("B", (0, -10, 0, 2), (10, 10, 0, 2))
    (c,) = pair_conflicts(a, b, 2.0)
    assert c.t_s == pytest.approx(5.0)
    assert c.horizontal_m == pytest.approx(0.0, abs=1e-9)
    assert c.vertical_m == pytest.approx(0.0)
    # The relative speed is 2*sqrt(2) m/s: closer than 2 m for 2/(2*sqrt(2)) s either side.
    assert c.start_s == pytest.approx(5 - 1 / 2**0.5)
    assert c.end_s == pytest.approx(5 + 1 / 2**0.5)
    assert c.position_a == pytest.approx((0, 0, 2))


def test_horizontal_or_vertical_either_one_is_enough():
    a = track("A", (0, 0, -10, 2), (10, 0, 10, 2))
    above = track("B", (0, -10, 0, 5), (10, 10, 0, 5))
    assert pair_conflicts(a, above, 2.0) == []
    assert len(pair_conflicts(a, above, 3.5)) == 1
    # Exactly the minimum apart is not a conflict.
    exactly = track("B", (0, -10, 0, 4), (10, 10, 0, 4))
    assert pair_conflicts(a, exactly, 2.0) == []
    side = track("B", (0, 2, -10, 2), (10, 2, 10, 2))  # flying alongside, 2 m north
    assert pair_conflicts(a, side, 2.0) == []
    assert len(pair_conflicts(a, side, 2.01)) == 1


def test_drones_on_the_ground_do_not_conflict():
    a = track("A", (0, 0, 0, 0), (10, 0, 0, 0), airborne=False)
    b = track("B", (0, 0, 0.5, 0), (10, 0, 0.5, 0), airborne=False)
    assert pair_conflicts(a, b, 2.0) == []


def test_tracks_with_different_breakpoints_are_merged():
    a = track("A", (0, 0, 0, 2), (4, 0, 0, 2), (8, 0, 8, 2))
    b = track("B", (0, 0, 20, 2), (6, 0, 2, 2), (8, 0, 20, 2))
    (c,) = pair_conflicts(a, b, 1.0)
    # A: east 2 (t - 4) from t = 4; B: east 20 - 3 t until t = 6: they meet at t = 5.6.
    assert c.t_s == pytest.approx(5.6)
    assert c.horizontal_m == pytest.approx(0.0, abs=1e-9)
    assert c.position_b == pytest.approx((0, 3.2, 2))


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-20, 20), min_size=6, max_size=6),
    st.lists(st.floats(-20, 20), min_size=6, max_size=6),
)
def test_no_conflict_is_missed_compared_to_dense_sampling(pa, pb):
    a = track("A", (0, pa[0], pa[1], abs(pa[2]) + 1), (10, pa[3], pa[4], abs(pa[5]) + 1))
    b = track("B", (0, pb[0], pb[1], abs(pb[2]) + 1), (10, pb[3], pb[4], abs(pb[5]) + 1))
    found = pair_conflicts(a, b, 2.0)
    for k in range(1001):
        t = k / 100
        p, q = a.at(t), b.at(t)
        h = ((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2) ** 0.5
        if h < 1.99 and abs(p[2] - q[2]) < 1.99:
            assert any(c.start_s - 1e-6 <= t <= c.end_s + 1e-6 for c in found), t
    for c in found:
        assert c.horizontal_m < 2.0 and c.vertical_m < 2.0 + 1e-9
