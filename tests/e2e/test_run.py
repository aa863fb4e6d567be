"""End to end through ``eamos run``: drone processes, real sockets, simulated drones."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.runs import (
    INDEPENDENT,
    MISSIONS,
    REPO,
    RUN_TIMEOUT_S,
    eamos,
    run_argv,
    run_mission,
)

pytestmark = pytest.mark.e2e

LOOP_FREE = {
    "experiment_a",
    "experiment_b",
    "experiment_c",
    "listing01_demo",
    "inspection_if",
    "relay_wait",
}
PILOT = REPO / "configs" / "experiment_d_pilot.toml"
FLEETS = {"experiment_d": PILOT, "experiment_d_lands": PILOT}


def by_action(actions: list[dict]) -> list[dict]:
    return sorted(actions, key=lambda a: a["start"])


@pytest.mark.parametrize("mission", sorted(p.stem for p in MISSIONS.glob("*.go")))
def test_every_mission_flies_and_finishes(tmp_path, mission):
    extra: tuple[str, ...] = ("--fleet", str(FLEETS[mission])) if mission in FLEETS else ()
    if mission == "experiment_d":
        # Listing 13 as printed leaves D1 and D2 hovering: the pre-flight check refuses it
        # (tests/check asserts those findings); fly it as the paper did: it does not finish.
        extra += ("--no-check",)
    proc, summary = run_mission(tmp_path, MISSIONS / f"{mission}.go", *extra)
    if mission == "experiment_d":
        assert proc.returncode == 1, proc.stdout + proc.stderr
        assert summary["result"] == "failed" and not summary["ok"]
        for name in ("D1", "D2"):
            assert f"{name} left in the air, armed, at (" in proc.stdout, proc.stdout
            assert summary["drones"][name]["final"]["armed"]
        final = summary["drones"]["D3"]["final"]
        assert final["landed"] and not final["armed"]  # disarmed by itself after landing
        return
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert summary["ok"] and summary["drones"]
    for name, report in summary["drones"].items():
        assert report["ok"], (name, report)
        assert all(a["result"] in ("ok", "cancelled") for a in report["actions"])
        final = report["final"]
        assert final is not None and final["z"] == pytest.approx(0.0, abs=0.15), (name, final)
        # Landed and disarmed: by Disarm(), or by itself a moment after Land().
        assert final["landed"] and not final["armed"], (name, final)
        if mission in LOOP_FREE:
            # The paper's Table 7 check: triggers on the wire equal the MDG's external arcs.
            assert report["triggers_sent"] == report["external_out"], name
            assert report["triggers_received"] == report["external_in"], name
    assert (Path(summary["run_dir"]) / "logs").is_dir()


def test_experiment_b_happens_before(tmp_path):
    proc, summary = run_mission(tmp_path, MISSIONS / "experiment_b.go")
    assert proc.returncode == 0, proc.stderr
    d1 = by_action(summary["drones"]["Drone1"]["actions"])
    d2 = by_action(summary["drones"]["Drone2"]["actions"])
    names = [a["action"] for a in d1]
    assert names == [
        "Arm",
        "Takeoff",
        "FlyByX",
        "FlyByY",
        "FlyByX",
        "FlyByY",
        "FlyByZ",
        "Land",
        "Disarm",
    ]
    assert [a["action"] for a in d2] == names
    assert d1[0]["end"] <= d2[0]["start"]  # armed one after the other
    assert d1[1]["start"] < d2[1]["end"] and d2[1]["start"] < d1[1]["end"]  # take-offs overlap
    for side in range(2, 6):  # each side of the square: both finish before either starts the next
        assert max(d1[side]["end"], d2[side]["end"]) <= min(
            d1[side + 1]["start"], d2[side + 1]["start"]
        )
    assert d1[6]["end"] <= d2[6]["start"]  # Drone1 climbs before Drone2
    for report in summary["drones"].values():
        final = report["final"]
        assert abs(final["x"]) < 0.2 and abs(final["y"]) < 0.2 and not final["armed"]


def test_experiment_d_pilot_moves_the_real_drones(tmp_path):
    # As `eamos run --help` shows it: Listing 13 with every drone landed at the end.
    proc, summary = run_mission(
        tmp_path, MISSIONS / "experiment_d_lands.go", "--fleet", str(FLEETS["experiment_d"])
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    d1 = [a for a in summary["drones"]["D1"]["actions"] if a["action"] == "FlyByX"]
    d2 = [a for a in summary["drones"]["D2"]["actions"] if a["action"] == "FlyByX"]
    assert {a["args"][0] for a in d1} == {0.2, -0.2} and {a["args"][0] for a in d2} == {0.2, -0.2}
    assert summary["drones"]["D3"]["final"]["x"] == pytest.approx(40.0, abs=0.5)  # landed outside
    assert [a["action"] for a in summary["drones"]["D3"]["actions"]][-1] == "Land"


def test_failed_action_stops_dependents_and_independent_drone_finishes(tmp_path):
    mission = tmp_path / "independent.go"
    mission.write_text(INDEPENDENT)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[drones.Drone1.hal]\nadapter = "sim"\nreject_actions = ["FlyByX"]\n')
    # The pre-flight check would refuse it (the rejection is in the model): fly it anyway.
    proc, summary = run_mission(tmp_path, mission, "--fleet", str(fleet), "--no-check")
    assert proc.returncode == 1
    d1 = summary["drones"]["Drone1"]
    assert [(a["action"], a["result"]) for a in d1["actions"]] == [
        ("Arm", "ok"),
        ("Takeoff", "ok"),
        ("FlyByX", "failed"),
    ]
    assert "rejected" in d1["actions"][-1]["reason"] and not d1["ok"] and d1["blocked_nodes"]
    d2 = summary["drones"]["Drone2"]
    assert d2["ok"] and [a["result"] for a in d2["actions"]] == ["ok"] * 5
    assert "FlyByX failed" in proc.stdout


def test_no_check_never_calls_a_drone_left_hovering_or_armed_finished(tmp_path):
    mission = tmp_path / "ends.go"
    # Drone1 ends hovering, Drone2 armed on the ground (never flown), Drone3 landed.
    mission.write_text(
        "var Drone1 Quadcopter\nvar Drone2 Quadcopter\nvar Drone3 Quadcopter\n"
        "func SEQ_Main() {\n    PAR_All()\n}\n"
        "func PAR_All() {\n    SEQ_Hover()\n    Drone2.Arm()\n    SEQ_Hop()\n}\n"
        "func SEQ_Hover() {\n    Drone1.Arm()\n    Drone1.Takeoff(2)\n}\n"
        "func SEQ_Hop() {\n    Drone3.Arm()\n    Drone3.Takeoff(2)\n    Drone3.Land()\n}\n"
    )
    proc, summary = run_mission(tmp_path, mission, "--no-check")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert summary["result"] == "failed" and not summary["ok"]
    first = proc.stdout.splitlines()[-5]
    assert first.startswith(
        "mission ends failed (Drone1 left in the air, armed, at (0.00, 0.00, 2.0"
    )
    assert "Drone2 left armed on the ground at (0.00, 0.00, 0.00)" in first
    assert "Drone3" not in first
    assert "  Drone3: ok," in proc.stdout
    final = summary["drones"]["Drone3"]["final"]
    assert final["landed"] and not final["armed"]


def test_bad_mission_is_a_located_error_not_a_traceback(tmp_path):
    mission = tmp_path / "bad.go"
    mission.write_text("func SEQ_M() {\n    Drone1.Takeof(1)\n}\n")
    proc = eamos("run", str(mission), "--plain")
    assert proc.returncode == 2
    assert f"{mission}:2:12" in proc.stderr and "did you mean Takeoff" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_bad_fleet_file_names_the_field(tmp_path):
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[drones.Drone1.hal]\nadapter = "sim"\nspeeedup = 3\n')
    proc, _ = run_mission(tmp_path, MISSIONS / "experiment_a.go", "--fleet", str(fleet))
    assert proc.returncode != 0
    assert "speeedup" in proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr


def test_node_with_bad_config_names_the_field(tmp_path):
    cfg = tmp_path / "d1.toml"
    cfg.write_text('drone = "Drone1"\nprogram = "p.json"\n[net]\nbind = "nonsense"\n')
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli.node", "--config", str(cfg)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert "net.bind" in proc.stderr and "Traceback" not in proc.stderr


def test_ctrl_c_lands_everyone_and_leaves_no_process(tmp_path):
    run_dir = tmp_path / "run"
    summary = tmp_path / "summary.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "eamos.cli",
            *run_argv(MISSIONS / "experiment_b.go", tmp_path, speedup=2, timeout_s=600),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
    )
    try:
        assert proc.stdout is not None
        for line in proc.stdout:  # wait until the square is being flown
            if "running   FlyByY" in line:
                break
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=RUN_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, out
    data = json.loads(summary.read_text())
    assert data["outcome"] == "aborted by the operator"
    for name, report in data["drones"].items():
        assert report["aborted"], name
        assert report["final"]["z"] == pytest.approx(0.0, abs=0.15), name
    leftovers = subprocess.run(["pgrep", "-f", str(run_dir)], capture_output=True, text=True)
    assert leftovers.stdout.strip() == "", f"processes left behind: {leftovers.stdout}"
    assert os.path.exists(run_dir / "logs" / "Drone1" / "mission.log")


def test_node_waiting_for_missing_peers_stops_at_once_on_sigterm(tmp_path):
    import time

    from eamos.compiler import compile_file

    program = compile_file(MISSIONS / "experiment_a.go").programs["Drone1"]
    program.save(tmp_path / "Drone1.program.json")
    cfg = tmp_path / "d1.toml"
    cfg.write_text(
        'drone = "Drone1"\nprogram = "Drone1.program.json"\nlog_dir = "logs"\n'
        'ready_timeout_s = 300\n[net]\nbind = "tcp://127.0.0.1:0"\nplain = true\n'
        '[net.peers]\nGCS = "tcp://127.0.0.1:9"\n[hal]\nadapter = "fake"\n'
    )
    proc = subprocess.Popen(
        [sys.executable, "-m", "eamos.cli.node", "--config", str(cfg)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    log = tmp_path / "logs" / "mission.log"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and "mission.runtime.started" not in (
        log.read_text() if log.exists() else ""
    ):
        time.sleep(0.05)  # test side only: wait until the node is up and waiting for its peers
    proc.send_signal(signal.SIGTERM)
    started = time.monotonic()
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, err
    assert time.monotonic() - started < 10  # not the 300 s ready timeout


def test_a_drone_that_goes_silent_shows_as_link_lines_and_the_mission_finishes(tmp_path):
    # The same peer-status lines as eamos-node's (eamos.ground.format_event): a drone
    # frozen for longer than peer_timeout_s (3 s) is "lost", then "back" when it resumes.
    run_dir = tmp_path / "run"
    summary = tmp_path / "summary.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "eamos.cli",
            *run_argv(
                MISSIONS / "experiment_b.go",
                tmp_path,
                # Drone2 is frozen alone: a process of its own.
                *("--drones-per-process", "1"),
                speedup=2,
                timeout_s=600,
            ),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=REPO,
    )
    lines: list[str] = []
    frozen: int | None = None
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if frozen is None and "running   FlyByY" in line:
                found = subprocess.run(
                    ["pgrep", "-f", str(run_dir / "configs" / "Drone2.toml")],
                    capture_output=True,
                    text=True,
                )
                frozen = int(found.stdout.split()[0])
                os.kill(frozen, signal.SIGSTOP)
            elif frozen is not None and "Drone2 link lost" in line:
                os.kill(frozen, signal.SIGCONT)
        proc.wait(timeout=RUN_TIMEOUT_S)
    finally:
        if frozen is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(frozen, signal.SIGCONT)  # never leave a stopped process behind
        if proc.poll() is None:
            proc.kill()
    out = "\n".join(lines)
    assert proc.returncode == 0, out
    stamp = r"\[\d\d:\d\d:\d\d\]"
    assert re.search(rf"^{stamp}   Drone2 link lost \(silent \d+\.\d s\)$", out, re.M), out
    assert re.search(rf"^{stamp}   Drone2 link back \(silent \d+\.\d s\)$", out, re.M), out
    assert json.loads(summary.read_text())["ok"]


def test_the_pre_flight_check_refuses_a_mission_that_would_fail(tmp_path):
    # The same mission and fleet as above, without --no-check: nothing flies.
    mission = tmp_path / "independent.go"
    mission.write_text(INDEPENDENT)
    fleet = tmp_path / "fleet.toml"
    fleet.write_text('[drones.Drone1.hal]\nadapter = "sim"\nreject_actions = ["FlyByX"]\n')
    proc, summary = run_mission(tmp_path, mission, "--fleet", str(fleet))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert summary == {}  # no drone was started, no summary written
    line = next(n for n, text in enumerate(INDEPENDENT.splitlines(), 1) if "FlyByX" in text)
    assert f"{mission}:{line}:" in proc.stdout and "error" in proc.stdout
    assert "--no-check" in proc.stderr and "Traceback" not in proc.stderr
    report = json.loads((tmp_path / "run" / "check.json").read_text())
    assert report["file"] == str(mission) and any(
        f["severity"] == "error" for f in report["findings"]
    )
    assert not (tmp_path / "run" / "logs").exists()


def test_a_mission_that_passes_the_check_keeps_its_report(tmp_path):
    proc, summary = run_mission(tmp_path, MISSIONS / "experiment_b.go")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "pre-flight check: 1 run(s), 0 error(s)" in proc.stdout
    report = json.loads((tmp_path / "run" / "check.json").read_text())
    assert not [f for f in report["findings"] if f["severity"] == "error"]
    assert summary["ok"]
