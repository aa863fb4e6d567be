"""Random Try missions in the virtual driver: a caught failure never fails the run, cancels
every drone's part of Body at once, and keeps one trigger per external arc (Table 7)."""

from __future__ import annotations

import os

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from eamos.compiler import compile_mission
from eamos.hal.sim.settings import SimSettings
from eamos.virtual import run_virtual, sim_vehicles

SCALE = float(os.environ.get("EAMOS_HYPOTHESIS_EXAMPLES", "1"))
MOVES = ("FlyByX", "FlyByY", "FlyByZ")

move = st.tuples(st.sampled_from(MOVES), st.integers(min_value=1, max_value=4))
bodies = st.lists(st.lists(move, min_size=1, max_size=4), min_size=2, max_size=3)


def mission(body: list[list[tuple[str, int]]]) -> str:
    drones = [f"D{i + 1}" for i in range(len(body))]
    out = ["package m", ""] + [f"var {d} Quadcopter" for d in drones] + [""]
    out += ["func SEQ_M() {", "\tPAR_Up()", "\tTry(PAR_Body, PAR_Fail)", "\tPAR_Down()", "}"]
    out += ["func PAR_Up() {"] + [f"\tSEQ_Up{d}()" for d in drones] + ["}"]
    for d in drones:
        out += [f"func SEQ_Up{d}() {{", f"\t{d}.Arm()", f"\t{d}.Takeoff(2)", "}"]
    out += ["func PAR_Body() {"] + [f"\tSEQ_Body{d}()" for d in drones] + ["}"]
    for d, moves in zip(drones, body, strict=True):
        out += [f"func SEQ_Body{d}() {{"] + [f"\t{d}.{a}({n})" for a, n in moves] + ["}"]
    out += ["func PAR_Fail() {"]
    out += [f"\t{d}.FlyToXYZ(0, {3 * i}, 2)" for i, d in enumerate(drones)] + ["}"]
    out += ["func PAR_Down() {"] + [f"\t{d}.Land()" for d in drones] + ["}"]
    return "\n".join(out) + "\n"


@settings(
    max_examples=max(1, int(25 * SCALE)),
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(bodies, st.integers(min_value=0, max_value=2), st.sampled_from((*MOVES, "none")))
def test_a_caught_failure_cancels_every_drone_and_counts_every_arc(body, who, rejected) -> None:
    compiled = compile_mission(mission(body), "p.go")
    failing = f"D{who % len(body) + 1}"
    fails = rejected != "none" and any(a == rejected for a, _ in body[who % len(body)])
    settings_ = {failing: SimSettings(reject_actions=(rejected,))} if rejected != "none" else {}
    run = run_virtual(compiled.programs, sim_vehicles(settings_), time_limit_s=600)
    assert run.ok, run.waiting
    for name, outcome in run.drones.items():
        stats = compiled.programs[name].stats()
        assert (outcome.triggers_sent, outcome.triggers_received) == (
            stats["external_out"],
            stats["external_in"],
        ), name
    records = [a for o in run.drones.values() for a in o.actions]
    caught = [a for a in records if a.result == "caught"]
    recovery = [a for a in records if a.action == "FlyToXYZ"]
    if not fails:
        assert not caught and not recovery
        assert all(a.result == "ok" for a in records)
        return
    assert len(caught) == 1 and caught[0].action == rejected
    assert len(recovery) == len(body)  # OnFailure ran on every drone
    at = caught[0].end
    for name, outcome in run.drones.items():
        if name == "GCS":
            continue
        moves = [a for a in outcome.actions if a.action in MOVES]
        # Nothing of Body starts after the failure; what ran then was cancelled at once.
        assert all(a.start <= at + 1e-6 for a in moves), name
        for a in moves:
            if a.end > at + 0.2:
                raise AssertionError(f"{name}: {a.action} ran on after the failure")
