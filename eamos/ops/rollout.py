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
and compares each drone's program without what does not change its behaviour:
source positions and the labels of *other* drones' nodes.  A drone whose own
part is unchanged keeps the program it has (its copy may show old line numbers).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
import shlex
import socket
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import __version__
from ..compiler import CompiledMission, compile_file, write_artifacts
from ..config import ConfigError, FleetConfig
from ..program.format import DroneProgram
from ..program.uniform import GROUND_STATION
from ..run import check_hal_settings, node_config_text
from .ssh import DroneError, FleetError, copy_to, for_each, remote_error, run_remote
from .targets import FleetTargets, SshTarget, load_targets

ROLLOUT_FILE = "rollout.json"
ROLLOUT_FORMAT = "eamos-rollout"
ROLLOUT_VERSION = 1

PROBE_TIMEOUT_S = 60.0
COPY_TIMEOUT_S = 300.0
LAUNCH_TIMEOUT_S = 200.0
STOP_OLD_NODE_S = 150  # an old node lands before it exits (its land timeout is 120 s)

Say = Callable[[str], None]


# -- identity of what is deployed ---------------------------------------------------------


def fleet_mission_id(mission: str, participants: list[str]) -> str:
    """The mission id of a roll-out: stable across edits of the same mission on one fleet.

    Drones drop messages of other missions; with the compiler's id (a hash of
    the text) a drone kept by a partial deployment would not talk to a
    redeployed one.  The roll-out stops every earlier node before it starts new
    ones, so stale nodes cannot mix in.
    """
    text = f"eamos-fleet {__version__}\n{mission}\n{','.join(participants)}"
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def restamp(compiled: CompiledMission, mission_id: str) -> CompiledMission:
    """``compiled`` with every program carrying ``mission_id`` (checksums recomputed)."""
    programs = {
        name: dataclasses.replace(prog, mission_id=mission_id)
        for name, prog in compiled.programs.items()
    }
    return dataclasses.replace(compiled, mission_id=mission_id, programs=programs)


# Node fields that describe rather than decide: a proxy stands for another
# drone's node, so only its identity and structure matter here.
_POSITION_FIELDS = ("line", "col")
_PROXY_DESCRIPTIVE = ("label", "action", "args", "cond", "count", "block")


def execution_digest(program: DroneProgram) -> str:
    """``sha256:`` of what the drone executes: the program minus descriptive fields.

    Equal digests mean the drone behaves the same (partial deployment keeps it).
    Left out: the mission id and file name, source positions, and the labels,
    actions, arguments and conditions of proxy nodes (nodes of other drones,
    which this drone never runs).
    """
    body = program.body()
    body.pop("mission_id", None)
    body.pop("source_file", None)
    nodes = []
    for node in body["nodes"]:
        node = {k: v for k, v in node.items() if k not in _POSITION_FIELDS}
        if not node.get("native"):
            node = {k: v for k, v in node.items() if k not in _PROXY_DESCRIPTIVE}
        nodes.append(node)
    body["nodes"] = nodes
    canonical = json.dumps(body, sort_keys=True, separators=(",", ":")).encode()
    return "sha256:" + hashlib.sha256(canonical).hexdigest()


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _folder_digest(folder: Path) -> str:
    digest = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


# -- progress and durations -----------------------------------------------------------------


@dataclass
class Steps:
    """Prints each step and each drone's part with its duration; keeps the durations."""

    say: Say
    durations: dict[str, float] = field(default_factory=dict)

    @contextmanager
    def step(self, name: str) -> Iterator[None]:
        t0 = time.monotonic()
        try:
            yield
        finally:
            self.durations[name] = round(time.monotonic() - t0, 3)
        self.say(f"{name} {self.durations[name]:.2f} s")


def paper_table(durations: dict[str, float]) -> list[tuple[str, float]]:
    """Paper Table 7's roll-out rows from the step durations.

    Compilation = compile; deployment = the file transfers (deploy); total
    roll-out = every step until the fleet is ready (compile, probe, deploy,
    launch, and ready when ``eamos start`` ran).
    """
    rows = [
        ("mission compilation", durations.get("compile", 0.0)),
        ("mission deployment", durations.get("deploy", 0.0)),
    ]
    total = sum(durations.get(k, 0.0) for k in ("compile", "probe", "deploy", "launch", "ready"))
    rows.append(("total roll-out", round(total, 3)))
    return rows


