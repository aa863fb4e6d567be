"""``eamos rollout``: compile a mission and put it on real drones over SSH (paper V-E, VI-E/F).

Steps, each timed (paper Table 7: compilation, deployment, total roll-out):

1. **compile** on the operator's machine into the run folder (programs, graphs,
   ``manifest.json``), as ``eamos run`` does.
2. **probe** every drone in parallel, one SSH call each: create the mission
   folder, ``eamos-node --version`` (must equal this eamos), free space, the
   stamp of what is deployed there, whether a node still runs.  Any failure
   stops the roll-out here: nothing is copied, nothing started.
3. **deploy**: copy, into a staging folder on each drone, only what changed: the
   program if the drone's part of the mission changed (partial deployment), its
   config if the endpoints or settings changed, the network keys if given.
4. **launch**: on every drone, move the staged files into place, stop a node
   left from an earlier run (SIGTERM: it lands first), start ``eamos-node``
   detached with fresh logs, record its pid.

Then ``eamos start`` (the ground station, :mod:`.ground`) waits until every
drone reports ready and sends the start trigger.  Every drone's node is
(re)started for every run -- a node exits after the mission -- but programs
are copied only to drones whose part changed.

Layout on a drone (``<folder>`` from the fleet file), the same as an ``eamos run``
folder so the same paths work::

    <folder>/<mission>/programs/<Drone>.program.json
    <folder>/<mission>/configs/<Drone>.toml
    <folder>/<mission>/logs/<Drone>/          mission.log, uniform.log, adapter.log, node.out
    <folder>/<mission>/logs/<Drone>.prev/     the previous run's logs
    <folder>/<mission>/state/<Drone>.deployed.json   what was deployed (the stamp)
    <folder>/<mission>/state/<Drone>.pid      the running node
    <folder>/<mission>/keys/                  network keys, when the fleet file names them

**Which drones changed.**  The compiler names a mission by a hash of its text,
so any edit would change every program.  A roll-out therefore gives its
programs a *fleet mission id* (mission name, participants and eamos version),
renumbers the new mission's nodes against the programs the drones run (the earlier
roll-out's, from its run folder: each node keeps its number where its place by
content, block, drone and action, is the same; :mod:`eamos.compiler.amendment`), so
inserting a statement into Drone2's part renumbers nothing of Drone1's, and compares
each drone's program without what does not change its behaviour: source positions
and the labels of *other* drones' nodes.  A drone whose own part is unchanged keeps
the program it has (its copy may show old line numbers).

The parts: :mod:`.identity` (fleet mission id, execution digests), :mod:`.probe`
(step 2), :mod:`.plan` (what to copy, staging, the launch script),
:mod:`.record` (``rollout.json``, step timings); this module runs the steps.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..compiler import CompiledMission, compile_file, write_artifacts
from ..compiler.amendment import rekey
from ..config import FleetConfig, fleet_order
from ..ground import check_hal_settings
from ..ground.local import new_deployment_id, new_run_dir, telemetry_links, use_run_dir
from ..ground.vehicles import mavlink_fleet_settings
from ..program.format import DroneProgram, ProgramError, load_program
from ..program.uniform import GROUND_STATION
from .identity import execution_digest, fleet_mission_id, folder_digest, restamp
from .plan import (
    DronePlan,
    bytes_kb,
    check_security,
    decide,
    diagnose_copy_failure,
    drone_config,
    human_kb,
    launch_script,
    stage,
)
from .probe import Probe, check_version, probe, sections
from .record import (
    Rollout,
    Say,
    Steps,
    write_rollout,
)
from .ssh import DroneError, FleetError, copy_to, for_each, remote_error, run_remote
from .start import running_ground_station, wait_pid_exit
from .targets import FleetTargets, SshTarget, load_targets

COPY_TIMEOUT_S = 300.0
LAUNCH_TIMEOUT_S = 200.0
#: How long an earlier roll-out's ground station gets to end (its drones land, report).
OLD_GROUND_STOP_S = 120.0


@dataclass
class RolloutOptions:
    """What ``eamos rollout`` was asked to do."""

    mission: Path
    fleet: Path
    run_dir: Path | None = None
    speedup: float | None = None
    svg: bool = False
    #: Called once the mission is compiled into the run folder, before any drone is
    #: contacted (``eamos rollout`` passes the pre-flight check; it raises to refuse).
    preflight: Callable[[CompiledMission, FleetConfig, Path], None] | None = None


def _default_run_dir(mission: str) -> Path:
    """A new ``runs/<mission>-<date-time>[-N]/`` folder, unique as ``eamos run``'s are."""
    return new_run_dir(mission)


