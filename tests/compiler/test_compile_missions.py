"""Every mission shipped in missions/ and every paper listing compiles unchanged."""

from __future__ import annotations

from pathlib import Path

import pytest

from eamos.compiler import compile_file
from eamos.compiler.dependency_graph import mdg_stats

from .compiler_helpers import MISSIONS, PAPER_COPIES, mission_files

OWN_MISSIONS = ["inspection_if.go", "survey_repeat.go", "patrol_do.go", "relay_wait.go"]


def test_missions_folder_has_the_paper_listings_and_our_own() -> None:
    present = {p.name for p in mission_files()}
    assert set(PAPER_COPIES) <= present
    assert set(OWN_MISSIONS) <= present


@pytest.mark.parametrize("path", mission_files(), ids=lambda p: p.name)
def test_mission_compiles_without_warnings(path: Path) -> None:
    compiled = compile_file(path)
    assert compiled.warnings == ()
    assert set(compiled.programs) == set(compiled.mdgs)
    assert next(iter(compiled.programs)) == "GCS"
    # The programs carry exactly the MDG figures.
    for drone, program in compiled.programs.items():
        assert program.stats() == mdg_stats(compiled.mdgs[drone])


@pytest.mark.parametrize("copy", sorted(PAPER_COPIES))
def test_paper_listing_copies_compile(copy: str) -> None:
    compile_file(MISSIONS / copy)


def test_own_missions_use_every_control_structure() -> None:
    kinds: set[str] = set()
    bare_pause_for_hosts: set[str] = set()
    for name in OWN_MISSIONS:
        compiled = compile_file(MISSIONS / name)
        kinds |= {a["kind"] for _, a in compiled.amt.nodes(data=True)}
        for _, a in compiled.meg.nodes(data=True):
            if a.get("action") == "PauseFor":
                bare_pause_for_hosts.add(a["drone"])
    assert {
        "if",
        "repeat_for",
        "repeat_until",
        "do_while",
        "do_until",
        "wait_until",
        "pause_while",
        "pause_until",
    } <= kinds
    assert "GCS" in bare_pause_for_hosts  # relay_wait starts with a bare PauseFor


def test_own_missions_stay_low_and_small() -> None:
    """Realistic missions: 1 to 3 drones, take-off heights of at most 10 m."""
    for name in OWN_MISSIONS:
        compiled = compile_file(MISSIONS / name)
        assert 2 <= len(compiled.programs) <= 4
        for _, a in compiled.meg.nodes(data=True):
            if a.get("action") == "Takeoff":
                assert 0 < a["args"][0] <= 10
            if a.get("action") == "FlyToXYZ":
                assert 0 < a["args"][2] <= 10
