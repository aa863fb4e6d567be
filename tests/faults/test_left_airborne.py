"""Issue 28, item 1: a drone whose part ends blocked in the air lands on its own, at once.

The stranded check must run on every path that ends a drone's part, before its
report: also when the ground station's Complete arrives first, which it always
does for the last drone to resolve (a single drone, or the failing drone of a
fleet that finished before it).  Each test asserts the stranded line the
operator sees (within a stated time of the failure) and that every drone ends
landed and disarmed, with the report sent after the landing.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from tests.faults.runs import LiveRun, read_json
from tests.support.runs import INDEPENDENT, MISSIONS, RUN_TIMEOUT_S

pytestmark = pytest.mark.e2e

#: From the failed action to the stranded line: the drone's loop notices at once (on
#: Complete, or within its 0.5 s tick); generous for a loaded 2-core machine.
STRANDED_LINE_WITHIN_S = 20

#: Drone1 lands early; Drone2 flies on and fails last (FlyByX rejected): when its part
#: ends, every other participant has resolved, so the Complete follows at once.
FAILS_LAST = """
func PAR_Main() {
    SEQ_One()
    SEQ_Two()
}
func SEQ_One() {
    Drone1.Arm()
    Drone1.Takeoff(1)
    Drone1.Land()
    Drone1.Disarm()
}
func SEQ_Two() {
    Drone2.Arm()
    Drone2.Takeoff(2)
    Drone2.FlyByY(3)
    Drone2.FlyByX(2)
    Drone2.Land()
    Drone2.Disarm()
}
"""


def landed_disarmed(report: dict[str, Any]) -> bool:
    final = report["final"]
    return abs(final["z"]) < 0.15 and not final["armed"] and final.get("landed") is not False


def _run(tmp_path: Path, mission: Path, fleet_text: str, failed: str) -> tuple[LiveRun, float]:
    """Fly ``mission`` with ``fleet_text``; wait for the ``failed`` line, then the
    stranded line; return the run (finished) and seconds from one line to the other."""
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(fleet_text)
    run = LiveRun.start(
        tmp_path, mission, "--fleet", str(fleet), "--no-check", speedup=10, timeout_s=300
    )
    try:
        run.wait_for(failed, within_s=120)
        seen = time.monotonic()
        run.wait_for("stranded  end policy: land", within_s=STRANDED_LINE_WITHIN_S)
        told_s = time.monotonic() - seen
        run.finish(RUN_TIMEOUT_S)
    finally:
        run.kill()
    return run, told_s


def test_a_single_drone_blocked_in_the_air_lands_before_its_report(tmp_path: Path) -> None:
    run, told_s = _run(
        tmp_path,
        MISSIONS / "experiment_a.go",
        '[defaults.hal]\nadapter = "sim"\nreject_actions = ["FlyByY"]\n',
        "Drone1 failed    FlyByY(1)",
    )
    assert told_s < STRANDED_LINE_WITHIN_S
    text = run.text()
    line = run.wait_for("Drone1 stranded  end policy: land", within_s=0)
    assert "its part ended with 5 node(s) failed or blocked" in line, text
    assert "the vehicle in the air at z = 1.5 m" in line
    assert run.returncode == 1, text
    summary = read_json(tmp_path / "summary.json")
    d1 = summary["drones"]["Drone1"]
    assert d1["aborted"] and d1["abort_reason"].startswith("stranded: its part ended"), d1
    assert landed_disarmed(d1), d1["final"]  # the report came after the landing
    assert "left in the air" not in text
    node_out = (run.run_dir / "logs" / "Drone1" / "node.out").read_text()
    assert "eamos-node Drone1: stranded: its part ended with" in node_out


@pytest.mark.parametrize(
    ("source", "fleet_text", "failed", "flying", "actions"),
    [
        pytest.param(
            FAILS_LAST,
            '[drones.Drone2.hal]\nadapter = "sim"\nreject_actions = ["FlyByX"]\n',
            "Drone2 failed    FlyByX(2)",
            ("Drone2", "Drone1", 2.0),
            ["Arm", "Takeoff", "FlyByY", "FlyByX"],
            id="fails-last-complete-first",
        ),
        pytest.param(
            # Drone2 still flies when Drone1 fails: Drone1's loop finds itself resolved
            # in the air on its own tick, long before any Complete.
            INDEPENDENT,
            '[drones.Drone1.hal]\nadapter = "sim"\nreject_actions = ["FlyByX"]\n',
            "Drone1 failed    FlyByX(2)",
            ("Drone1", "Drone2", 2.0),
            ["Arm", "Takeoff", "FlyByX"],
            id="fails-first-others-fly-on",
        ),
    ],
)
def test_the_failing_drone_of_two_lands_before_its_report(
    tmp_path: Path,
    source: str,
    fleet_text: str,
    failed: str,
    flying: tuple[str, str, float],
    actions: list[str],
) -> None:
    stranded, other, z = flying
    mission = tmp_path / "two.go"
    mission.write_text(source)
    run, told_s = _run(tmp_path, mission, fleet_text, failed)
    assert told_s < STRANDED_LINE_WITHIN_S
    text = run.text()
    line = run.wait_for(f"{stranded} stranded  end policy: land", within_s=0)
    assert f"the vehicle in the air at z = {z:.1f} m" in line, text
    assert f"{other} stranded" not in text
    assert run.returncode == 1, text
    drones = read_json(tmp_path / "summary.json")["drones"]
    assert drones[other]["ok"] and landed_disarmed(drones[other]), drones[other]
    report = drones[stranded]
    assert [a["action"] for a in report["actions"]] == actions
    assert [a["result"] for a in report["actions"]] == ["ok"] * (len(actions) - 1) + ["failed"]
    assert report["aborted"] and report["abort_reason"].startswith("stranded: its part ended")
    assert landed_disarmed(report), report["final"]
