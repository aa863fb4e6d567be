"""The live look-ahead in a real ``eamos run`` (real processes, simulated drones).

``missions/crossing.go`` with ``configs/crossing_slow.toml``: Drone2 flies at half the
speed its type declares (a disturbance the pre-flight check cannot know; the check
passes), so the flight heads into a separation conflict with Drone1.  The ground
station's look-ahead (every 2 s) says so at least 10 s ahead, naming both drones and
both lines, writes ``lookahead.json``, and (``hold_before_s = 12``) holds both drones
before it happens.  The operator then lets Drone2 fly on past the crossing and Drone1
after it: the mission ends ok, and the two drones never came within 2 m.
"""

from __future__ import annotations

import bisect
import json
import math
import re
from pathlib import Path

import pytest

from tests.lookahead.test_lookahead import line_of
from tests.operator.runs import log_lines, operator, positions, start
from tests.support.runs import MISSIONS, REPO

pytestmark = pytest.mark.e2e

SLOW_FLEET = REPO / "configs" / "crossing_slow.toml"
HOMES = {"Drone1": (0.0, 0.0), "Drone2": (-20.0, 10.0)}  # configs/crossing_slow.toml
MIN_SEPARATION_M = 2.0


def closest_approach(run_dir: Path) -> float:
    """The smallest distance between the two drones' logged positions (fleet frame)."""
    one = [(t, x + HOMES["Drone1"][0], y + HOMES["Drone1"][1], z) for t, x, y, z in
           positions(run_dir, "Drone1")]  # fmt: skip
    two = [(t, x + HOMES["Drone2"][0], y + HOMES["Drone2"][1], z) for t, x, y, z in
           positions(run_dir, "Drone2")]  # fmt: skip
    times = [p[0] for p in two]
    best = math.inf
    for p in one:
        i = min(bisect.bisect_left(times, p[0]), len(two) - 1)
        for q in two[max(0, i - 1) : i + 1]:
            if abs(q[0] - p[0]) <= 0.25:
                best = min(best, math.dist(p[1:], q[1:]))
    return best


def test_the_look_ahead_sees_the_slowed_drones_conflict_coming_and_holds_them(
    tmp_path: Path,
) -> None:
    run = start(tmp_path, MISSIONS / "crossing.go", speedup=1, extra=("--fleet", str(SLOW_FLEET)))
    try:
        said = run.wait_for("look-ahead: error in ", within_s=120)
        run.wait_for("look-ahead: Drone1 held", within_s=60)
        run.wait_for("look-ahead: Drone2 held", within_s=10)
        # The operator lets Drone2 fly on past the crossing, then Drone1.
        operator("drone", str(run.run_dir), "Drone2", "resume")
        run.wait_for("Drone2 ok        FlyByX(40)", within_s=120)
        operator("drone", str(run.run_dir), "Drone1", "resume")
        assert run.finish(240) == 0, run.text()
    finally:
        run.kill()
    ahead = int(re.search(r"look-ahead: error in (\d+) s", said).group(1))  # type: ignore[union-attr]
    assert ahead >= 10, said
    for text in ("Drone1.FlyByY(20)", "Drone2.FlyByX(40)"):
        assert f"{text} (line {line_of(text)})" in said, said
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ok"], summary
    held = [(c["command"], c["drone"], c["origin"]) for c in summary["operator_commands"]]
    assert ("hold", "Drone1", "look-ahead") in held and ("hold", "Drone2", "look-ahead") in held
    found = log_lines(run.run_dir, "GCS", "mission", "mission.lookahead.finding")
    assert found and found[0]["check"] == "separation", found
    record = json.loads((run.run_dir / "lookahead.json").read_text())
    assert record["cycle"] >= 3 and record["cycle_s"] < 2.0, record
    assert record["speeds_mps"]["Drone2"] == pytest.approx(1.0, abs=0.15), record
    approach = closest_approach(run.run_dir)
    assert approach > MIN_SEPARATION_M, approach


COLD_FLEET = REPO / "configs" / "crossing_cold.toml"


def test_the_look_ahead_measures_drone2s_cold_battery_and_sees_it_land_below_the_reserve(
    tmp_path: Path,
) -> None:
    """``configs/crossing_cold.toml``: Drone2's battery drains six times its model in the
    air (the pre-flight check passes, each drone landing above the 90 % reserve).  The
    ground station measures Drone2's drain from its telemetry and predicts, before Drone2
    lands, that it lands below the reserve; and it does."""
    run = start(tmp_path, MISSIONS / "crossing.go", speedup=2, extra=("--fleet", str(COLD_FLEET)))
    try:
        said = run.wait_for("look-ahead: error in ", within_s=120)
        assert run.finish(240) == 0, run.text()
    finally:
        run.kill()
    assert "Drone2" in said and "below the reserve of 90 %" in said, said
    record = json.loads((run.run_dir / "lookahead.json").read_text())
    assert record["drain_factors"]["Drone2"] == pytest.approx(6.0, rel=0.25), record
    assert "Drone1" not in record["drain_factors"], record
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["ok"], summary
    # Said before it happened, and it happened: Drone2 landed below the reserve.
    text = run.text()
    assert text.index(said) < text.index("Drone2 ok        Land"), text
    assert summary["drones"]["Drone2"]["final"]["battery"] < 90.0, summary["drones"]["Drone2"]
    assert summary["drones"]["Drone1"]["final"]["battery"] > 90.0
