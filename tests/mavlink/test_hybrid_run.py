"""Hybrid fleets through ``eamos run``: MAVLink drones on simulated autopilots, sim drones."""

from __future__ import annotations

import json
import subprocess
import tomllib
from pathlib import Path

import pytest

from tests.support.runs import run_mission

REPO = Path(__file__).resolve().parents[2]
RUN_TIMEOUT_S = 300
pytestmark = [pytest.mark.e2e, pytest.mark.timeout(RUN_TIMEOUT_S + 60)]


def eamos_run(
    tmp_path: Path, mission: Path, fleet: Path, *extra: str
) -> tuple[subprocess.CompletedProcess[str], dict]:
    return run_mission(
        tmp_path,
        mission,
        "--fleet",
        str(fleet),
        *extra,
        speedup=5,
        timeout_s=200,
        process_timeout_s=RUN_TIMEOUT_S,
    )


def test_experiment_c_hybrid(tmp_path):
    proc, summary = eamos_run(
        tmp_path,
        REPO / "missions" / "experiment_c.go",
        REPO / "configs" / "experiment_c_hybrid.toml",
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["ok"] and set(summary["drones"]) == {"Drone1", "Drone2", "Drone3"}
    for name, report in summary["drones"].items():
        assert report["ok"], (name, report)
        assert all(a["result"] == "ok" for a in report["actions"]), name
        final = report["final"]
        assert abs(final["x"]) < 0.5 and abs(final["y"]) < 0.5, (name, final)
        assert final["z"] == pytest.approx(0.0, abs=0.15) and not final["armed"], (name, final)
        # The paper's Table 7 check: triggers on the wire equal the MDG's external arcs.
        assert report["triggers_sent"] == report["external_out"], name
        assert report["triggers_received"] == report["external_in"], name
    run = Path(summary["run_dir"])
    for name, autopilot in (("Drone1", "px4"), ("Drone2", "ardupilot")):
        hal = tomllib.loads((run / "configs" / f"{name}.toml").read_text())["hal"]
        assert hal["adapter"] == "mavlink" and "sim_vehicle" not in hal
        assert hal["connection"].startswith(
            "udpin:127.0.0.1:" if autopilot == "px4" else "tcp:127.0.0.1:"
        )
        adapter_log = (run / "logs" / name / "adapter.log").read_text()
        assert f'"autopilot": "{autopilot}"' in adapter_log
        vehicle_log = (run / "logs" / name / "sim-vehicle.log").read_text()
        assert '"event": "vehicle.stop"' in vehicle_log  # stopped cleanly at the end
    print(f"experiment C hybrid at speed-up 5: {summary['duration_s']:.1f} s")


INDEPENDENT = """\
// Drone1 (MAVLink) and Drone2 fly independently of each other.
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
    Drone2.Takeoff(1.5)
    Drone2.FlyByX(1)
    Drone2.Land()
    Drone2.Disarm()
}
"""

REFUSING_FLEET = """\
[drones.Drone1.hal]
adapter = "mavlink"
sim_vehicle = { autopilot = "px4", prearm_delay_s = inf }
armable_timeout_s = 15  # vehicle seconds (the adapter runs on the vehicle's clock, speed-up 5)

[drones.Drone2.hal]
adapter = "mavlink"
sim_vehicle = { autopilot = "ardupilot", prearm_delay_s = 1 }
"""


def test_vehicle_refusing_to_arm_does_not_stop_an_independent_drone(tmp_path):
    mission = tmp_path / "independent.go"
    mission.write_text(INDEPENDENT)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(REFUSING_FLEET)
    proc, summary = eamos_run(tmp_path, mission, fleet)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    d1 = summary["drones"]["Drone1"]
    assert [(a["action"], a["result"]) for a in d1["actions"]] == [("Arm", "failed")]
    assert (
        d1["actions"][0]["reason"]
        == "vehicle never became armable within 15 s: Preflight Fail: ekf2 missing data"
    )
    assert not d1["ok"] and d1["blocked_nodes"]
    d2 = summary["drones"]["Drone2"]
    assert d2["ok"] and [a["result"] for a in d2["actions"]] == ["ok"] * 5
    assert "Arm failed: vehicle never became armable" in proc.stdout


def test_bad_sim_vehicle_table_is_a_config_error(tmp_path):
    mission = tmp_path / "independent.go"
    mission.write_text(INDEPENDENT)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text(
        '[drones.Drone1.hal]\nadapter = "mavlink"\nsim_vehicle = { autopilot = "inav" }\n'
    )
    proc, _ = eamos_run(tmp_path, mission, fleet)
    assert proc.returncode == 2
    assert 'drones.Drone1.hal.sim_vehicle.autopilot: must be "px4" or "ardupilot"' in proc.stderr
    fleet.write_text(
        '[drones.Drone1.hal]\nadapter = "mavlink"\nheartbeat_timeout = 2\n'
        'sim_vehicle = { autopilot = "px4" }\n'
    )
    proc, _ = eamos_run(tmp_path, mission, fleet)
    assert proc.returncode == 2
    assert (
        "hal.heartbeat_timeout: unknown setting (did you mean 'heartbeat_timeout_s'?)"
        in proc.stderr
    )


def test_experiment_c_hybrid_real_drones_wait_armed_past_auto_disarm(tmp_path):
    # Drone3 climbs slowly, so Drone1 (PX4) and Drone2 (ArduCopter) wait armed on the
    # ground for more than 15 s: longer than their autopilots' 10 s pre-flight
    # auto-disarm.  The adapter arms them again before Takeoff (issue 16, item 3).
    fleet = tmp_path / "fleet.toml"
    shipped = (REPO / "configs" / "experiment_c_hybrid.toml").read_text()
    assert shipped.rstrip().endswith('[drones.Drone3.hal]\nadapter = "sim"')
    fleet.write_text(shipped + "climb_speed_mps = 0.3\n")
    proc, summary = eamos_run(tmp_path, REPO / "missions" / "experiment_c.go", fleet)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["ok"], summary
    run = Path(summary["run_dir"])
    for name, disarmed in (
        ("Drone1", "Disarmed by auto preflight disarming"),
        ("Drone2", "Disarming motors"),
    ):
        events = [
            json.loads(line)
            for line in (run / "logs" / name / "sim-vehicle.log").read_text().splitlines()
        ]
        armed = [e["t_sim"] for e in events if e["event"] == "vehicle.armed" and e["armed"]]
        up = next(e["t_sim"] for e in events if e["event"] == "vehicle.position" and e["z_m"] > 0.2)
        assert up - armed[0] >= 15.0, (name, armed, up)
        assert any(e.get("text") == disarmed for e in events), name
        adapter_log = (run / "logs" / name / "adapter.log").read_text()
        assert '"event": "adapter.rearm"' in adapter_log, name
