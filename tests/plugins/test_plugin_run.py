"""Custom drone types with plugin actions, flown through real processes (``eamos run``).

Each drone is an ``eamos-node`` process with a simulated quadcopter; the plugin actions
reach its adapter through the uniform API, decoded with the plugin's parameters.  The
pre-flight check flies the same plugin actions in virtual time first.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from eamos.logs import read_log

from .lab import env_with, install_lab

pytestmark = [pytest.mark.e2e, pytest.mark.timeout(600)]

INSPECT = """\
package Inspect

type Inspector interface {
	Quadcopter
	TakePhoto()
	Gimbal(pitch_deg float64)
}

var D1 Inspector
var D2 Inspector

func INIT() {
	PAR_Up()
	PAR_Work()
	PAR_Home()
}

func PAR_Up() {
	SEQ_Up1()
	SEQ_Up2()
}

func SEQ_Up1() {
	D1.Arm()
	D1.Takeoff(5)
	D1.FlyByX(4)
}

func SEQ_Up2() {
	D2.Arm()
	D2.Takeoff(8)
}

func PAR_Work() {
	SEQ_Photo()
	SEQ_Circle()
}

func SEQ_Photo() {
	D1.Gimbal(-45)
	D1.TakePhoto()
}

func SEQ_Circle() {
	D2.Gimbal(-30)
	D2.Orbit(3, 1)
	D2.TakePhoto()
}

func PAR_Home() {
	SEQ_Home1()
	SEQ_Home2()
}

func SEQ_Home1() {
	D1.ReturnHome()
	D1.Disarm()
}

func SEQ_Home2() {
	D2.ReturnHome()
	D2.Disarm()
}
"""

SPRAY = """\
package Spray

type Sprayer interface {
	Quadcopter
	Spray(duration_s float64)
}

var D1 Sprayer

func INIT() {
	D1.Arm()
	D1.Takeoff(4)
	D1.Spray(3)
	D1.Land()
	D1.Disarm()
}
"""


def _run(
    tmp_path: Path, mission: str, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    path = tmp_path / "m.go"
    path.write_text(mission, encoding="utf-8")
    argv = [sys.executable, "-m", "eamos.cli.main", "run", str(path), "--speedup", "10"]
    argv += ["--plain", "--no-svg", "--run-dir", str(tmp_path / "run")]
    return subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=500)


def _events(tmp_path: Path, drone: str, event: str) -> list[dict[str, Any]]:
    log = read_log(tmp_path / "run" / "logs" / drone / "adapter.log")
    return [e for e in log if e.get("event") == event]


def test_an_inspector_mission_with_camera_plugins_orbit_and_return_home(tmp_path: Path) -> None:
    done = _run(tmp_path, INSPECT)
    assert done.returncode == 0, done.stdout + done.stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    assert summary["ok"] is True
    d1 = [a["action"] for a in summary["drones"]["D1"]["actions"]]
    assert d1 == ["Arm", "Takeoff", "FlyByX", "Gimbal", "TakePhoto", "ReturnHome", "Disarm"]
    # D1's photo: taken 4 m north of home at 5 m, the gimbal pitched down 45 degrees.
    [photo] = [e for e in _events(tmp_path, "D1", "adapter.plugin") if e["action"] == "TakePhoto"]
    assert (photo["x_m"], photo["y_m"], photo["z_m"]) == pytest.approx((4, 0, 5), abs=0.15)
    assert photo["gimbal_pitch_deg"] == -45.0
    # D2 orbited the point 3 m ahead (north) and came back to where it started.
    positions = [
        (e["x_m"], e["y_m"]) for e in _events(tmp_path, "D2", "adapter.position") if e["z_m"] > 7.9
    ]
    assert max(x for x, _ in positions) == pytest.approx(6.0, abs=0.3)
    assert max(abs(math.dist(p, (3.0, 0.0)) - 3.0) for p in positions if p[0] > 0.5) < 0.4
    ends = {e["action"]: e for e in _events(tmp_path, "D2", "adapter.action.end")}
    assert ends["Orbit"]["status"] == "ok"
    assert (ends["Orbit"]["x_m"], ends["Orbit"]["y_m"]) == pytest.approx((0, 0), abs=0.15)
    assert ends["TakePhoto"]["payload"] == {"gimbal_pitch_deg": -30.0, "photos": 1.0}
    # ReturnHome: each drone is back on the ground at its home.
    for drone in ("D1", "D2"):
        final = summary["drones"][drone]["final"]
        assert (final["x"], final["y"], final["z"]) == pytest.approx((0, 0, 0), abs=0.15)


def test_a_plugin_installed_from_a_lab_package_flies(tmp_path: Path) -> None:
    site = install_lab(tmp_path / "site")
    done = _run(tmp_path, SPRAY, env_with(site))
    assert done.returncode == 0, done.stdout + done.stderr
    [spray] = _events(tmp_path, "D1", "adapter.plugin")
    assert spray["action"] == "Spray" and spray["sprayed_s"] == 3.0
    [end] = [e for e in _events(tmp_path, "D1", "adapter.action.end") if e["action"] == "Spray"]
    assert end["status"] == "ok" and end["duration_sim_s"] == pytest.approx(3.0, abs=0.05)
    # Without the package the mission is refused before anything starts: Spray is no action.
    (tmp_path / "bare").mkdir()
    bare = _run(tmp_path / "bare", SPRAY)
    assert bare.returncode == 2, bare.stdout + bare.stderr
    assert "no adapter implements action 'Spray'" in bare.stderr
