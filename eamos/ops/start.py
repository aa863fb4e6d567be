"""``eamos start`` and ``eamos abort`` for a rolled-out fleet (paper VI-G: mission trigger).

``eamos start RUN_DIR`` is the ground station of ``eamos run`` without local
drone processes: it binds the ground station's endpoint (``[ground] bind``),
waits until every drone's ``eamos-node`` (started by the roll-out) reports
ready with the program the roll-out deployed, sends the start trigger, shows
progress, declares completion, and writes ``summary.json`` -- the same file
``eamos run`` writes.  If a drone never becomes ready (or its node dies) the
start trigger is not sent: the others are told to abort and report.

While it waits, one SSH connection per drone watches the node's process
(``tail --pid`` on the drone), so a node that dies is noticed at once, with
the last line of its ``node.out``, instead of after the ready timeout.

``eamos abort`` makes every drone land now: if ``eamos start`` runs for this
run folder it is signalled (it broadcasts the abort and collects the
reports); otherwise ``eamos abort`` binds the ground station's endpoint
itself -- the drones' sockets reconnect to it on their own -- broadcasts
the abort and waits until every drone reports it has landed.
"""

from __future__ import annotations

import json
import os
import select
import shlex
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..actors.runtime import DroneRuntimeError, NetSettings
from ..ground import (
    Display,
    DroneReport,
    DroneView,
    GroundStation,
    Limits,
    RunSummary,
    fly,
    ground_runtime,
    make_display,
    summarize,
)
from ..ground.local import LATEST, RUNS_ROOT, link_latest
from ..logs import report_write_error
from ..net import wire
from ..program.format import DroneProgram, load_program
from ..program.uniform import GROUND_STATION
from .deployment import Deployment, from_run_dir, resolve
from .localrun import is_local_run, local_deployment, local_ground_pid
from .probe import RUNNING_SH
from .record import ROLLOUT_FILE, paper_table, read_rollout
from .ssh import FleetConnectError, FleetError, classify
from .targets import SshTarget

GROUND_PID_FILE = "ground.pid"
WATCH_MARGIN_S = 600.0
LANDED_Z_M = 0.3
REPORT_GRACE_S = 5.0

Say = Callable[[str], None]


def short(checksum: str) -> str:
    """``sha256:1a2b3c4d5e6f`` -> ``1a2b3c4d5e6f`` (12 hex digits are plenty for people)."""
    return checksum.split(":", 1)[-1][:12]


# -- watching the drones' processes ---------------------------------------------------------


def watch_script(target: SshTarget, mission: str) -> str:
    """Remote script: return when the drone's node exits, then show how it ended."""
    d = shlex.quote(target.mission_dir(mission))
    n = shlex.quote(target.drone)
    return f"""
cd {d} || exit 90
N={n}
{RUNNING_SH}p=$(cat "state/$N.pid" 2>/dev/null)
if [ -n "$p" ] && running "$p"; then
  echo "@@watching $p"
  tail --pid="$p" -f /dev/null
fi
echo "@@exited"
tail -n 3 "logs/$N/node.out" 2>/dev/null
"""


