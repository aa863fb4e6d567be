"""Tracks recorded from the simulator core: exact at every step, straight pieces merged."""

from __future__ import annotations

import itertools

import pytest

from eamos.check.explore import run_once
from eamos.compiler import compile_file
from eamos.hal.sim import SimSettings
from tests.support.runs import MISSIONS


def test_a_recorded_track_is_the_simulated_one_with_straight_pieces_merged():
    compiled = compile_file(MISSIONS / "experiment_b.go")
    homes = {"Drone1": (0.0, 0.0), "Drone2": (3.0, 5.0)}
    settings = {d: SimSettings() for d in homes}
    run, tracks = run_once(compiled, settings, homes, 600.0)
    for drone, (north, east) in homes.items():
        track = tracks[drone]
        pts = track.points
        # Accelerating changes the velocity every step (a point each); standing, hovering and
        # cruising are one piece each: the two seconds of arming are one piece.
        assert len(pts) < 0.7 * run.steps, (len(pts), run.steps)
        assert max(b.t_s - a.t_s for a, b in itertools.pairwise(pts)) >= 1.9
        assert [p.t_s for p in pts] == sorted(p.t_s for p in pts)
        assert pts[0].position == (north, east, 0.0) and not pts[0].airborne
        final = run.drones[drone].final
        assert pts[-1].position == pytest.approx((north + final.x_m, east + final.y_m, final.z_m))
        assert not pts[-1].airborne and not pts[-1].armed
        # At every action's end the track is where the vehicle was (1 m square at 1.5 m, +0.5 m).
        ends = {a.action + str(a.args): track.at(a.end) for a in run.drones[drone].actions}
        assert ends["FlyByX(1.0,)"] == pytest.approx((north + 1, east, 1.5), abs=0.1)
        assert ends["FlyByZ(0.5,)"] == pytest.approx((north, east, 2.0), abs=0.1)
