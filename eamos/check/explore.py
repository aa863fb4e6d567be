"""Run a compiled mission in virtual time and check every run: :func:`check_mission`.

Each drone flies the simulator's kinematic model with its fleet-file settings
(speeds, accelerations, arming delay, battery, scripted pilot), from its home in
the fleet frame; the tracks are recorded and every rule of :mod:`eamos.check.rules`
is applied to the run.
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..compiler import CompiledMission
from ..compiler.drone_types import installed_plugins
from ..config import ConfigError, FleetConfig, SafetySettings, fleet_order
from ..config.types import mavlink_model
from ..hal.api import AdapterError
from ..hal.sim import SimCore, SimSettings
from ..program.plugins import EMPTY_PLUGINS, PluginRegistry
from ..virtual import (
    Continuation,
    Decide,
    QuietLog,
    SnapshotError,
    Vehicle,
    VirtualMission,
    VirtualRun,
)
from ..virtual.decisions import FailHook
from ..virtual.vehicles import Clock
from .branches import Oracle
from .findings import CheckReport, Finding, Place, RunSummary
from .limits import battery, geofence
from .rules import (
    block_files,
    deadlock,
    failed_actions,
    node_index,
    place,
    separation,
    termination,
)
from .tracks import Track, TrackRecorder

#: Virtual seconds after which a run that has not ended is reported (a wait never ending).
CHECK_TIME_LIMIT_S = 1800.0
#: Default bound on the number of explored runs.
MAX_RUNS = 64
#: Default minimum separation (metres, horizontal or vertical).
MIN_SEPARATION_M = 2.0
CHECKS = ("actions", "termination", "deadlock", "separation", "duration")


def sim_settings(fleet: FleetConfig, drone: str) -> tuple[SimSettings, str | None]:
    """The kinematic model of one drone from the fleet file, and a note if approximated."""
    hal = fleet.hal_for(drone)
    adapter = hal.get("adapter", "sim")
    where = f"{fleet.path}: drones.{drone}.hal" if fleet.path else f"drones.{drone}.hal"
    if adapter == "sim":
        try:
            settings = SimSettings.from_mapping(hal)
        except AdapterError as exc:
            raise ConfigError(f"{where}: {exc}") from exc
        # A disturbance is what the check cannot know: the drone is checked without it.
        calm = dataclasses.replace(
            settings, disturbance_speed_factor=1.0, disturbance_drain_factor=1.0
        )
        return calm, None
    if adapter == "mavlink":
        model, note = mavlink_model(hal)
        if model is None:
            return SimSettings(), f"{drone} flies adapter 'mavlink': {note}"
        try:
            return SimSettings.from_mapping(model), None
        except AdapterError as exc:
            raise ConfigError(f"{where}: {exc}") from exc
    return SimSettings(), (
        f"{drone} flies adapter {adapter!r}: checked with the simulator's default kinematic model"
    )


def run_once(
    compiled: CompiledMission,
    settings: Mapping[str, SimSettings],
    homes: Mapping[str, tuple[float, float]],
    time_limit_s: float,
    decide: Decide | None = None,
    fail: FailHook | None = None,
    plugins: PluginRegistry = EMPTY_PLUGINS,
    battery_floor_pct: float | None = None,
    continuation: Continuation | None = None,
) -> tuple[VirtualRun, dict[str, Track]]:
    """One virtual run with every drone's track recorded (fleet frame).

    ``plugins``: the action plugins the simulated drones run (their "sim"
    implementations); a check passes the installed ones, found once.
    ``battery_floor_pct``: the fleet's battery reserve, below which a Try's Body
    action fails (as on the drones).  ``continuation``: the rest of the mission from
    a run's snapshot, each vehicle starting where it saw it.
    """
    recorders: dict[str, TrackRecorder] = {}

    def make(drone: str, clock: Clock) -> Vehicle:
        core = SimCore(
            drone,
            settings.get(drone, SimSettings()),
            QuietLog(),
            clock,
            plugins=plugins,
            start=None if continuation is None else continuation.vehicle(drone),
        )
        rec = TrackRecorder(drone, core, clock, homes.get(drone, (0.0, 0.0)))
        recorders[drone] = rec
        return rec

    run = VirtualMission(
        compiled.programs,
        make,
        time_limit_s,
        decide=decide,
        fail=fail,
        battery_floor_pct=battery_floor_pct,
        continuation=continuation,
    ).run()
    return run, {d: r.track() for d, r in recorders.items()}


def check_run(
    compiled: CompiledMission,
    run: VirtualRun,
    tracks: Mapping[str, Track],
    *,
    branch: str,
    safety: SafetySettings,
    time_limit_s: float,
) -> list[Finding]:
    """Every rule applied to one run."""
    nodes = node_index(compiled.programs, block_files(compiled.mission.blocks))
    return [
        *failed_actions(run, nodes, branch),
        *deadlock(run, nodes, time_limit_s, branch),
        *termination(run, nodes, tracks, branch),
        *separation(run, nodes, tracks, safety.min_separation_m, branch),
        *geofence(run, nodes, tracks, safety, branch),
        *battery(run, nodes, tracks, safety, branch),
    ]


def merge_findings(findings: list[Finding]) -> list[Finding]:
    """One finding per (check, places, drones) over all runs: the first, with a count of others."""
    first: dict[tuple[object, ...], Finding] = {}
    count: dict[tuple[object, ...], int] = {}
    for f in findings:
        key = (f.severity, f.check, f.places, tuple(d for d, _ in f.positions))
        first.setdefault(key, f)
        count[key] = count.get(key, 0) + 1
    return [
        dataclasses.replace(f, message=f"{f.message} (and in {count[k] - 1} other run(s))")
        if count[k] > 1
        else f
        for k, f in first.items()
    ]


@dataclass(frozen=True)
class Measured:
    """What the live look-ahead measured on drones in flight (see :func:`check_mission`)."""

    speeds: Mapping[str, float]
    drains: Mapping[str, float]


def check_mission(
    compiled: CompiledMission,
    fleet: FleetConfig | None = None,
    *,
    time_limit_s: float = CHECK_TIME_LIMIT_S,
    max_runs: int = MAX_RUNS,
    min_separation_m: float | None = None,
    continuation: Continuation | None = None,
    speeds: Mapping[str, float] | None = None,
    drains: Mapping[str, float] | None = None,
) -> CheckReport:
    """Simulate ``compiled`` in virtual time with the fleet's models and check every run.

    ``continuation``: check the rest of the mission from a run's snapshot (each
    drone starts where the snapshot saw it; what had ended is not flown again).
    ``speeds``: horizontal speeds (m/s) measured on drones in flight, used instead of
    their models' (the live look-ahead, :mod:`.lookahead`); ``drains``: how many times
    faster than its model each such drone's battery was seen to drain in the air.
    Raises :class:`~eamos.config.ConfigError` for fleet settings the model cannot use,
    :class:`~eamos.virtual.SnapshotError` for a snapshot of another mission.
    """
    if continuation is not None and continuation.mission_id != compiled.mission_id:
        raise SnapshotError(
            f"the snapshot is of mission {continuation.mission_id}, "
            f"this file compiles to mission {compiled.mission_id}: not the mission that flew"
        )
    return _check_mission(
        compiled,
        fleet,
        time_limit_s,
        max_runs,
        min_separation_m,
        continuation,
        Measured(speeds or {}, drains or {}),
    )


def _check_mission(
    compiled: CompiledMission,
    fleet: FleetConfig | None,
    time_limit_s: float,
    max_runs: int,
    min_separation_m: float | None,
    continuation: Continuation | None,
    measured: Measured,
) -> CheckReport:
    # Bound to the mission, each drone's type selects its [types.NAME.hal] settings.
    fleet = (fleet or FleetConfig.empty()).for_mission(compiled.programs, compiled.mission.types)
    plugins = installed_plugins()
    drones = fleet_order(compiled.programs)
    fleet.check_drones(drones)  # a misspelt [drones.X] table is an error, not ignored
    notes: list[Finding] = [
        Finding(
            "warning",
            "compile",
            d.message,
            (Place("", "", "", d.loc.line, d.loc.col, d.loc.file),),
        )
        for d in compiled.warnings
    ]
    settings: dict[str, SimSettings] = {}
    for drone in drones:
        settings[drone], note = sim_settings(fleet, drone)
        if note:
            notes.append(Finding("warning", "model", note))
    homes = fleet.homes(drones)
    # Each simulated drone stands at its home (so FlyToLLA targets, given in
    # latitude and longitude, are where they are for every drone).
    settings = {d: dataclasses.replace(st, home_m=homes[d]) for d, st in settings.items()}
    speeds, drains = measured.speeds, measured.drains
    for drone, speed in speeds.items():
        if drone in settings:
            settings[drone] = dataclasses.replace(settings[drone], horizontal_speed_mps=speed)
    for drone, factor in drains.items():
        if drone in settings:
            settings[drone] = dataclasses.replace(settings[drone], disturbance_drain_factor=factor)
    safety = fleet.safety
    if min_separation_m is not None:
        safety = dataclasses.replace(safety, min_separation_m=min_separation_m)
    checks: tuple[str, ...] = CHECKS
    if safety.geofence_m or safety.max_altitude_m is not None:
        checks = (*checks, "geofence")
    if safety.battery_reserve_pct is not None:
        checks = (*checks, "battery")
    piloted = {d for d, st in settings.items() if st.pilot}
    runs: list[RunSummary] = []
    findings: list[Finding] = []
    pictured: list[tuple[str, Mapping[str, Track]]] = []
    queue: deque[tuple[int, ...]] = deque([()])
    nodes = node_index(compiled.programs, block_files(compiled.mission.blocks))
    while queue and len(runs) < max_runs:
        prefix = queue.popleft()
        oracle = Oracle(prefix, piloted, lambda drone, key: place(nodes, drone, key).file)
        run, tracks = run_once(
            compiled,
            settings,
            homes,
            time_limit_s,
            oracle,
            oracle.fail,
            plugins=plugins,
            battery_floor_pct=safety.battery_reserve_pct,
            continuation=continuation,
        )
        choices = oracle.choices()
        # Every choice point met beyond the prefix is another run: its other way.
        queue.extend((*choices[:i], 1) for i in range(len(prefix), len(choices)))
        branch = oracle.branch()
        found = check_run(
            compiled, run, tracks, branch=branch, safety=safety, time_limit_s=time_limit_s
        )
        findings.extend(found)
        if found or not runs:
            pictured.append((branch, tracks))
        runs.append(
            RunSummary(
                branch=branch,
                duration_s=run.duration_s,
                timed_out=run.timed_out,
                checked=checks,
                errors=sum(f.severity == "error" for f in found),
                warnings=sum(f.severity == "warning" for f in found),
            )
        )
    used: dict[str, Any] = {
        "min_separation_m": safety.min_separation_m,
        "max_altitude_m": safety.max_altitude_m,
        "geofence_m": [list(p) for p in safety.geofence_m],
        "battery_reserve_pct": safety.battery_reserve_pct,
        "time_limit_s": time_limit_s,
        "homes_m": {d: list(h) for d, h in homes.items()},
    }
    if continuation is not None:
        used["continued_from"] = {"why": continuation.why, "taken_at": continuation.taken_at}
    if speeds:
        used["measured_speeds_mps"] = dict(speeds)
    if drains:
        used["measured_drain_factors"] = dict(drains)
    return CheckReport(
        mission=compiled.mission.name,
        source_file=compiled.source_file,
        runs=tuple(runs),
        findings=tuple(notes + merge_findings(findings)),
        max_runs=max_runs,
        unexplored=len(queue),
        tracks=tuple(pictured),
        settings=used,
    )


__all__ = [
    "CHECKS",
    "CHECK_TIME_LIMIT_S",
    "MAX_RUNS",
    "MIN_SEPARATION_M",
    "check_mission",
    "run_once",
    "sim_settings",
]