# -- the probe --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Probe:
    """What a drone told about itself before the roll-out touched anything."""

    version_output: str
    version_rc: int
    free_kb: int | None
    stamp: dict[str, Any] | None
    sums: dict[str, str]  # path relative to the mission folder -> sha256 hex
    pid: int | None
    alive: bool

    @property
    def version(self) -> str | None:
        match = re.search(r"eamos\s+(\S+)", self.version_output)
        return match.group(1) if match else None


def _sections(text: str) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    current = ""
    for line in text.splitlines():
        if line.startswith("@@"):
            current = line[2:].split(" ", 1)[0]
            out[current] = [line[2 + len(current) :].strip()]
        elif current:
            out[current].append(line)
    return {k: [ln for ln in v if ln.strip()] for k, v in out.items()}


# A pid file may outlive its process, and the pid be reused: a process counts as
# the drone's node only if its command line names the drone's config.
RUNNING_SH = r"""running() {
  kill -0 "$1" 2>/dev/null || return 1
  [ -r "/proc/$1/cmdline" ] || return 0
  tr '\0' ' ' < "/proc/$1/cmdline" | grep -q -- "configs/$N.toml"
}
"""


def probe_script(target: SshTarget, mission: str) -> str:
    """The remote shell script of the probe step (POSIX sh)."""
    d = shlex.quote(target.mission_dir(mission))
    drone = shlex.quote(target.drone)
    node = target.node_command
    return f"""
D={d}; N={drone}
{RUNNING_SH}mkdir -p "$D/programs" "$D/configs" "$D/logs" "$D/state" || exit 90
cd "$D" || exit 90
rm -rf ".incoming/$N" && mkdir -p ".incoming/$N" || exit 90
echo "@@version"
{node} --version 2>&1
echo "@@rc $?"
echo "@@df"
df -Pk . 2>&1 | tail -n 1
echo "@@stamp"
cat "state/$N.deployed.json" 2>/dev/null
echo
echo "@@sums"
sha256sum "programs/$N.program.json" "configs/$N.toml" 2>/dev/null
echo "@@pid"
if [ -f "state/$N.pid" ]; then
  p=$(cat "state/$N.pid")
  if running "$p"; then echo "alive $p"; else echo "dead $p"; fi
fi
echo "@@end"
"""


def parse_probe(stdout: str) -> Probe:
    """Read the probe script's output."""
    sec = _sections(stdout)
    rc_line = (sec.get("rc") or ["0"])[0]
    try:
        rc = int(rc_line.split()[0])
    except (ValueError, IndexError):
        rc = -1
    free_kb: int | None = None
    df = sec.get("df") or []
    if df:
        fields = df[-1].split()
        if len(fields) >= 4 and fields[3].isdigit():
            free_kb = int(fields[3])
    stamp: dict[str, Any] | None = None
    stamp_text = "\n".join(sec.get("stamp", [])).strip()
    if stamp_text:
        try:
            loaded = json.loads(stamp_text)
            stamp = loaded if isinstance(loaded, dict) else None
        except json.JSONDecodeError:
            stamp = None  # a damaged stamp means: redeploy
    sums: dict[str, str] = {}
    for line in sec.get("sums", []):
        parts = line.split(None, 1)
        if len(parts) == 2:
            sums[parts[1].strip().lstrip("*")] = parts[0]
    pid: int | None = None
    alive = False
    for line in sec.get("pid", []):
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            pid, alive = int(parts[1]), parts[0] == "alive"
    return Probe(
        version_output="\n".join(sec.get("version", [])).strip(),
        version_rc=rc,
        free_kb=free_kb,
        stamp=stamp,
        sums=sums,
        pid=pid,
        alive=alive,
    )


def probe(target: SshTarget, mission: str) -> Probe:
    """Run the probe on one drone; :class:`DroneError` if unreachable or unusable."""
    result = run_remote(target, probe_script(target, mission), PROBE_TIMEOUT_S)
    if result.returncode == 90:
        raise remote_error(target, result, "cannot use the folder")
    if result.returncode != 0 or "@@end" not in result.stdout:
        raise remote_error(target, result, "probe failed")
    return parse_probe(result.stdout)


