"""The stress-test generator makes missions of the sizes it promises, and they compile."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

from eamos.compiler import compile_mission

from .compiler_helpers import REPO


def _bench() -> ModuleType:
    path = REPO / "scripts" / "bench_compile.py"
    spec = importlib.util.spec_from_file_location("bench_compile", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_compile"] = module
    spec.loader.exec_module(module)
    return module


def test_single_drone_mission_has_a_34_node_meg() -> None:
    c = compile_mission(_bench().single_drone_mission(33), "s.go")
    assert c.meg.number_of_nodes() == 34 and list(c.programs) == ["GCS", "Drone1"]


def test_fleet_mission_size_and_shape() -> None:
    bench = _bench()
    c = compile_mission(bench.fleet_mission(20, steps=2), "f.go")
    assert len(c.programs) == 21
    # per round: 1 fork + 4 group forks + 20 * 12 actions + 1 solo action
    assert c.meg.number_of_nodes() == 1 + 2 * (1 + 4 + 20 * 12 + 1)
    assert c.warnings == ()


def test_measure_runs_a_fresh_process() -> None:
    figures = _bench().measure(_bench().single_drone_mission(33), timeout=120)
    assert figures["meg_nodes"] == 34 and figures["drones"] == 1
    assert 0 < figures["seconds"] < 5 and figures["peak_rss_mb"] > 0
    assert {"parse_seconds", "slice_seconds", "synthesis_seconds"} <= set(figures)


def test_measure_goes_through_every_phase_of_a_mission_with_groups() -> None:
    # The phase-by-phase figures expand loops and load libraries, as compile_mission does.
    fleet100 = REPO / "missions" / "fleets" / "fleet100.go"
    figures = _bench().measure(
        fleet100.read_text(encoding="utf-8"), timeout=300, folder=fleet100.parent
    )
    assert figures["drones"] == 100 and figures["meg_nodes"] == 914
    assert "expand_seconds" in figures
