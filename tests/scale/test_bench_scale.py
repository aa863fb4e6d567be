"""scripts/bench_scale.py: the relay mission it generates, and a smoke run at 10 and 25 drones.

The smoke run asserts only that the benchmark completes and that its JSON has
every field (never a time: speed is the benchmark's to report, not a test's).
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

from eamos.compiler import compile_mission

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "bench_scale.py"


def _bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_scale", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_scale"] = module
    spec.loader.exec_module(module)
    return module


def test_relay_mission_is_a_relay_then_squares_then_a_reverse_relay() -> None:
    compiled = compile_mission(_bench().relay_mission(4), "relay.go")
    assert sorted(compiled.programs) == ["D1", "D2", "D3", "D4", "GCS"]
    # Every drone waits for the one before it (up) and after it (down): external arcs both ways.
    stats = {n: p.stats() for n, p in compiled.programs.items() if n != "GCS"}
    assert stats["D2"]["external_in"] >= 2 and stats["D2"]["external_out"] >= 2
    assert compiled.warnings == ()


def test_relay_gaps_pair_each_drone_with_the_next() -> None:
    bench = _bench()

    class Entry:
        def __init__(self, action: str, start: float, end: float) -> None:
            self.action, self.start, self.end = action, start, end

    class Report:
        def __init__(self, *entries: Entry) -> None:
            self.actions = entries

    reports = {
        "D1": Report(Entry("Arm", 0, 1), Entry("Takeoff", 1, 2), Entry("Land", 10, 11),
                     Entry("Disarm", 11, 12)),
        "D2": Report(Entry("Arm", 2.5, 3), Entry("Takeoff", 3, 4), Entry("Land", 8, 9),
                     Entry("Disarm", 9, 9.25)),
    }  # fmt: skip
    assert bench.relay_gaps_ms(reports, 2) == [500.0, 750.0]
    assert bench.percentile([1.0, 2.0, 3.0, 4.0], 0.5) == 2.0
    assert bench.percentile([], 0.99) is None


@pytest.mark.e2e
def test_smoke_run_at_10_and_25_drones_has_every_field() -> None:
    bench = _bench()
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--json", "--drones", "10,25", "--speedup", "50"],
        capture_output=True,
        text=True,
        timeout=1200,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    runs = json.loads(proc.stdout)["runs"]
    assert [r["drones"] for r in runs] == [10, 25]
    for run in runs:
        assert "error" not in run, run.get("error")
        assert set(bench.FIELDS) <= set(run), set(bench.FIELDS) - set(run)
        assert run["ok"] is True, run["outcome"]
        assert set(run["phases_s"]) == set(bench.PHASES)
        assert all(v is not None for v in run["phases_s"].values())
        assert run["relay_gap_ms"]["count"] == 2 * (run["drones"] - 1)
        assert run["cpu_s"] > 0 and run["peak_rss_mb"] > 0
        assert run["simulated_flight_s"] > 0
        assert 0 < run["ground_cpu_s"] < run["cpu_s"] and run["monitor"] is None


@pytest.mark.e2e
def test_smoke_run_with_the_monitor_served_to_a_page() -> None:
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--json", "--drones", "5", "--speedup", "50", "--monitor"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (run,) = json.loads(proc.stdout)["runs"]
    assert run["ok"] is True, run.get("error") or run["outcome"]
    # The page got the run's updates over its websocket.
    assert run["monitor"]["messages_to_page"] > 0 and run["monitor"]["bytes_to_page"] > 0