def _compile(
    opts: RolloutOptions, fleet: FleetConfig
) -> tuple[CompiledMission, FleetConfig, list[str], FleetTargets, Path]:
    """Step 1: compile into the run folder; the fleet settings are checked first.

    Returns the fleet bound to the mission (each drone knows its type, so
    ``[types.NAME.hal]`` tables apply).
    """
    compiled = compile_file(opts.mission)
    fleet = fleet.for_mission(compiled.programs, compiled.mission.types)
    drones = [n for n in compiled.programs if n != GROUND_STATION]
    # Fleet settings are validated before anything is written or contacted.
    fleet.check_drones(drones)
    targets = load_targets(fleet, drones)
    compiled = restamp(compiled, fleet_mission_id(compiled.mission.name, list(compiled.programs)))
    run_dir = (opts.run_dir or _default_run_dir(compiled.mission.name)).resolve()
    use_run_dir(run_dir)
    write_artifacts(compiled, run_dir, svg=opts.svg)
    if opts.preflight is not None:
        opts.preflight(compiled, fleet, run_dir)
    return compiled, fleet, drones, targets, run_dir


def _plans(
    opts: RolloutOptions,
    fleet: FleetConfig,
    compiled: CompiledMission,
    targets: FleetTargets,
    run_dir: Path,
    deployment: str,
) -> dict[str, DronePlan]:
    """Every drone's plan (its program and config); the operator keeps a copy of each config."""
    keys = targets.ground.keys
    # As eamos run: the fleet's ground_telemetry_hz, the peers' rate for drones others read.
    drones = [n for n in compiled.programs if n != GROUND_STATION]
    links = telemetry_links(compiled.programs, drones, fleet)
    plans: dict[str, DronePlan] = {}
    for name in compiled.programs:
        if name == GROUND_STATION:
            continue
        hal = dict(targets.hal[name])
        if opts.speedup is not None and hal.get("adapter", "sim") == "sim":
            hal["speedup"] = opts.speedup
        if hal.get("adapter") == "mavlink":  # its fleet home and the [safety] fence, as eamos run
            hal = {**mavlink_fleet_settings(fleet, name, fleet_order(compiled.programs)), **hal}
        check_hal_settings(name, hal, fleet.path)
        program = compiled.programs[name]
        config = drone_config(
            name,
            run_dir,
            targets.endpoints,
            targets.ground.bind,
            hal,
            targets.ground.ready_timeout_s,
            keys is not None,
            fleet.safety.battery_reserve_pct,
            links[name],
            deployment,
        )
        plans[name] = DronePlan(
            drone=name,
            target=targets.drones[name],
            endpoint=targets.endpoints[name],
            program=program,
            digest=execution_digest(program),
            config_text=config.to_toml(),
            staging=run_dir / "deploy" / name,
            deployment=deployment,
            run_dir=str(run_dir),
        )
        # The operator's copy of every drone's config, as eamos run keeps it.
        (run_dir / "configs").mkdir(exist_ok=True)
        (run_dir / "configs" / f"{name}.toml").write_text(plans[name].config_text)
    return plans


def _probe_each(
    plans: dict[str, DronePlan], mission: str
) -> tuple[dict[str, Probe], list[DroneError]]:
    """Step 2a: probe every drone in parallel (what it has, before anything is touched)."""
    return for_each([p.target for p in plans.values()], lambda t: probe(t, mission))


def earlier_programs(probes: dict[str, Probe], mission_id: str) -> dict[str, DroneProgram]:
    """The programs of the roll-out whose stamps most drones carry, read from its run
    folder on this machine: what the drones run, to renumber the new mission against.
    Empty when there is none, it is of another fleet mission, or its folder is gone."""
    named = Counter(
        str(found.stamp.get("run_dir") or "")
        for found in probes.values()
        if found.stamp and found.stamp.get("mission_id") == mission_id
    )
    named.pop("", None)
    if not named:
        return {}
    folder = Path(named.most_common(1)[0][0]) / "programs"
    programs: dict[str, DroneProgram] = {}
    for path in sorted(folder.glob("*.program.json")) if folder.is_dir() else []:
        try:
            program = load_program(path)
        except ProgramError:
            return {}
        programs[program.drone] = program
    same = all(p.mission_id == mission_id for p in programs.values())
    return programs if same else {}


