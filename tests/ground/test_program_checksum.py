"""A drone running a program other than the one compiled for the run is not started (issue 28).

A program file edited on disk with its checksum recomputed loads (the checksum guards
against damage, not against an edit); what catches it is the ground station comparing the
checksum each drone announces in ``Ready`` with the compiled program's.  The real thing:
``eamos run``'s fly loop with a real ``eamos-node`` process reading the edited file.
"""

from __future__ import annotations

import dataclasses
import io
import threading
from pathlib import Path

import pytest

from eamos.compiler import compile_file, write_artifacts
from eamos.config import FleetConfig
from eamos.ground import GroundStation, Limits, LocalMission, PlainDisplay, fly_local
from eamos.net import wire
from eamos.program import load_program

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.timeout(300)


def test_a_ready_naming_another_program_is_refused_not_counted_ready() -> None:
    station = GroundStation(["D1"], "m", checksums={"D1": "sha256:compiled", "GCS": "sha256:g"})
    for _ in range(2):  # Ready is resent until acknowledged: one failure, said once
        station.handle(wire.Ready(mission="m", sender="D1", program_checksum="sha256:edited"))
    assert station.not_ready() == ["D1"]
    assert station.failures == [
        "D1: runs a program other than the one compiled for this run "
        "(checksum sha256:edited..., expected sha256:compiled...): not started"
    ]
    assert not station.wait_ready(5.0)  # fails at once, not after the timeout
    station.handle(wire.Ready(mission="m", sender="D1", program_checksum="sha256:compiled"))
    assert station.not_ready() == []


def test_eamos_run_does_not_start_a_drone_whose_program_file_was_edited(tmp_path: Path) -> None:
    compiled = compile_file(REPO / "missions" / "experiment_a.go")
    run_dir = tmp_path / "run"
    write_artifacts(compiled, run_dir, svg=False)
    path = run_dir / "programs" / "Drone1.program.json"
    honest = load_program(path)
    # An edit with the checksum recomputed: FlyByX(1) flies 100 m instead.
    nodes = tuple(
        dataclasses.replace(n, args=(100.0,)) if n.action == "FlyByX" else n for n in honest.nodes
    )
    edited = dataclasses.replace(honest, nodes=nodes)
    edited.save(path)
    assert load_program(path).checksum == edited.checksum != honest.checksum  # it loads
    out = io.StringIO()
    summary = fly_local(
        LocalMission(compiled.mission.name, compiled.mission_id, compiled.programs),
        run_dir,
        FleetConfig.empty(),
        Limits(ready_timeout_s=60, timeout_s=120),
        threading.Event(),
        speedup=20,
        display=PlainDisplay(out),
    )
    assert not summary.ok
    assert "Drone1: runs a program other than the one compiled for this run" in summary.outcome
    report = summary.drones["Drone1"].report
    # Not started: no action ran, the vehicle never left the ground.
    assert report is None or not report.actions
    assert report is None or report.final is None or not report.final.armed
