"""Several drones in one ``eamos-node`` process (``eamos run --drones-per-process``)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from eamos.cli.exits import EXIT_BAD_INPUT
from eamos.compiler import compile_mission, write_artifacts
from eamos.config import ConfigError, FleetConfig
from eamos.ground import Limits, LocalMission, fly_local, make_display
from eamos.ground.local import process_groups

REPO = Path(__file__).resolve().parents[2]


def relay_mission(n: int) -> str:
    path = REPO / "scripts" / "bench_scale.py"
    spec = importlib.util.spec_from_file_location("bench_scale", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_scale"] = module
    spec.loader.exec_module(module)
    return str(module.relay_mission(n))


def test_groups_keep_mission_order_and_automatic_means_one_per_core() -> None:
    names = [f"D{i}" for i in range(1, 11)]
    assert process_groups(names, 4) == [names[0:4], names[4:8], names[8:10]]
    assert process_groups(names, 1) == [[n] for n in names]
    auto = process_groups(names, None)
    cores = os.cpu_count() or 1
    assert len(auto) == min(cores, len(names))
    assert [n for group in auto for n in group] == names
    with pytest.raises(ConfigError, match="at least 1"):
        process_groups(names, 0)


@pytest.mark.e2e
@pytest.mark.timeout(600)
def test_a_relay_flies_with_two_drones_per_process(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    compiled = compile_mission(relay_mission(4), "relay.go")
    write_artifacts(compiled, run_dir, svg=False)
    drones = ["D1", "D2", "D3", "D4"]
    summary = fly_local(
        LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
        run_dir,
        FleetConfig.empty(),
        Limits(120.0, 300.0),
        threading.Event(),
        speedup=50.0,
        display=make_display(False, drones),
        drones_per_process=2,
    )
    assert summary.ok, summary.outcome
    for name in drones:
        result = summary.drones[name]
        assert result.ok and result.exit_code == 0
        assert (run_dir / "logs" / name / "exit_code").read_text().strip() == "0"
        assert (run_dir / "logs" / name / "mission.log").exists()
    # Two processes, each with its own output beside the drones' folders.
    assert (run_dir / "logs" / "node-D1-D2.out").exists()
    assert (run_dir / "logs" / "node-D3-D4.out").exists()
    # A drone given twice to one process is bad input, said before anything starts.
    config = run_dir / "configs" / "D1.toml"
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli.node", "--config", str(config), "--config", str(config)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == EXIT_BAD_INPUT and "D1 given twice" in proc.stderr
