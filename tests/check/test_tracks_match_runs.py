"""The simulated tracks match real runs: what ``eamos check`` predicts at each action's end is
where ``eamos run`` (drone processes, the simulated adapter) reports the drone then."""

from __future__ import annotations

import json

import pytest

from eamos.check.explore import run_once
from eamos.compiler import compile_file
from eamos.config import FleetConfig
from eamos.hal.sim import SimSettings
from tests.support.runs import MISSIONS, run_mission

pytestmark = pytest.mark.e2e
TOLERANCE_M = 0.3


@pytest.mark.parametrize("mission", ["experiment_a", "experiment_b"])
def test_positions_at_each_action_end_match_eamos_run(tmp_path, mission):
    path = MISSIONS / f"{mission}.go"
    compiled = compile_file(path)
    drones = [d for d in compiled.programs if d != "GCS"]
    homes = FleetConfig.empty().homes(drones)
    run, tracks = run_once(compiled, {d: SimSettings() for d in drones}, homes, 600.0)
    proc, summary = run_mission(tmp_path, path)
    assert proc.returncode == 0, proc.stderr
    assert summary["ok"]
    compared = 0
    for drone in drones:
        log = [
            json.loads(line)
            for line in (tmp_path / "run" / "logs" / drone / "adapter.log").read_text().splitlines()
        ]
        # The simulated drone of `eamos run` stood at its home in the fleet frame, as checked.
        (start,) = [doc for doc in log if doc["event"] == "adapter.start"]
        assert start["home_m"] == list(homes[drone])
        ends = [doc for doc in log if doc["event"] == "adapter.action.end"]
        predicted = run.drones[drone].actions
        assert [e["action"] for e in ends] == [a.action for a in predicted], drone
        for real, rec in zip(ends, predicted, strict=True):
            north, east, up = tracks[drone].at(rec.end)
            local = (north - homes[drone][0], east - homes[drone][1], up)
            flown = (real["x_m"], real["y_m"], real["z_m"])
            assert max(abs(a - b) for a, b in zip(local, flown, strict=True)) <= TOLERANCE_M, (
                drone,
                rec.action,
                local,
                flown,
            )
            compared += 1
    assert compared >= 8 * len(drones)  # every action of every drone