def renumber_plans(
    compiled: CompiledMission,
    plans: dict[str, DronePlan],
    base: dict[str, DroneProgram],
    run_dir: Path,
    svg: bool,
) -> CompiledMission:
    """Renumber the mission against ``base`` (the programs the drones run) by content,
    so that a drone whose part is unchanged has the program it runs, node for node;
    the run folder's files and every plan follow."""
    if not base:
        return compiled
    compiled = rekey(base, compiled)
    write_artifacts(compiled, run_dir, svg=svg)
    for name, plan in plans.items():
        plan.program = compiled.programs[name]
        plan.digest = execution_digest(plan.program)
    return compiled


def _decide_all(
    plans: dict[str, DronePlan],
    probed: tuple[dict[str, Probe], list[DroneError]],
    mission: str,
    keys: Path | None,
    say: Say,
) -> None:
    """Step 2b: decide and stage every drone's files; FleetError if any is unusable."""
    drones = list(plans)
    probes, errors = probed

    def keys_sha(name: str) -> str | None:
        return None if keys is None else folder_digest(keys / name)

    for name in drones:
        if name not in probes:
            continue
        plan, found = plans[name], probes[name]
        try:
            check_version(plan.target, found)
            decide(plan, found, keys_sha(name))
            plan.files = stage(plan, keys, keys_sha(name))
            need = plan.target.min_free_kb + bytes_kb(plan.files)
            if found.free_kb is not None and found.free_kb < need:
                raise DroneError(
                    name,
                    plan.target.label,
                    "disk full",
                    f"{found.free_kb} kB free in {plan.target.mission_dir(mission)}, "
                    f"the roll-out needs {need} kB (files and ssh.min_free_kb = "
                    f"{plan.target.min_free_kb} for the logs)",
                )
        except DroneError as exc:
            errors.append(exc)
            continue
        line = (
            f"  {name} ({plan.target.label}): eamos {found.version}, "
            f"{human_kb(found.free_kb)} free, {plan.state}"
        )
        if plan.changed:
            line += f", copy {plan.copied()}"
        if plan.old_node:
            line += f", node of an earlier run still up (pid {plan.old_node})"
        say(line)
    if errors:
        raise FleetError(
            f"roll-out stopped at the probe: {len(errors)} of {len(drones)} drone(s) not "
            "usable; nothing was copied or started",
            sorted(errors, key=lambda e: drones.index(e.drone)),
        )


def _deploy_all(plans: dict[str, DronePlan], mission: str, say: Say) -> None:
    """Step 3: copy the staged files of every changed drone; FleetError if a copy fails."""

    def deploy_one(target: SshTarget) -> float:
        plan = plans[target.drone]
        if not plan.files:
            return 0.0
        t0 = time.monotonic()
        staging_remote = f"{target.mission_dir(mission)}/.incoming/{target.drone}"
        try:
            copy_to(target, plan.files, staging_remote, COPY_TIMEOUT_S)
        except DroneError as exc:
            raise diagnose_copy_failure(target, mission, plan.files, exc) from exc
        return time.monotonic() - t0

    copied, errors = for_each([p.target for p in plans.values()], deploy_one)
    for name, plan in plans.items():
        if name in copied and plan.changed:
            plan.durations["copy"] = round(copied[name], 3)
            say(f"  {name}: {plan.state}: copy {copied[name]:.2f} s ({plan.copied()})")
        elif name in copied:
            say(f"  {name}: {plan.state}")
    if errors:
        raise FleetError(
            "roll-out stopped at the deployment; no drone was started (copied files wait "
            "unused in a staging folder)",
            errors,
        )


def earlier_ground_stations(plans: dict[str, DronePlan], run_dir: Path) -> dict[Path, str]:
    """The run folders of earlier roll-outs of this mission on these drones (their stamps
    name them), with the host they were rolled out from."""
    found: dict[Path, str] = {}
    for plan in plans.values():
        old = plan.old_stamp.get("run_dir")
        if isinstance(old, str) and old and Path(old) != run_dir:
            found[Path(old)] = str(plan.old_stamp.get("operator") or "")
    return found


