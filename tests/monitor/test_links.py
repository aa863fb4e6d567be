"""Live trigger counts per link from node states (pure; no threads, no clocks).

The oracle is the virtual-time driver: it runs the real node logic of every
participant and routes each trigger itself, so it knows exactly which
triggers crossed which link.  The counts are fed only what the ground station
hears from a real fleet -- each node's state changes (what the executive turns
into Progress: the logic's node events and its action records) and
``Resolved`` -- and must end equal to the driver's, trigger for trigger.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import pytest

from eamos.actors.logic import Emit, Progress, Record, Resolve
from eamos.compiler import compile_file
from eamos.ground.links import LinkArc, LinkCounts, LinkGraph
from eamos.hal.sim.settings import SimSettings
from eamos.monitor.setup import build_setup
from eamos.monitor.state import MonitorState, apply_patches
from eamos.net import wire
from eamos.virtual import VirtualMission, sim_vehicles

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
EVERY_STRUCTURE = REPO / "tests" / "virtual" / "every_structure.go"

Trigger = tuple[str, str, tuple[int, ...]]


class _Quiet:
    """A log that keeps nothing (with a log the node logic makes its progress events)."""

    def __getattr__(self, name: str) -> Any:
        return lambda *args, **fields: None


class Watched(VirtualMission):
    """A virtual run whose node states also go to ``counts``, as a ground station hears them."""

    def __init__(self, programs: Any, counts: LinkCounts, settings: Any = None) -> None:
        super().__init__(programs, sim_vehicles(settings), log=_Quiet())
        self.counts = counts
        self.emitted: dict[tuple[str, str], set[Trigger]] = {}
        self.told: set[str] = set()
        self.seen_sent: list[dict[tuple[str, str], int]] = []
        apply = self._apply_one
        emit, record, resolve = apply[Emit], apply[Record], apply[Resolve]

        def on_emit(node: tuple[str, str], fx: Emit) -> None:
            if fx.route.external:
                link = (node[0], fx.route.drone)
                self.emitted.setdefault(link, set()).add((node[1], fx.route.dst, fx.iteration))
            emit(node, fx)

        def on_progress(node: tuple[str, str], fx: Progress) -> None:
            e = fx.event
            counts.progress(e.node, e.state, tuple(e.iteration))
            self._check_behind()

        def on_record(node: tuple[str, str], fx: Record) -> None:
            r = fx.record
            counts.progress(r.node, r.result, tuple(r.iteration))
            record(node, fx)

        def on_resolve(node: tuple[str, str], fx: Resolve) -> None:
            resolve(node, fx)
            part = self.participants[node[0]]
            if part.all_resolved and node[0] not in self.told:
                self.told.add(node[0])
                counts.resolved(node[0])
                self._check_behind()

        apply[Emit], apply[Progress], apply[Record], apply[Resolve] = (
            on_emit,
            on_progress,
            on_record,
            on_resolve,
        )

    def _check_behind(self) -> None:
        """Never more received than the driver delivered so far (the page never runs ahead)."""
        for link, got in self.counts.received.items():
            assert got <= self.emitted.get(link, set()), link


def programs_of(mission: str) -> dict[str, Any]:
    path = EVERY_STRUCTURE if mission == "every_structure" else MISSIONS / f"{mission}.go"
    return dict(compile_file(path).programs)


def settings_for(mission: str) -> dict[str, SimSettings]:
    if mission not in ("experiment_d", "experiment_d_lands"):
        return {}
    doc = tomllib.loads((REPO / "configs" / "experiment_d_pilot.toml").read_text())
    return {name: SimSettings.from_mapping(d["hal"]) for name, d in doc["drones"].items()}


def watched_run(programs: dict[str, Any], settings: Any = None) -> tuple[Watched, Any]:
    counts = LinkCounts(LinkGraph.from_programs(programs.values()))
    counts.started()  # the ground station's start trigger
    run = Watched(programs, counts, settings)
    return run, run.run()


MISSION_NAMES = [*sorted(p.stem for p in MISSIONS.glob("*.go")), "every_structure"]


@pytest.mark.parametrize("mission", MISSION_NAMES)
def test_counts_from_node_states_equal_the_triggers_that_crossed_each_link(mission):
    run, result = watched_run(programs_of(mission), settings_for(mission))
    assert not result.timed_out
    counts = run.counts
    # Trigger for trigger, on every link: the same (source, destination, iteration).
    for link in {*run.emitted, *counts.sent}:
        assert counts.sent.get(link, set()) == run.emitted.get(link, set()), link
        assert counts.received.get(link, set()) == run.emitted.get(link, set()), link
    # And per participant, the drones' own counts (what the reports' Table 7 says).
    totals = counts.totals()
    for name, outcome in result.drones.items():
        assert totals.get(name, (0, 0)) == (outcome.triggers_sent, outcome.triggers_received)
    # Per arc (the snapshot's "arcs"): each arc's triggers, every iteration once.
    per_arc: dict[tuple[str, str], int] = {}
    for keys in run.emitted.values():
        for src, dst, _ in keys:
            per_arc[(src, dst)] = per_arc.get((src, dst), 0) + 1
    arcs = counts.per_arc()
    for arc in arcs:
        assert arc["sent"] == arc["received"] == per_arc.get((arc["src"], arc["dst"]), 0), arc
    for name, outcome in result.drones.items():
        sent = sum(a["sent"] for a in arcs if a["from"] == name)
        received = sum(a["received"] for a in arcs if a["to"] == name)
        assert (sent, received) == (outcome.triggers_sent, outcome.triggers_received), name


def test_a_loop_mission_counts_more_triggers_than_arcs():
    run, result = watched_run(programs_of("experiment_d"), settings_for("experiment_d"))
    assert not result.timed_out
    over = [c for c in run.counts.counts() if c.sent > c.arcs]
    assert over, "experiment D's loops send their arcs' triggers once per iteration"
    assert all(c.sent == c.received for c in run.counts.counts())


def test_counts_grow_live_and_only_changed_links_are_reported():
    programs = dict(compile_file(MISSIONS / "experiment_b.go").programs)
    counts = LinkCounts(LinkGraph.from_programs(programs.values()))
    assert [(c.src, c.dst) for c in counts.counts()] == [
        ("Drone1", "Drone2"),
        ("Drone2", "Drone1"),
        ("GCS", "Drone1"),
    ]
    assert all(c.sent == c.received == 0 for c in counts.counts())
    started = counts.started()
    assert [(c.src, c.dst, c.sent, c.received) for c in started] == [("GCS", "Drone1", 1, 0)]
    # Drone1's first action ran: the start trigger arrived.
    first = next(n.key for n in programs["Drone1"].native_nodes() if n.kind == "action")
    got = counts.progress(first, "running", ())
    assert [(c.src, c.dst, c.sent, c.received) for c in got] == [("GCS", "Drone1", 1, 1)]
    assert counts.progress(first, "running", ()) == []  # nothing new: nothing reported
    # It finished: its trigger to Drone2 is out, not yet seen to arrive.
    got = counts.progress(first, "ok", ())
    assert [(c.src, c.dst, c.sent, c.received) for c in got] == [("Drone1", "Drone2", 1, 0)]


def test_the_page_state_carries_link_patches():
    compiled = compile_file(MISSIONS / "experiment_a.go")
    setup = build_setup(dict(compiled.programs), {})
    assert setup.links is not None
    state = MonitorState(setup, 0.0)
    page = state.snapshot()
    assert {(v["src"], v["dst"]) for v in page["links"].values()} == set(setup.links.links())
    patches: list[dict[str, Any]] = []
    for name in setup.drones:
        patches += state.apply(name, wire.Ready(mission="m", sender=name, program_checksum=""), 1.0)
    for name in [*setup.drones, "GCS"]:
        patches += state.apply(name, wire.Resolved(mission="m", sender=name), 2.0)
    assert any(p["k"] == "link" for p in patches)
    apply_patches(page, patches)
    assert page["links"] == state.snapshot()["links"]
    assert all(v["sent"] == v["received"] == v["arcs"] for v in page["links"].values())


def test_the_flush_timer_waits_on_the_closing_event_not_a_sleep(monkeypatch):
    """With an hour between flushes, stopping the server still ends its loop at once."""
    from eamos.monitor import server as server_module
    from eamos.monitor.hub import Hub

    monkeypatch.setattr(server_module, "TICK_S", 3600.0)
    setup = build_setup(dict(compile_file(MISSIONS / "experiment_a.go").programs), {})
    server = server_module.MonitorServer(Hub(setup)).start()
    thread = server._thread
    assert thread is not None and thread.is_alive()
    server.stop(drain_s=0)
    assert not thread.is_alive(), "the server's thread still waits for its flush timer"


def test_one_resolved_walks_a_chain_of_thousands_of_nodes():
    """Nothing seen before the end: Resolved alone walks the chain (no recursion limit)."""
    n = 5000
    owner = {f"n{i}": ("A", "B")[i % 2] for i in range(n)}
    arcs = tuple(LinkArc(f"n{i}", f"n{i + 1}", "seq", True) for i in range(n - 1))
    counts = LinkCounts(LinkGraph(owner, dict.fromkeys(owner, "action"), {}, arcs))
    got = counts.resolved("B")  # its last node is n4999: everything before it resolved
    assert {(c.src, c.dst, c.sent, c.received) for c in got} == {
        ("A", "B", n // 2, n // 2),
        ("B", "A", n // 2 - 1, n // 2 - 1),
    }
