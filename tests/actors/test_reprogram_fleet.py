"""An amendment applied to a whole fleet in one process: real runtimes, real ZeroMQ.

Two drones (:mod:`tests.actors.fleet_harness`, fake vehicles the test finishes by hand)
are held in their ``Arm`` while the ground station's :class:`AmendmentApplier` applies an
amendment of D1's later leg: a changed leg and a new one, which D2 now waits for across
the link (D2's part changes too: its incoming arc).  Both switch; D1 flies the new legs
and D2 takes its trigger from D1's new node.  Prepared but never committed, D1 cancels an
amendment by itself after ``PREPARED_FOR_S`` and tells the ground station: the mission
flies as written.
"""

from __future__ import annotations

import json
import shutil
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.actors import reprogram
from eamos.compiler import compile_mission
from eamos.compiler.amendment import rekey
from eamos.ground.amend import JUDGED_AGAINST, AmendmentApplier, judged_against
from eamos.net import wire
from eamos.program.uniform import GROUND_STATION

from .fleet_harness import WAIT_S, Fleet, make_fleet

SOURCE = """package T

var D1 Quadcopter
var D2 Quadcopter

func SEQ_M() {
	PAR_Up()
	D1.FlyByX(3)
	D2.FlyByX(3)
	PAR_Down()
}

func PAR_Up() {
	D1.Arm()
	D2.Arm()
}

func PAR_Down() {
	D1.Land()
	D2.Land()
}
"""
AMENDED = SOURCE.replace("\tD1.FlyByX(3)\n", "\tD1.FlyByX(4)\n\tD1.FlyByZ(1)\n")


class Answers:
    """The drones' answers, as the ground station's amendment applier takes them."""

    def __init__(self) -> None:
        self.got: list[wire.Amend] = []
        self.cond = threading.Condition()

    def __call__(self, msg: wire.Amend) -> None:
        with self.cond:
            self.got.append(msg)
            self.cond.notify_all()

    def wait(self, phase: str) -> wire.Amend:
        with self.cond:
            assert self.cond.wait_for(lambda: any(a.phase == phase for a in self.got), WAIT_S)
            return next(a for a in self.got if a.phase == phase)


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[Fleet, Answers]]:
    made = make_fleet(SOURCE, auto=False, log_dir=tmp_path)
    answers = Answers()
    made.station.amendment_answers = answers
    yield made, answers
    made.close()


def send(fleet: Fleet, phase: str, program: bytes = b"") -> None:
    msg = wire.Amend(
        mission=fleet.compiled.mission_id,
        sender=GROUND_STATION,
        dest="D1",
        number=1,
        phase=phase,  # type: ignore[arg-type]
        program=program,
    )
    fleet.runtimes[GROUND_STATION].send(msg)


def amended_program(fleet: Fleet) -> bytes:
    new = rekey(fleet.compiled.programs, compile_mission(AMENDED, "test.go"))
    return new.programs["D1"].to_json().encode()


def fly_on(fleet: Fleet) -> dict[str, list[tuple[str, tuple[Any, ...]]]]:
    """Let both vehicles finish every action from now on; the actions each ran."""
    for name in ("D1", "D2"):
        fake = fleet.adapters[name]
        fake.auto = True
        fake.finish("Arm")
    assert fleet.wait_resolved(), fleet.station.unresolved()
    return {
        name: [(c.action, tuple(c.args)) for c in fleet.adapters[name].calls_of("run")]
        for name in ("D1", "D2")
    }


def hold_arms(fleet: Fleet) -> None:
    fleet.start()
    for name in ("D1", "D2"):
        fleet.adapters[name].wait_started("Arm", WAIT_S)


def test_a_committed_amendment_flies_and_the_peer_waits_for_the_new_node(
    fleet: Any, tmp_path: Path
) -> None:
    made, _ = fleet
    run_dir = tmp_path / "run"
    staged = run_dir / "amendments" / "1"
    (run_dir / "programs").mkdir(parents=True)
    (staged / "programs").mkdir(parents=True)
    new = rekey(made.compiled.programs, compile_mission(AMENDED, "test.go")).programs
    for name, program in made.compiled.programs.items():
        program.save(run_dir / "programs" / f"{name}.program.json")
        new[name].save(staged / "programs" / f"{name}.program.json")
    doc = {"accepted": True, JUDGED_AGAINST: judged_against(made.compiled.programs)}
    (staged / "amendment.json").write_text(json.dumps(doc))
    # A second amendment checked against the same programs, staged before the first is applied.
    shutil.copytree(staged, run_dir / "amendments" / "2")
    applier = AmendmentApplier(made.station, run_dir)
    hold_arms(made)
    assert applier.apply("1", "test") == ""
    assert json.loads((staged / "applied.json").read_text())["drones"] == ["D1", "D2"]
    assert applier.apply("1", "test") == "amendment 1 was applied already"
    # Applied now, it would undo what the first changed: refused, nothing sent.
    assert "checked against other programs than those flying now" in applier.apply("2", "test")
    ran = fly_on(made)
    assert [a for a in ran["D1"] if a[0].startswith("Fly")] == [
        ("FlyByX", (4.0,)),
        ("FlyByZ", (1.0,)),
    ]
    assert [a for a in ran["D2"] if a[0].startswith("Fly")] == [("FlyByX", (3.0,))]
    for name in ("D1", "D2"):
        assert made.runtimes[name].program.checksum == new[name].checksum


def test_a_prepared_amendment_never_committed_is_cancelled_by_the_drone(
    fleet: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    made, answers = fleet
    monkeypatch.setattr(reprogram, "PREPARED_FOR_S", 0.5)
    hold_arms(made)
    send(made, "prepare", amended_program(made))
    answers.wait("prepared")
    cancelled = answers.wait("cancelled")
    assert "no commit within 0.5 s" in cancelled.reason
    send(made, "commit")  # too late: refused, nothing changes
    assert "not prepared here" in answers.wait("refused").reason
    ran = fly_on(made)
    assert [a for a in ran["D1"] if a[0].startswith("Fly")] == [("FlyByX", (3.0,))]
    assert made.runtimes["D1"].program.checksum == made.compiled.programs["D1"].checksum