def stop_earlier_ground_stations(plans: dict[str, DronePlan], run_dir: Path, say: Say) -> None:
    """Stop the ground station (``eamos start``) of an earlier roll-out still running.

    It would otherwise go on talking to the drones of this one: its drones are
    about to be stopped, and the new nodes must start only on this roll-out's
    Start.  Signalled as ``eamos abort`` does (its drones land, it writes its
    summary), waited for; killed if it does not end.  One on another machine is
    named (its Start cannot start this roll-out's nodes: the deployment differs).
    """
    here = socket.gethostname()
    for old, operator in sorted(earlier_ground_stations(plans, run_dir).items()):
        if operator and operator != here:
            say(
                f"  the roll-out in {old} was made on {operator}: if its `eamos start` still "
                "runs there, stop it (its Start cannot start this roll-out's nodes)"
            )
            continue
        pid = running_ground_station(old)
        if pid is None:
            continue
        say(f"  stopping the ground station of the earlier roll-out {old} (pid {pid})")
        os.kill(pid, signal.SIGTERM)
        if not wait_pid_exit(pid, OLD_GROUND_STOP_S):
            say(f"  it did not end within {OLD_GROUND_STOP_S:g} s: killed (pid {pid})")
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            wait_pid_exit(pid, 10.0)


def _launch_all(plans: dict[str, DronePlan], mission: str, say: Say) -> list[DroneError]:
    """Step 4: install the staged files and start eamos-node on every drone; the failures."""

    def launch_one(target: SshTarget) -> int:
        plan = plans[target.drone]
        if plan.old_node:
            say(f"  {target.drone}: stopping the node of an earlier run (pid {plan.old_node})")
        result = run_remote(target, launch_script(target, mission), LAUNCH_TIMEOUT_S)
        if result.returncode != 0:
            raise remote_error(target, result, "could not start eamos-node")
        pid_lines = sections(result.stdout).get("pid") or [""]
        text = pid_lines[0].strip()
        if not text.isdigit():
            raise DroneError(
                target.drone, target.label, "could not start eamos-node", "no pid recorded"
            )
        return int(text)

    pids, errors = for_each([p.target for p in plans.values()], launch_one)
    for name, pid in pids.items():
        plans[name].pid = pid
        say(f"  {name}: eamos-node started (pid {pid})")
    return errors


def rollout(opts: RolloutOptions, say: Say) -> Rollout:
    """Compile, probe, deploy what changed, launch every node; raise :class:`FleetError`.

    On a probe or copy failure nothing is started anywhere (and nothing changed
    on any drone: copies wait in a staging folder until the launch step).
    """
    steps = Steps(say)
    t_all = time.monotonic()
    fleet = FleetConfig.load(opts.fleet)
    with steps.step("compile"):
        compiled, fleet, drones, targets, run_dir = _compile(opts, fleet)
    mission = compiled.mission.name
    say(
        f"roll-out of {mission} (fleet mission id {compiled.mission_id}) to "
        f"{len(drones)} drone(s); run folder {run_dir}"
    )
    check_security(targets, list(compiled.programs))
    deployment = new_deployment_id()
    plans = _plans(opts, fleet, compiled, targets, run_dir, deployment)
    with steps.step("probe"):
        probed = _probe_each(plans, mission)
        # Each drone's program by content against what the drones run (identity.py).
        base = earlier_programs(probed[0], compiled.mission_id)
        compiled = renumber_plans(compiled, plans, base, run_dir, opts.svg)
        _decide_all(plans, probed, mission, targets.ground.keys, say)
    with steps.step("deploy"):
        _deploy_all(plans, mission, say)
    with steps.step("launch"):
        stop_earlier_ground_stations(plans, run_dir, say)
        errors = _launch_all(plans, mission, say)
    result = Rollout(
        run_dir,
        mission,
        compiled.mission_id,
        plans,
        targets,
        steps.durations,
        opts.speedup,
        deployment,
    )
    steps.durations["rollout"] = round(time.monotonic() - t_all, 3)
    write_rollout(result)
    if errors:
        raise FleetError(
            f"roll-out failed at the launch: stop the drones started with `eamos abort {run_dir}`",
            errors,
        )
    return result


__all__ = ["RolloutOptions", "rollout"]