def check_version(target: SshTarget, found: Probe) -> None:
    """The drone's eamos must be the operator's: programs and wire format are versioned."""
    wanted = __version__
    fix = f"run `pip install eamos=={wanted}` on the drone"
    if found.version is None:
        output = found.version_output.splitlines()[-1] if found.version_output else "no output"
        raise DroneError(
            target.drone,
            target.label,
            "eamos not found",
            f"`{target.node_command} --version` failed ({output}): {fix}, "
            "or set ssh.node_command in the fleet file",
        )
    if found.version != wanted:
        raise DroneError(
            target.drone,
            target.label,
            "version mismatch",
            f"drone has eamos {found.version}, operator {wanted}: {fix}",
        )


# -- the plan ------------------------------------------------------------------------------


@dataclass
class DronePlan:
    """What the roll-out does on one drone."""

    drone: str
    target: SshTarget
    endpoint: str
    program: DroneProgram
    digest: str
    config_text: str
    staging: Path
    copy_program: bool = True
    copy_config: bool = True
    copy_keys: bool = False
    deployed_checksum: str = ""  # the program the drone will run (kept or new)
    state: str = ""
    pid: int | None = None
    old_node: int | None = None
    old_stamp: dict[str, Any] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)
    durations: dict[str, float] = field(default_factory=dict)

    @property
    def changed(self) -> bool:
        return self.copy_program or self.copy_config or self.copy_keys

    def copied(self) -> str:
        """What is copied, for people: ``program, config``."""
        parts = [("program", self.copy_program), ("config", self.copy_config)]
        parts.append(("keys", self.copy_keys))
        return ", ".join(name for name, copied in parts if copied) or "nothing"

    def describe(self) -> dict[str, Any]:
        return {
            "target": self.target.label,
            "ssh": self.target.describe(),
            "dir": self.target.mission_dir(self.program.mission),
            "endpoint": self.endpoint,
            "program_checksum": self.deployed_checksum,
            "compiled_checksum": self.program.checksum,
            "digest": self.digest,
            "state": self.state,
            "copied": {
                "program": self.copy_program,
                "config": self.copy_config,
                "keys": self.copy_keys,
            },
            "pid": self.pid,
            "durations": self.durations,
        }


def _stamp(plan: DronePlan, keys_sha: str | None) -> str:
    """The stamp of what the drone has after this roll-out (``state/<Drone>.deployed.json``)."""
    doc = dict(plan.old_stamp)  # a kept program keeps its checksum, digest and file hash
    if plan.copy_program:
        doc.update(
            checksum=plan.program.checksum,
            digest=plan.digest,
            program_sha256=_sha256_bytes(plan.program.to_json().encode()),
            deployed_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        )
    doc.update(
        drone=plan.drone,
        mission=plan.program.mission,
        mission_id=plan.program.mission_id,
        fleet=list(plan.program.fleet),
        endpoint=plan.endpoint,
        keys_sha256=keys_sha,
        eamos=__version__,
        operator=socket.gethostname(),
        updated_at=time.strftime("%Y-%m-%dT%H:%M:%S%z"),
    )
    return json.dumps(doc, indent=1) + "\n"


def config_text_for(
    drone: str,
    endpoints: dict[str, str],
    ground_bind: str,
    hal: dict[str, Any],
    ready_timeout_s: float,
    keys: bool,
) -> str:
    """A drone's ``configs/<Drone>.toml`` (paths relative to it, like ``eamos run``'s)."""
    peers = {GROUND_STATION: ground_bind}
    peers.update({n: e for n, e in endpoints.items() if n != drone})
    # Fleet keys (eamos keys) travel in the mission folder, next to configs/; without
    # them the sockets are plain, which eamos-node allows on loopback only.
    return node_config_text(
        drone,
        f"../programs/{drone}.program.json",
        f"../logs/{drone}",
        endpoints[drone],
        peers,
        hal,
        ready_timeout_s,
        keys=f"../keys/{drone}" if keys else None,
        plain=not keys,
    )


def decide(plan: DronePlan, found: Probe, keys_sha: str | None) -> None:
    """Partial deployment: copy only what differs from what the drone has."""
    stamp = found.stamp or {}
    prog_rel = f"programs/{plan.drone}.program.json"
    conf_rel = f"configs/{plan.drone}.toml"
    same_program = (
        stamp.get("digest") == plan.digest
        and stamp.get("mission_id") == plan.program.mission_id
        and stamp.get("eamos") == __version__
        and bool(stamp.get("program_sha256"))
        and found.sums.get(prog_rel) == stamp.get("program_sha256")
    )
    plan.old_stamp = stamp
    plan.copy_program = not same_program
    plan.deployed_checksum = plan.program.checksum if plan.copy_program else stamp["checksum"]
    config_sha = _sha256_bytes(plan.config_text.encode())
    plan.copy_config = found.sums.get(conf_rel) != config_sha
    plan.copy_keys = keys_sha is not None and stamp.get("keys_sha256") != keys_sha
    plan.old_node = found.pid if found.alive else None
    if plan.copy_program:
        plan.state = "changed, redeployed" if stamp else "new, deployed"
    else:
        plan.state = "unchanged, kept"


