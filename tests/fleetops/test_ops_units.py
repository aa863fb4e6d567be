"""Fleet operations without a network: fleet settings, partial-deployment identity, parsing."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from eamos import __version__
from eamos.compiler import compile_file
from eamos.compiler.amendment import rekey
from eamos.config import ConfigError, FleetConfig, NodeConfig
from eamos.net.keys import create_fleet_keys
from eamos.net.link import LinkSettings
from eamos.ops.identity import execution_digest, fleet_mission_id, restamp
from eamos.ops.plan import DronePlan, decide, drone_config
from eamos.ops.probe import Probe, check_version, parse_probe
from eamos.ops.record import paper_table
from eamos.ops.rollout import earlier_programs
from eamos.ops.ssh import DroneError, classify
from eamos.ops.status import current_action
from eamos.ops.targets import SshTarget, load_targets

REPO = Path(__file__).resolve().parents[2]
EXPERIMENT_B = REPO / "missions" / "experiment_b.go"


def edited(tmp_path: Path, old: str, new: str, name: str = "experiment_b.go") -> Path:
    text = EXPERIMENT_B.read_text()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


# -- which drones changed -------------------------------------------------------------------


def digests(path: Path) -> dict[str, str]:
    return {n: execution_digest(p) for n, p in compile_file(path).programs.items()}


def test_an_edit_of_one_drone_changes_only_its_digest(tmp_path):
    before = digests(EXPERIMENT_B)
    after = digests(edited(tmp_path, "Drone2.FlyByZ(0.5)", "Drone2.FlyByZ(0.6)"))
    changed = sorted(n for n in before if before[n] != after[n])
    assert changed == ["Drone2"]


def test_moved_lines_and_comments_change_no_digest(tmp_path):
    before = digests(EXPERIMENT_B)
    after = digests(
        edited(tmp_path, "func SEQ_Experiment_B", "// a comment\n\nfunc SEQ_Experiment_B")
    )
    assert before == after


def test_a_shared_change_redeploys_both(tmp_path):
    before = digests(EXPERIMENT_B)
    after = digests(
        edited(
            tmp_path,
            "Drone1.Takeoff(1.5)\n\tDrone2.Takeoff(1.5)",
            "Drone1.Takeoff(2)\n\tDrone2.Takeoff(2)",
        )
    )
    assert sorted(n for n in before if before[n] != after[n]) == ["Drone1", "Drone2"]


def test_fleet_mission_id_is_stable_across_edits(tmp_path):
    a = compile_file(EXPERIMENT_B)
    b = compile_file(edited(tmp_path, "Drone2.FlyByZ(0.5)", "Drone2.FlyByZ(0.6)"))
    assert a.mission_id != b.mission_id  # the compiler's id hashes the text
    ida = fleet_mission_id(a.mission.name, list(a.programs))
    idb = fleet_mission_id(b.mission.name, list(b.programs))
    assert ida == idb
    ra, rb = restamp(a, ida), restamp(b, idb)
    assert {p.mission_id for p in [*ra.programs.values(), *rb.programs.values()]} == {ida}
    # Restamped programs are consistent files (their checksum covers the new id).
    assert ra.programs["Drone1"].checksum != a.programs["Drone1"].checksum
    assert fleet_mission_id("other", list(a.programs)) != ida


def plan_for(program, config: str = "cfg") -> DronePlan:
    return DronePlan(
        drone=program.drone,
        target=SshTarget(program.drone, "h"),
        endpoint="tcp://h:6001",
        program=program,
        digest=execution_digest(program),
        config_text=config,
        staging=Path("/nonexistent"),
    )


def probe_with(stamp: dict | None, sums: dict[str, str]) -> Probe:
    return Probe("eamos " + __version__, 10**6, stamp, sums, None, False)


LANES = REPO / "tests" / "fleetops" / "lanes.go"
INSERTION = ("\tDrone1.FlyByX(-4)\n", "\tDrone1.FlyByZ(1)\n\tDrone1.FlyByX(-4)\n")


def rolled_out(path: Path, run_dir: Path):  # type: ignore[no-untyped-def]
    """``path`` compiled as a roll-out stamps it, its programs in ``run_dir/programs``."""
    compiled = compile_file(path)
    compiled = restamp(compiled, fleet_mission_id(compiled.mission.name, list(compiled.programs)))
    (run_dir / "programs").mkdir(parents=True)
    for name, program in compiled.programs.items():
        program.save(run_dir / "programs" / f"{name}.program.json")
    return compiled


def test_a_rollout_renumbers_against_the_run_folder_the_drones_stamps_name(tmp_path):
    first = rolled_out(LANES, tmp_path / "run1")
    stamp = {"mission_id": first.mission_id, "run_dir": str(tmp_path / "run1")}
    probes = {d: probe_with(stamp, {}) for d in ("Drone1", "Drone2")}
    base = earlier_programs(probes, first.mission_id)
    assert set(base) == set(first.programs)
    text = LANES.read_text().replace(*INSERTION)
    (tmp_path / "lanes.go").write_text(text)
    edited_lanes = compile_file(tmp_path / "lanes.go")
    edited_lanes = restamp(edited_lanes, first.mission_id)
    as_written = {d: execution_digest(p) for d, p in edited_lanes.programs.items()}
    renumbered = {d: execution_digest(p) for d, p in rekey(base, edited_lanes).programs.items()}
    before = {d: execution_digest(p) for d, p in first.programs.items()}
    # Numbered as written, the insertion into Drone1's lane (written first) renumbers
    # Drone2's nodes: its program changes too.  Renumbered, only Drone1's changes.
    assert as_written["Drone2"] != before["Drone2"]
    assert renumbered["Drone2"] == before["Drone2"] and renumbered["Drone1"] != before["Drone1"]


def test_without_the_earlier_run_folder_a_rollout_compares_as_numbered(tmp_path):
    first = rolled_out(LANES, tmp_path / "run1")
    gone = {"mission_id": first.mission_id, "run_dir": str(tmp_path / "elsewhere")}
    assert earlier_programs({"Drone1": probe_with(gone, {})}, first.mission_id) == {}
    other = {"mission_id": "another", "run_dir": str(tmp_path / "run1")}
    assert earlier_programs({"Drone1": probe_with(other, {})}, first.mission_id) == {}
    assert earlier_programs({"Drone1": probe_with(None, {})}, first.mission_id) == {}


def test_decide_keeps_an_unchanged_program_and_copies_a_changed_config():
    program = compile_file(EXPERIMENT_B).programs["Drone1"]
    plan = plan_for(program, "new config")
    file_sha = "ab" * 32
    stamp = {
        "digest": plan.digest,
        "mission_id": program.mission_id,
        "eamos": __version__,
        "program_sha256": file_sha,
        "checksum": "sha256:old",
    }
    decide(
        plan,
        probe_with(stamp, {"programs/Drone1.program.json": file_sha, "configs/Drone1.toml": "x"}),
        None,
    )
    assert not plan.copy_program and plan.copy_config and not plan.copy_keys
    assert plan.state == "unchanged, kept"
    assert plan.deployed_checksum == "sha256:old"  # what the drone will report when ready


def test_decide_redeploys_a_tampered_or_missing_program():
    program = compile_file(EXPERIMENT_B).programs["Drone1"]
    stamp = {
        "digest": execution_digest(program),
        "mission_id": program.mission_id,
        "eamos": __version__,
        "program_sha256": "ab" * 32,
        "checksum": "sha256:old",
    }
    plan = plan_for(program)
    decide(plan, probe_with(stamp, {"programs/Drone1.program.json": "cd" * 32}), None)
    assert plan.copy_program and plan.state == "changed, redeployed"
    plan = plan_for(program)
    decide(plan, probe_with(None, {}), None)
    assert plan.copy_program and plan.state == "new, deployed"
    assert plan.deployed_checksum == program.checksum


# -- the probe ----------------------------------------------------------------------------------


PROBE_OUT = """\
@@version
eamos 0.0.9
@@rc 0
@@df
/dev/sda1 1000 10 123456 1% /home
@@stamp
{"digest": "sha256:d", "checksum": "sha256:c"}

