"""A virtual run continues from a real run's snapshot (issue 30): real processes, sim drones.

``eamos run missions/survey_repeat.go``, ``eamos pause`` while Drone1 flies its third
survey lane (a RepeatFor's third iteration; Drone2 is in its RepeatUntil), the snapshot
kept, ``eamos resume``, the run ends.  Continued from the kept snapshot, the virtual run
replays every action the snapshot had as ended without flying it, flies exactly the
actions the real run went on to fly (same nodes, same loop counters, same order) from
where the drones were, and ends where the real drones ended; ``eamos check --from``
checks that rest.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from eamos.compiler import compile_file
from eamos.virtual import VirtualMission, continuation, load_snapshot
from tests.operator.runs import operator, resume_to_the_end, start
from tests.support.runs import MISSIONS, eamos

pytestmark = pytest.mark.e2e

SURVEY = MISSIONS / "survey_repeat.go"
THIRD_LANE = "Drone1 running   FlyByX(4)"
#: Where the continuation's drones end against where the real ones did: the simulated
#: vehicle's settle tolerance twice, and the snapshot's position (telemetry at the
#: ground station's rate) of the leg that was flying.
END_M = 0.5


def test_a_virtual_run_continues_from_a_paused_runs_snapshot_as_the_run_went_on(
    tmp_path: Path,
) -> None:
    run = start(tmp_path, SURVEY, speedup=1)
    kept = tmp_path / "paused" / "snapshot.json"
    try:
        run.wait_for(THIRD_LANE, count=3)
        operator("pause", str(run.run_dir))
        kept.parent.mkdir()
        shutil.copy(run.run_dir / "snapshot.json", kept)
        summary = resume_to_the_end(run, tmp_path)
    finally:
        run.kill()
    doc = load_snapshot(kept.parent)
    past = continuation(doc)
    compiled = compile_file(SURVEY)
    rest = VirtualMission(compiled.programs, continuation=past).run()
    assert rest.ok, rest
    lanes = [
        e["iteration"]
        for e in doc["participants"]["Drone1"]["activations"]
        if e.get("action") == "FlyByX(4)"
    ]
    assert [2] in lanes, lanes  # paused in the third lane
    for drone in ("Drone1", "Drone2"):
        real = summary["drones"][drone]["actions"]
        states = {(e["node"], tuple(e["iteration"])): e["state"]
                  for e in doc["participants"][drone]["activations"]}  # fmt: skip
        ended = [
            (a["node"], tuple(a["iteration"]))
            for a in real
            if states.get((a["node"], tuple(a["iteration"]))) in ("ok", "failed", "cancelled")
        ]
        went_on = [
            (a["node"], tuple(a["iteration"]))
            for a in real
            if (a["node"], tuple(a["iteration"])) not in ended
        ]
        assert ended and went_on, (drone, states)
        # Replayed, not flown: what the snapshot had as ended.
        assert sorted((n, it) for d, n, it in rest.replayed if d == drone) == sorted(ended)
        replayed = set(ended)
        flown = [
            (r.node, tuple(r.iteration))
            for r in rest.drones[drone].actions
            if (r.node, tuple(r.iteration)) not in replayed
        ]
        assert flown == went_on, (drone, flown, went_on)
        end = summary["drones"][drone]["final"]
        final = rest.drones[drone].final
        gap = math.dist((end["x"], end["y"], end["z"]), (final.x_m, final.y_m, final.z_m))
        assert gap < END_M, (drone, end, final)
    proc = eamos("check", str(SURVEY), "--from", str(kept.parent))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "the rest of the mission from" in proc.stdout