def stage(plan: DronePlan, keys: Path | None, keys_sha: str | None) -> list[Path]:
    """Write what must be copied to the drone into the local staging folder; return the paths.

    Nothing when the drone has everything already; otherwise the changed files
    and the new stamp.
    """
    if not plan.changed:
        return []
    plan.staging.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    if plan.copy_program:
        files.append(plan.program.save(plan.staging / f"{plan.drone}.program.json"))
    if plan.copy_config:
        path = plan.staging / f"{plan.drone}.toml"
        path.write_text(plan.config_text)
        files.append(path)
    if plan.copy_keys and keys is not None:
        files.append(keys / plan.drone)  # arrives as .incoming/<Drone>/<Drone>/
    stamp = plan.staging / f"{plan.drone}.deployed.json"
    stamp.write_text(_stamp(plan, keys_sha))
    files.append(stamp)
    return files


def _human_kb(kb: int | None) -> str:
    if kb is None:
        return "? kB"
    for unit, size in (("GB", 1 << 20), ("MB", 1 << 10)):
        if kb >= size:
            return f"{kb / size:.1f} {unit}"
    return f"{kb} kB"


def _bytes_kb(paths: list[Path]) -> int:
    total = 0
    for path in paths:
        if path.is_dir():
            total += sum(p.stat().st_size for p in path.rglob("*") if p.is_file())
        else:
            total += path.stat().st_size
    return total // 1024 + 1


def diagnose_copy_failure(
    target: SshTarget, mission: str, files: list[Path], error: DroneError
) -> DroneError:
    """Say "disk full" when a failed copy left the drone's disk full.

    scp over SFTP reports a full disk only as "failed to upload file", so the
    free space is looked at after the failure.
    """
    if error.kind != "copy failed":
        return error
    script = f"df -Pk {shlex.quote(target.mission_dir(mission))} | tail -n 1"
    try:
        result = run_remote(target, script, PROBE_TIMEOUT_S)
    except DroneError:
        return error
    fields = result.stdout.split()
    if len(fields) >= 4 and fields[3].isdigit():
        free_kb, need_kb = int(fields[3]), _bytes_kb(files)
        if free_kb < need_kb:
            return DroneError(
                target.drone,
                target.label,
                "disk full",
                f"{free_kb} kB free in {target.mission_dir(mission)} after the copy failed, the "
                f"files need {need_kb} kB ({error.detail})",
            )
    return error


def launch_script(target: SshTarget, mission: str) -> str:
    """Remote script of the launch step: install staged files, stop an old node, start."""
    d = shlex.quote(target.mission_dir(mission))
    n = shlex.quote(target.drone)
    node = f'{target.node_command} --config "configs/$N.toml"'
    return f"""
D={d}; N={n}
{RUNNING_SH}cd "$D" || exit 90
I=".incoming/$N"
# Install what the deploy step staged (renames within one file system: atomic).
install() {{ if [ -e "$I/$1" ]; then rm -rf "$2" && mv -f "$I/$1" "$2" || exit 91; fi; }}
mkdir -p keys
install "$N.program.json" "programs/$N.program.json"
install "$N.toml" "configs/$N.toml"
install "$N" "keys/$N"
install "$N.deployed.json" "state/$N.deployed.json"
rm -rf "$I"
if [ -f "state/$N.pid" ]; then
  p=$(cat "state/$N.pid")
  if running "$p"; then
    echo "@@stopping $p"
    kill -TERM "$p"
    timeout {STOP_OLD_NODE_S} tail --pid="$p" -f /dev/null 2>/dev/null
    if running "$p"; then kill -KILL "$p"; fi
  fi
fi
rm -rf "logs/$N.prev"
if [ -d "logs/$N" ]; then mv "logs/$N" "logs/$N.prev"; fi
mkdir -p "logs/$N" || exit 91
PYTHONUNBUFFERED=1 nohup {node} > "logs/$N/node.out" 2>&1 < /dev/null &
echo $! > "state/$N.pid"
echo "@@pid $!"
"""