@@sums
aaaa  programs/Drone1.program.json
bbbb  configs/Drone1.toml
@@pid
alive 4242
@@end
"""


def test_parse_probe_and_version_mismatch_names_the_fix():
    probe = parse_probe(PROBE_OUT)
    assert probe.version == "0.0.9" and probe.free_kb == 123456
    assert probe.stamp == {"digest": "sha256:d", "checksum": "sha256:c"}
    assert probe.sums == {"programs/Drone1.program.json": "aaaa", "configs/Drone1.toml": "bbbb"}
    assert probe.pid == 4242 and probe.alive
    with pytest.raises(DroneError) as err:
        check_version(SshTarget("Drone1", "198.18.0.2", user="ubuntu"), probe)
    assert str(err.value) == (
        f"Drone1 (ubuntu@198.18.0.2:22): version mismatch: drone has eamos 0.0.9, operator "
        f"{__version__}: run `pip install eamos=={__version__}` on the drone"
    )


def test_missing_eamos_node_says_how_to_install():
    probe = parse_probe("@@version\nsh: 1: eamos-node: not found\n@@rc 127\n@@end\n")
    with pytest.raises(DroneError) as err:
        check_version(SshTarget("Drone1", "h"), probe)
    assert err.value.kind == "eamos not found"
    assert "pip install eamos==" in err.value.detail and "node_command" in err.value.detail


# -- ssh errors -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("stderr", "kind"),
    [
        ("ssh: connect to host 198.18.0.4 port 22: Connection refused", "unreachable"),
        ("ssh: connect to host 198.18.0.9 port 22: Connection timed out", "unreachable"),
        ("ssh: Could not resolve hostname drone7: Name or service not known", "unreachable"),
        ("root@198.18.0.2: Permission denied (publickey).", "wrong key"),
        ('scp: dest open "x": No space left on device', "disk full"),
        ("mkdir: cannot create directory 'a': No space left on device", "disk full"),
        ("@@@ WARNING: REMOTE HOST IDENTIFICATION HAS CHANGED! @@@", "host key changed"),
    ],
)
def test_ssh_failures_are_classified(stderr, kind):
    found = classify("Warning: something\n" + stderr + "\n")
    assert found is not None and found[0] == kind


def test_unknown_failures_are_not_guessed():
    assert classify("some other problem") is None


# -- fleet settings ---------------------------------------------------------------------------


def fleet(tmp_path: Path, text: str) -> FleetConfig:
    path = tmp_path / "fleet.toml"
    path.write_text(text)
    return FleetConfig.load(path)


GOOD = """
[ground]
bind = "tcp://198.18.0.1:6000"
[defaults.ssh]
user = "ubuntu"
folder = "missions"
[defaults.hal]
adapter = "sim"
[drones.Drone1.ssh]
host = "198.18.0.2"
[drones.Drone2.ssh]
host = "198.18.0.3"
port = 2222
[drones.Drone2]
bind = "tcp://198.18.0.3:7000"
[drones.Drone2.hal]
speedup = 3
"""


def test_fleet_targets_merge_defaults_and_default_endpoints(tmp_path):
    targets = load_targets(fleet(tmp_path, GOOD), ["Drone1", "Drone2"])
    d1, d2 = targets.drones["Drone1"], targets.drones["Drone2"]
    assert d1.label == "ubuntu@198.18.0.2:22" and d2.label == "ubuntu@198.18.0.3:2222"
    assert d1.mission_dir("experiment_b") == "missions/experiment_b"
    assert targets.endpoints == {
        "Drone1": "tcp://198.18.0.2:6001",
        "Drone2": "tcp://198.18.0.3:7000",
    }
    assert targets.hal["Drone2"] == {"adapter": "sim", "speedup": 3}
    argv = d2.ssh_argv("true")
    assert (
        argv[0] == "ssh" and "BatchMode=yes" in argv and argv[-2:] == ["ubuntu@198.18.0.3", "true"]
    )
    assert "-p" in argv and argv[argv.index("-p") + 1] == "2222"


def test_eamos_run_ignores_the_rollout_tables(tmp_path):
    config = fleet(tmp_path, GOOD)
    assert config.hal_for("Drone2") == {"adapter": "sim", "speedup": 3}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (GOOD.replace('host = "198.18.0.3"\n', ""), "drones.Drone2.ssh.host: required"),
        (GOOD.replace("port = 2222", 'port = "x"'), "drones.Drone2.ssh.port: must be a number"),
        (GOOD.replace('user = "ubuntu"', 'usr = "ubuntu"'), "defaults.ssh.usr: unknown field"),
        (GOOD.replace('bind = "tcp://198.18.0.1:6000"\n', ""), "ground.bind: required"),
        (
            GOOD.replace("tcp://198.18.0.3:7000", "tcp://*:7000"),
            "drones.Drone2.bind: use the address",
        ),
        (GOOD + "[drones.Drone1.ssh.x]\n", "drones.Drone1.ssh.x: unknown field"),
        (GOOD.replace('folder = "missions"', 'identity = "nokey"'), "nokey: no such file"),
    ],
)
def test_bad_fleet_settings_name_the_field(tmp_path, text, message):
    with pytest.raises(ConfigError) as err:
        load_targets(fleet(tmp_path, text), ["Drone1", "Drone2"])
    assert message in str(err.value) and "fleet.toml" in str(err.value)


def test_a_network_fleet_without_keys_is_refused_before_any_drone_is_touched(tmp_path):
    from eamos.ops.plan import check_security

    targets = load_targets(fleet(tmp_path, GOOD), ["Drone1", "Drone2"])
    with pytest.raises(ConfigError) as err:
        check_security(targets, ["GCS", "Drone1", "Drone2"])
    assert "ground.keys: required" in str(err.value) and "eamos keys" in str(err.value)
    local = GOOD.replace("198.18.0.", "127.0.0.")
    check_security(load_targets(fleet(tmp_path, local), ["Drone1", "Drone2"]), ["GCS"])


def test_drone_config_has_peers_and_security(tmp_path):
    endpoints = {"Drone1": "tcp://198.18.0.2:6001", "Drone2": "tcp://198.18.0.3:6002"}
    config = drone_config(
        "Drone1", tmp_path, endpoints, "tcp://198.18.0.1:6000", {"adapter": "sim"}, 30, True
    )
    assert config.path == tmp_path / "configs" / "Drone1.toml"
    text = config.to_toml()
    path = config.write()
    import tomllib

    doc = tomllib.loads(text)
    assert doc["net"]["bind"] == "tcp://198.18.0.2:6001"
    assert doc["net"]["peers"] == {
        "GCS": "tcp://198.18.0.1:6000",
        "Drone2": "tcp://198.18.0.3:6002",
    }
    assert (
        doc["net"]["keys"] == "../keys/Drone1"
        and doc["program"] == "../programs/Drone1.program.json"
    )
    plain = tomllib.loads(drone_config("Drone1", tmp_path, endpoints, "x", {}, 30, False).to_toml())
    assert plain["net"]["plain"] is True and "keys" not in plain["net"]
    assert plain["net"]["telemetry_max_hz"] == LinkSettings().telemetry_max_hz
    # The telemetry rate the roll-out computes (as eamos run: telemetry_links) is written.
    slow = drone_config(
        "Drone1", tmp_path, endpoints, "x", {}, 30, False, link=LinkSettings(telemetry_max_hz=2.0)
    )
    assert tomllib.loads(slow.to_toml())["net"]["telemetry_max_hz"] == 2.0
    # The text is one eamos-node reads back (keys from the fleet's folder, as on a drone).
    keys = create_fleet_keys(tmp_path / "keys", ["GCS", "Drone1", "Drone2"], force=True)
    assert NodeConfig.load(path).keys_dir == keys / "Drone1"


def test_paper_table_rows():
    rows = dict(
        paper_table({"compile": 0.3, "probe": 0.5, "deploy": 0.4, "launch": 0.6, "ready": 1.2})
    )
    assert rows == {"mission compilation": 0.3, "mission deployment": 0.4, "total roll-out": 3.0}


# -- status ------------------------------------------------------------------------------------


def event(kind: str, node: str, action: str, args=(), status: str = "ok") -> dict:
    return {
        "event": kind,
        "token": [node, []],
        "action": action,
        "args": list(args),
        "status": status,
    }


def test_current_action_from_uniform_log():
    events = [
        event("uniform.call", "n2", "Arm"),
        event("uniform.result", "n2", "Arm"),
        event("uniform.call", "n5", "Takeoff", [1.5]),
    ]
    assert current_action(events) == "Takeoff(1.5)"
    assert current_action([*events, event("uniform.result", "n5", "Takeoff", [1.5])]) == (
        "idle (last: Takeoff(1.5) ok)"
    )
    assert current_action([]) == "idle"


def test_stamp_round_trip_through_json():
    program = compile_file(EXPERIMENT_B).programs["Drone2"]
    plan = plan_for(dataclasses.replace(program, mission_id="m"))
    plan.copy_program = True
    from eamos.ops.plan import stamp_text

    doc = json.loads(stamp_text(plan, None))
    assert doc["digest"] == plan.digest and doc["checksum"] == plan.program.checksum
    assert doc["mission_id"] == "m" and doc["eamos"] == __version__


def test_the_example_fleet_file_is_valid(tmp_path, monkeypatch):
    (tmp_path / "configs").mkdir()
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    keys = tmp_path / "home" / ".local" / "share" / "eamos" / "keys"
    keys.mkdir(parents=True)  # `eamos keys --fleet ...` would make it
    example = tmp_path / "configs" / "fleet_example.toml"
    example.write_text((REPO / "configs" / "fleet_example.toml").read_text())
    config = FleetConfig.load(example)
    assert config.hal_for("Drone2")["adapter"] == "mavlink"
    targets = load_targets(config, ["Drone1", "Drone2"])
    assert targets.ground.keys == keys
    assert targets.endpoints["Drone2"] == "tcp://192.0.2.12:6002"
    assert targets.drones["Drone1"].label == "pi@192.0.2.11:22"


def test_a_rollout_becomes_runs_latest_when_it_starts_flying(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from eamos.ops.start import _flying

    monkeypatch.chdir(tmp_path)
    said: list[str] = []
    rolled = tmp_path / "runs" / "experiment_b-20261126-120000"
    rolled.mkdir(parents=True)
    _flying(rolled, said.append, 1.5)
    assert said == ["ready 1.50 s"]
    assert (tmp_path / "runs" / "latest").resolve() == rolled
    # A roll-out into a folder of its own (--run-dir elsewhere) leaves runs/latest alone.
    elsewhere = tmp_path / "lab" / "b"
    elsewhere.mkdir(parents=True)
    _flying(elsewhere, said.append, 2.0)
    assert (tmp_path / "runs" / "latest").resolve() == rolled