class NodeWatcher:
    """One SSH connection per drone that returns when the drone's ``eamos-node`` exits."""

    def __init__(
        self,
        targets: dict[str, SshTarget],
        mission: str,
        timeout_s: float,
        on_exit: Callable[[str, str], None],
        on_lost: Callable[[str, str], None],
    ) -> None:
        self.targets = targets
        self.mission = mission
        self.timeout_s = timeout_s
        self.on_exit = on_exit
        self.on_lost = on_lost
        self._procs: dict[str, subprocess.Popen[str]] = {}
        self._lock = threading.Lock()
        self._closing = threading.Event()
        self._threads: list[threading.Thread] = []

    def start(self) -> None:
        for name, target in self.targets.items():
            thread = threading.Thread(
                target=self._watch, args=(name, target), name=f"watch-{name}", daemon=True
            )
            self._threads.append(thread)
            thread.start()

    def _watch(self, name: str, target: SshTarget) -> None:
        proc = subprocess.Popen(
            target.ssh_argv(watch_script(target, self.mission)),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
        )
        with self._lock:
            self._procs[name] = proc
        try:
            out, err = proc.communicate(timeout=self.timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            return
        if self._closing.is_set():
            return
        if "@@exited" in out:
            tail = [ln for ln in out.split("@@exited", 1)[1].splitlines() if ln.strip()]
            self.on_exit(name, tail[-1].strip() if tail else "")
        else:
            found = classify(err)
            self.on_lost(
                name, found[1] if found else (err.strip() or f"ssh exit {proc.returncode}")
            )

    def close(self) -> None:
        """Stop watching (ends the SSH connections this object started)."""
        self._closing.set()
        with self._lock:
            procs = list(self._procs.values())
        for proc in procs:
            if proc.poll() is None:
                proc.terminate()
        for proc in procs:
            try:
                proc.wait(5)
            except subprocess.TimeoutExpired:
                proc.kill()
        for thread in self._threads:
            thread.join(5)


# -- eamos start ---------------------------------------------------------------------------------


@dataclass
class StartOptions:
    """What ``eamos start`` was asked to do."""

    run_dir: Path
    timeout_s: float = 600.0
    ready_timeout_s: float | None = None  # default: the fleet file's [ground] ready_timeout_s
    live: bool | None = None


def _flying(run_dir: Path, speak: Say, ready_s: float) -> None:
    """Every drone is ready and the start trigger goes next: the roll-out flies.

    A roll-out's folder in the default ``runs/`` (of the folder ``eamos start`` runs in)
    becomes ``runs/latest``, as ``eamos run``'s does when its drones start: the newest
    run that flew, for the notebook, ``eamos report`` and ``eamos monitor``.
    """
    speak(f"ready {ready_s:.2f} s")
    if run_dir.parent == RUNS_ROOT.resolve() and run_dir.name != LATEST:
        link_latest(run_dir)


def fly_rollout(
    opts: StartOptions,
    stop: threading.Event,
    say: Say | None = None,
    display: Display | None = None,
) -> RunSummary:
    """Be the ground station of a rolled-out mission; return the summary (also written)."""
    run_dir = Path(opts.run_dir).resolve()
    doc = read_rollout(run_dir)
    dep = from_run_dir(run_dir)
    drones = dep.drones
    gcs_program = load_program(run_dir / "programs" / f"{GROUND_STATION}.program.json")
    if gcs_program.mission_id != dep.mission_id:
        raise FleetError(
            f"{run_dir}: programs/{GROUND_STATION}.program.json is not the rolled-out mission "
            f"({gcs_program.mission_id} != {dep.mission_id}); run `eamos rollout` again"
        )
    ready_timeout = opts.ready_timeout_s or float(doc["ground"]["ready_timeout_s"])
    shown = display or make_display(opts.live, drones)
    speak = say or shown.say
    station: GroundStation

    def on_change(name: str, view: DroneView, msg: Any) -> None:
        if isinstance(msg, wire.Ready) and msg.program_checksum != dep.checksums.get(name):
            station.fail(
                name,
                f"runs program {short(msg.program_checksum)}, the roll-out deployed "
                f"{short(dep.checksums.get(name, ''))}: roll out again",
            )
        shown.event(name, view, msg)

    station = GroundStation(drones, dep.mission_id, on_change=on_change, deployment=dep.deployment)
    shown.watch(station)
    speedup = doc.get("speedup")
    runtime = ground_runtime(
        gcs_program,
        station,
        NetSettings(dep.ground_bind, dict(dep.endpoints), keys=dep.ground_keys()),
        run_dir / "logs" / GROUND_STATION,
        {"adapter": "ground", "speedup": speedup} if speedup else None,
    )
    exited: dict[str, str] = {}

    def on_exit(name: str, last_line: str) -> None:
        # Every exit is counted at once (GroundStation.exited): the normal end after
        # Complete, else a failure.
        exited[name] = last_line
        station.exited(
            name,
            f"eamos-node is not running on {dep.targets[name].label}"
            + (f": {last_line}" if last_line else ""),
        )

    def on_lost(name: str, why: str) -> None:
        speak(f"{name}: cannot watch its process any more ({why})")

    watcher = NodeWatcher(
        dep.targets, dep.mission, ready_timeout + opts.timeout_s + WATCH_MARGIN_S, on_exit, on_lost
    )
    pid_file = run_dir / GROUND_PID_FILE
    started = time.time()
    outcome = "not started"
    ready_s = None
    try:
        try:
            runtime.start()
        except DroneRuntimeError as exc:
            raise FleetConnectError(
                f"cannot be the ground station at {dep.ground_bind}: {exc} "
                "([ground] bind must be an address of this machine that the drones reach; "
                "is another `eamos start` running?)"
            ) from exc
        pid_file.write_text(f"{os.getpid()}\n")  # for `eamos abort RUN_DIR`
        station.attach(runtime)
        watcher.start()
        with shown:
            speak(
                f"mission {dep.mission}: waiting for {len(drones)} drone(s) "
                f"(up to {ready_timeout:g} s): {', '.join(drones)}"
            )
            flight = fly(
                station,
                shown,
                stop,
                Limits(ready_timeout, opts.timeout_s),
                alive=lambda: [n for n in drones if n not in exited],
                on_ready=lambda s: _flying(run_dir, speak, s),
                control=run_dir,
            )
        outcome, started, ready_s = flight.outcome, flight.started, flight.ready_s
    finally:
        watcher.close()
        gcs_report = runtime.drone_report() if runtime.executive is not None else None
        runtime.stop()
        pid_file.unlink(missing_ok=True)
    durations = dict(doc.get("durations", {}))
    if ready_s is not None:
        durations["ready"] = round(ready_s, 3)
    views = station.snapshot()
    if outcome.startswith("not ready"):
        for name in drones:
            if not views[name].ready and name not in exited:
                speak(
                    f"{name}: never became ready; its eamos-node gives up by itself after "
                    f"ready_timeout_s ({ready_timeout:g} s)"
                )
    summary = summarize(
        dep.mission,
        dep.mission_id,
        outcome,
        started,
        time.time(),
        run_dir,
        views,
        drones,
        list(station.failures),
        gcs_report,
        hosts={name: dep.targets[name].label for name in drones},
    )
    summary = replace(
        summary,
        rollout={
            "durations": durations,
            "table": {row: value for row, value in paper_table(durations)},
            "drones": {
                n: {"state": e.get("state"), "durations": e.get("durations", {})}
                for n, e in doc["drones"].items()
            },
        },
    )
    summary.write(run_dir / "summary.json")
    doc["durations"] = durations
    try:
        (run_dir / ROLLOUT_FILE).write_text(json.dumps(doc, indent=1) + "\n")
    except OSError as exc:  # a full disk: the run's result is the summary, already out
        report_write_error(run_dir / ROLLOUT_FILE, exc, "the start's durations are not recorded")
    return summary


# -- eamos abort --------------------------------------------------------------------------------


def _is_alive_eamos(pid: int) -> bool:
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        try:
            os.kill(pid, 0)
        except OSError:
            return False
        return True  # no /proc: trust the pid file
    return b"eamos" in cmdline


def running_ground_station(run_dir: Path) -> int | None:
    """The pid of the ``eamos start`` running for ``run_dir`` (None: none runs)."""
    try:
        pid = int((run_dir / GROUND_PID_FILE).read_text().strip())
    except (OSError, ValueError):
        return None
    return pid if pid > 0 and _is_alive_eamos(pid) else None


def wait_pid_exit(pid: int, timeout_s: float) -> bool:
    """Wait (on a pidfd, no polling) until process ``pid`` ends; False on timeout."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    except (AttributeError, OSError):  # pragma: no cover - not Linux >= 5.3: cannot wait
        return False
    try:
        ready, _, _ = select.select([fd], [], [], timeout_s)
        return bool(ready)
    finally:
        os.close(fd)


@dataclass
class AbortResult:
    """How an abort went, per drone."""

    landed: dict[str, bool]
    notes: list[str]

    @property
    def ok(self) -> bool:
        return all(self.landed.values())


def abort(
    source: Path,
    mission: str | None,
    reason: str,
    timeout_s: float,
    say: Say,
) -> AbortResult:
    """Every drone of the deployment lands now.

    ``source`` is a roll-out folder, a fleet file, or an ``eamos run`` folder
    (whose drones are local processes: see :mod:`.localrun`).
    """
    pid = 0
    if source.is_dir() and not (source / ROLLOUT_FILE).exists() and is_local_run(source):
        dep = local_deployment(source)
        pid = local_ground_pid(source) or 0
        which = "eamos run"
    else:
        dep = resolve(source, mission)
        which = "eamos start"
    if dep.run_dir is not None:
        if not pid:
            pid_path = dep.run_dir / GROUND_PID_FILE
            try:
                pid = int(pid_path.read_text().strip())
            except (OSError, ValueError):
                pid = 0
        if pid and _is_alive_eamos(pid):
            say(f"signalling the ground station ({which}, pid {pid}): every drone lands")
            os.kill(pid, signal.SIGTERM)
            done = wait_pid_exit(pid, timeout_s)
            landed = _landed_from_summary(dep.run_dir) if done else {}
            notes = [] if done else [f"the ground station did not end within {timeout_s:g} s"]
            return AbortResult({n: landed.get(n, False) for n in dep.drones}, notes)
    return broadcast_abort(dep, reason, timeout_s, say, dep.ground_keys())


def _landed_from_summary(run_dir: Path) -> dict[str, bool]:
    try:
        summary = RunSummary.read(run_dir / "summary.json")
    except (OSError, ValueError):
        return {}
    return {name: _reported_landed(d.report) is True for name, d in summary.drones.items()}


def _reported_landed(report: DroneReport | None) -> bool | None:
    """Whether a drone's report says it is down; None when it has no final state."""
    if report is None or report.final is None:
        return None
    return abs(report.final.z) < LANDED_Z_M


def abort_program(dep: Deployment) -> DroneProgram:
    """The ground station's program for an abort: no nodes, only the mission's identity.

    Aborting needs no mission logic, so ``eamos abort`` works from a fleet file
    alone (without the run folder that holds the ground station's program).
    """
    return DroneProgram(
        mission=dep.mission,
        mission_id=dep.mission_id,
        drone=GROUND_STATION,
        drone_type="",
        fleet=(GROUND_STATION, *dep.drones),
        nodes=(),
        arcs=(),
    )


def _landed(view: DroneView) -> bool:
    reported = _reported_landed(view.report)
    if reported is not None:
        return reported
    return view.position is not None and abs(view.position[2]) < LANDED_Z_M and not view.armed


def broadcast_abort(
    dep: Deployment, reason: str, timeout_s: float, say: Say, keys: Any = None
) -> AbortResult:
    """Be the ground station just long enough to broadcast Abort and see every drone land.

    The drones' sockets reconnect to the ground station's endpoint on their
    own; an abort is sent once each drone listens (PUB/SUB drops what is sent
    before), and the drones then report (they land, report and exit).
    """
    changed = threading.Condition()

    def on_change(name: str, view: DroneView, msg: Any) -> None:
        with changed:
            changed.notify_all()

    station = GroundStation(dep.drones, dep.mission_id, on_change=on_change)
    log_dir = (dep.run_dir / "logs" / f"{GROUND_STATION}.abort") if dep.run_dir else None
    runtime = ground_runtime(
        abort_program(dep),
        station,
        NetSettings(dep.ground_bind, dict(dep.endpoints), keys=keys),
        log_dir,
    )
    notes: list[str] = []
    try:
        try:
            runtime.start()
        except DroneRuntimeError as exc:
            raise FleetConnectError(
                f"cannot be the ground station at {dep.ground_bind}: {exc} "
                "(is `eamos start` running somewhere else?)"
            ) from exc
        station.attach(runtime)
        say(f"broadcasting abort to {', '.join(dep.drones)} (waiting for them to listen)")
        out = runtime.out
        listening = list(dep.drones)
        if out is not None:
            out.wait_subscribed([wire.topic_to(d) for d in dep.drones], min(15.0, timeout_s))
            listening = [d for d in dep.drones if out.wait_subscribed([wire.topic_to(d)], 0)]
        deaf = [d for d in dep.drones if d not in listening]
        if deaf:
            notes.append(f"not listening (node not running, or unreachable): {', '.join(deaf)}")
        station.abort(reason)

        def settled() -> bool:
            # Down is what matters; the report (sent once landed) may trail it.
            views = station.snapshot()
            return all(views[d].report is not None or _landed(views[d]) for d in listening)

        with changed:
            changed.wait_for(settled, timeout_s)
        station.wait_reports(listening, REPORT_GRACE_S)
        views = station.snapshot()
        landed = {d: _landed(views[d]) for d in dep.drones}
        for d in listening:
            if views[d].report is None:
                notes.append(f"{d}: no report (its node may still run: eamos status)")
        return AbortResult(landed, notes)
    finally:
        runtime.stop()


__all__ = [
    "AbortResult",
    "NodeWatcher",
    "StartOptions",
    "abort",
    "broadcast_abort",
    "fly_rollout",
    "running_ground_station",
    "wait_pid_exit",
]