def check_security(targets: FleetTargets, participants: list[str]) -> None:
    """Fleet keys for every participant, or every endpoint on loopback (ConfigError).

    eamos-node refuses plain sockets off loopback, so a fleet on a network
    needs the keys of ``eamos keys``; checked here, before any drone is touched.
    """
    from ..net.keys import FleetKeys, KeysError, is_local_endpoint

    w = f"{targets.path}: " if targets.path is not None else ""
    keys = targets.ground.keys
    if keys is None:
        remote = [
            e
            for e in [targets.ground.bind, *targets.endpoints.values()]
            if not is_local_endpoint(e)
        ]
        if remote:
            raise ConfigError(
                f"{w}ground.keys: required: the drones talk over the network ({remote[0]}), "
                "and plain sockets are allowed on loopback only; make the fleet's keys with "
                f"`eamos keys KEYS --fleet {' '.join(participants)}` and set "
                '[ground] keys = "KEYS"'
            )
        return
    for name in participants:
        try:
            found = FleetKeys.load(keys if name == GROUND_STATION else keys / name, name)
        except KeysError as exc:
            raise ConfigError(f"{w}ground.keys: {exc}") from exc
        missing = found.missing(p for p in participants if p != name)
        if missing:
            raise ConfigError(
                f"{w}ground.keys: {keys} has no public key for {', '.join(missing)} "
                f"(make them again with `eamos keys {keys} --fleet {' '.join(participants)}`)"
            )


# -- the roll-out -------------------------------------------------------------------------------


@dataclass
class RolloutOptions:
    """What ``eamos rollout`` was asked to do."""

    mission: Path
    fleet: Path
    run_dir: Path | None = None
    speedup: float | None = None
    svg: bool = False


@dataclass
class Rollout:
    """The result of a roll-out (also ``rollout.json`` in the run folder)."""

    run_dir: Path
    mission: str
    mission_id: str
    plans: dict[str, DronePlan]
    targets: FleetTargets
    durations: dict[str, float]
    speedup: float | None

    def to_json(self) -> dict[str, Any]:
        return {
            "format": ROLLOUT_FORMAT,
            "version": ROLLOUT_VERSION,
            "eamos": __version__,
            "mission": self.mission,
            "mission_id": self.mission_id,
            "run_dir": str(self.run_dir),
            "fleet_file": None if self.targets.path is None else str(self.targets.path),
            "speedup": self.speedup,
            "ground": {
                "bind": self.targets.ground.bind,
                "ready_timeout_s": self.targets.ground.ready_timeout_s,
                "keys": None if self.targets.ground.keys is None else str(self.targets.ground.keys),
            },
            "drones": {name: plan.describe() for name, plan in self.plans.items()},
            "durations": self.durations,
            "created": time.time(),
        }


def _default_run_dir(mission: str) -> Path:
    return Path("runs") / f"{mission}-{time.strftime('%Y%m%d-%H%M%S')}"


def rollout(opts: RolloutOptions, say: Say) -> Rollout:
    """Compile, probe, deploy what changed, launch every node; raise :class:`FleetError`.

    On a probe or copy failure nothing is started anywhere (and nothing changed
    on any drone: copies wait in a staging folder until the launch step).
    """
    steps = Steps(say)
    t_all = time.monotonic()
    fleet = FleetConfig.load(opts.fleet)
    with steps.step("compile"):
        compiled = compile_file(opts.mission)
        drones = [n for n in compiled.programs if n != GROUND_STATION]
        # Fleet settings are validated before anything is written or contacted.
        targets = load_targets(fleet, drones)
        compiled = restamp(
            compiled, fleet_mission_id(compiled.mission.name, list(compiled.programs))
        )
        run_dir = (opts.run_dir or _default_run_dir(compiled.mission.name)).resolve()
        run_dir.mkdir(parents=True, exist_ok=True)
        write_artifacts(compiled, run_dir, svg=opts.svg)
    mission = compiled.mission.name
    say(
        f"roll-out of {mission} (fleet mission id {compiled.mission_id}) to "
        f"{len(drones)} drone(s); run folder {run_dir}"
    )
    keys = targets.ground.keys
    check_security(targets, list(compiled.programs))
    plans: dict[str, DronePlan] = {}
    for name in drones:
        hal = dict(targets.hal[name])
        if opts.speedup is not None and hal.get("adapter", "sim") == "sim":
            hal["speedup"] = opts.speedup
        check_hal_settings(name, hal, fleet.path)
        program = compiled.programs[name]
        text = config_text_for(
            name,
            targets.endpoints,
            targets.ground.bind,
            hal,
            targets.ground.ready_timeout_s,
            keys is not None,
        )
        plans[name] = DronePlan(
            drone=name,
            target=targets.drones[name],
            endpoint=targets.endpoints[name],
            program=program,
            digest=execution_digest(program),
            config_text=text,
            staging=run_dir / "deploy" / name,
        )
        # The operator's copy of every drone's config, as eamos run keeps it.
        (run_dir / "configs").mkdir(exist_ok=True)
        (run_dir / "configs" / f"{name}.toml").write_text(text)

    def keys_sha(name: str) -> str | None:
        return None if keys is None else _folder_digest(keys / name)

    with steps.step("probe"):
        probes, errors = for_each([p.target for p in plans.values()], lambda t: probe(t, mission))
        for name in drones:
            if name not in probes:
                continue
            plan, found = plans[name], probes[name]
            try:
                check_version(plan.target, found)
                decide(plan, found, keys_sha(name))
                plan.files = stage(plan, keys, keys_sha(name))
                need = plan.target.min_free_kb + _bytes_kb(plan.files)
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
                f"{_human_kb(found.free_kb)} free, {plan.state}"
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

    with steps.step("deploy"):
        copied, errors = for_each([p.target for p in plans.values()], deploy_one)
        for name in drones:
            plan = plans[name]
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

    def launch_one(target: SshTarget) -> int:
        plan = plans[target.drone]
        if plan.old_node:
            say(f"  {target.drone}: stopping the node of an earlier run (pid {plan.old_node})")
        result = run_remote(target, launch_script(target, mission), LAUNCH_TIMEOUT_S)
        if result.returncode != 0:
            raise remote_error(target, result, "could not start eamos-node")
        pid_lines = _sections(result.stdout).get("pid") or [""]
        text = pid_lines[0].strip()
        if not text.isdigit():
            raise DroneError(
                target.drone, target.label, "could not start eamos-node", "no pid recorded"
            )
        return int(text)

    with steps.step("launch"):
        pids, errors = for_each([p.target for p in plans.values()], launch_one)
        for name, pid in pids.items():
            plans[name].pid = pid
            say(f"  {name}: eamos-node started (pid {pid})")
    result = Rollout(
        run_dir, mission, compiled.mission_id, plans, targets, steps.durations, opts.speedup
    )
    steps.durations["rollout"] = round(time.monotonic() - t_all, 3)
    write_rollout(result)
    if errors:
        raise FleetError(
            f"roll-out failed at the launch: stop the drones started with `eamos abort {run_dir}`",
            errors,
        )
    return result


def write_rollout(result: Rollout) -> Path:
    """Write ``rollout.json`` into the run folder."""
    path = result.run_dir / ROLLOUT_FILE
    path.write_text(json.dumps(result.to_json(), indent=1) + "\n")
    return path


def read_rollout(run_dir: Path) -> dict[str, Any]:
    """Read a run folder's ``rollout.json``; :class:`FleetError` if missing or not one."""
    path = Path(run_dir) / ROLLOUT_FILE
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError as exc:
        raise FleetError(
            f"{run_dir}: not a roll-out folder (no {ROLLOUT_FILE}); run `eamos rollout` first"
        ) from exc
    except (OSError, json.JSONDecodeError) as exc:
        raise FleetError(f"{path}: cannot read it: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != ROLLOUT_FORMAT:
        raise FleetError(f"{path}: not an EAMOS roll-out record")
    return doc


def targets_of(doc: dict[str, Any]) -> dict[str, SshTarget]:
    """The drones' SSH targets recorded in ``rollout.json``."""
    return {
        name: SshTarget.from_description(name, entry["ssh"])
        for name, entry in doc["drones"].items()
    }


__all__ = [
    "ROLLOUT_FILE",
    "DronePlan",
    "Probe",
    "Rollout",
    "RolloutOptions",
    "check_version",
    "execution_digest",
    "fleet_mission_id",
    "paper_table",
    "parse_probe",
    "read_rollout",
    "restamp",
    "rollout",
    "targets_of",
]
