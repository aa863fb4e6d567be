"""``eamos status`` and ``eamos logs fetch`` for a rolled-out fleet.

Status asks each drone over SSH whether its ``eamos-node`` runs, which program
it has, and reads the tail of its own logs (the action in progress from
``uniform.log``, the last position from ``adapter.log``); meanwhile it listens
to the drones' telemetry (``tm/<drone>``) for a moment, for live positions.

It never subscribes to messages addressed to the ground station: a drone
still waiting for the ground station would take that subscription for the
ground station's and report ready to nobody.

``eamos logs fetch`` copies every drone's ``logs/<Drone>/`` into the run
folder's ``logs/<Drone>/`` (where ``eamos run`` puts them), so ``eamos report``
and the notebook read a fleet run like a local one.
"""

from __future__ import annotations

import json
import shlex
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..net import wire
from ..program.format import ProgramError, load_program
from .deployment import Deployment
from .localrun import local_node_pids
from .probe import RUNNING_SH
from .ssh import DroneError, copy_from, for_each, run_remote
from .start import short
from .targets import SshTarget

STATUS_TIMEOUT_S = 30.0
FETCH_TIMEOUT_S = 600.0
LOG_TAIL_LINES = 200


@dataclass
class DroneStatus:
    """One row of ``eamos status``."""

    drone: str
    host: str
    up: bool = False
    pid: int | None = None
    program: str = ""  # deployed program checksum (short)
    action: str = ""
    position: tuple[float, float, float] | None = None
    position_source: str = ""  # "live" (telemetry) or "log"
    landed: bool | None = None
    finished: bool = False
    error: str = ""
    notes: list[str] = field(default_factory=list)


def status_script(target: SshTarget, mission: str) -> str:
    """Remote script: pid, stamp, and the tails of the drone's logs."""
    d = shlex.quote(target.mission_dir(mission))
    n = shlex.quote(target.drone)
    return f"""
cd {d} 2>/dev/null || {{ echo "@@nofolder"; exit 0; }}
N={n}
{RUNNING_SH}echo "@@pid"
if [ -f "state/$N.pid" ]; then
  p=$(cat "state/$N.pid")
  if running "$p"; then echo "alive $p"; else echo "dead $p"; fi
fi
echo "@@stamp"
cat "state/$N.deployed.json" 2>/dev/null
echo
echo "@@uniform"
tail -n {LOG_TAIL_LINES} "logs/$N/uniform.log" 2>/dev/null
echo "@@adapter"
grep '"adapter.position"' "logs/$N/adapter.log" 2>/dev/null | tail -n 1
echo "@@report"
cat "logs/$N/report.json" 2>/dev/null
echo
echo "@@end"
"""


def _chunks(text: str) -> dict[str, str]:
    out: dict[str, str] = {}
    parts = text.split("\n@@")
    if parts and parts[0].startswith("@@"):
        parts[0] = parts[0][2:]
    for part in parts:
        part = part.lstrip("@")
        name, _, body = part.partition("\n")
        out[name.strip().split(" ")[0]] = body
    return out


def _json_lines(text: str) -> list[dict[str, Any]]:
    events = []
    for line in text.splitlines():
        try:
            event = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut by tail, or being written
        if isinstance(event, dict):
            events.append(event)
    return events


def current_action(events: list[dict[str, Any]]) -> str:
    """The action in progress (calls without a result yet), else the last one finished."""
    running: dict[str, str] = {}
    last = ""
    for event in events:
        kind = event.get("event")
        token = json.dumps(event.get("token"))
        label = f"{event.get('action', '')}({', '.join(str(a) for a in event.get('args', []))})"
        if kind == "uniform.call":
            running[token] = label
        elif kind == "uniform.result":
            running.pop(token, None)
            last = f"{label} {event.get('status', '')}".strip()
        elif kind == "uniform.abort":
            running.clear()
            last = "aborted: landing"
    if running:
        return " + ".join(running.values())
    return f"idle (last: {last})" if last else "idle"


def parse_status(target: SshTarget, stdout: str, expected_checksum: str) -> DroneStatus:
    """One drone's row from the status script's output."""
    return parse_status_of(target.drone, target.label, stdout, expected_checksum)


def parse_status_of(drone: str, host: str, stdout: str, expected_checksum: str) -> DroneStatus:
    """One drone's row from the status script's output (or its local equivalent)."""
    row = DroneStatus(drone, host)
    chunks = _chunks(stdout)
    if "nofolder" in chunks:
        row.error = "mission not deployed here"
        return row
    for line in chunks.get("pid", "").splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            row.up, row.pid = parts[0] == "alive", int(parts[1])
    try:
        stamp = json.loads(chunks.get("stamp", "").strip() or "{}")
    except json.JSONDecodeError:
        stamp = {}
    checksum = str(stamp.get("checksum", ""))
    row.program = short(checksum) if checksum else "?"
    if expected_checksum and checksum and checksum != expected_checksum:
        row.notes.append(f"expected program {short(expected_checksum)}")
    row.action = current_action(_json_lines(chunks.get("uniform", "")))
    positions = _json_lines(chunks.get("adapter", ""))
    if positions:
        p = positions[-1]
        row.position = (float(p["x_m"]), float(p["y_m"]), float(p["z_m"]))
        row.position_source = "log"
        row.landed = bool(p.get("landed"))
    report = chunks.get("report", "").strip()
    if report:
        row.finished = True
        if not row.up:
            try:
                ok = json.loads(report).get("ok")
            except (json.JSONDecodeError, AttributeError):
                ok = None
            row.action = f"finished ({'ok' if ok else 'not ok'})"
    return row


class TelemetryListener:
    """Listens to the drones' telemetry topics only (never ``to/GCS``: see the module doc)."""

    def __init__(self, dep: Deployment) -> None:
        import zmq

        from ..net.bridges import InBridge

        self.latest: dict[str, wire.TelemetrySample] = {}
        self._cond = threading.Condition()
        self._context: zmq.Context[Any] = zmq.Context()
        topics = [wire.topic_telemetry(d) for d in dep.drones]
        self._inb = InBridge(
            self._context, dep.endpoints, topics, self._on, dep.mission_id, curve=dep.ground_keys()
        )
        self._inb.start()
        self.drones = list(dep.drones)

    def _on(self, msg: wire.Message) -> None:
        if isinstance(msg, wire.TelemetrySample):
            with self._cond:
                self.latest[msg.sender] = msg
                self._cond.notify_all()

    def wait(self, drones: list[str], timeout_s: float) -> dict[str, wire.TelemetrySample]:
        """Wait until each of ``drones`` sent a sample, or ``timeout_s``; return what came."""
        with self._cond:
            self._cond.wait_for(lambda: all(d in self.latest for d in drones), timeout_s)
            return dict(self.latest)

    def close(self) -> None:
        self._inb.close()
        self._context.term()


def fleet_status(dep: Deployment, listen_s: float = 2.0) -> list[DroneStatus]:
    """Every drone's row: SSH facts plus live telemetry heard within ``listen_s``."""
    listener = TelemetryListener(dep)
    try:

        def ask(target: SshTarget) -> DroneStatus:
            result = run_remote(target, status_script(target, dep.mission), STATUS_TIMEOUT_S)
            return parse_status(target, result.stdout, dep.checksums.get(target.drone, ""))

        rows, errors = for_each([dep.targets[d] for d in dep.drones], ask)
        up = [d for d, r in rows.items() if r.up]
        heard = listener.wait(up, listen_s) if up else {}
    finally:
        listener.close()
    out: list[DroneStatus] = []
    failures = {e.drone: e for e in errors}
    for name in dep.drones:
        if name in failures:
            err = failures[name]
            out.append(
                DroneStatus(name, dep.targets[name].label, error=f"{err.kind}: {err.detail}")
            )
            continue
        row = rows[name]
        sample = heard.get(name)
        if sample is not None:
            row.position = (sample.x_m, sample.y_m, sample.z_m)
            row.position_source = "live"
            row.landed = sample.landed
        out.append(row)
    return out


def local_status_text(run_dir: Path, drone: str, pid: int | None) -> str:
    """What the status script prints, for a drone of an ``eamos run`` folder (no SSH)."""
    logs = run_dir / "logs" / drone

    def read(path: Path) -> str:
        try:
            return path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""

    try:
        checksum = load_program(run_dir / "programs" / f"{drone}.program.json").checksum
    except (OSError, ProgramError):
        checksum = ""
    uniform = read(logs / "uniform.log").splitlines()[-LOG_TAIL_LINES:]
    positions = [ln for ln in read(logs / "adapter.log").splitlines() if '"adapter.position"' in ln]
    parts = [
        "@@pid",
        f"alive {pid}" if pid else "",
        "@@stamp",
        json.dumps({"checksum": checksum}),
        "@@uniform",
        *uniform,
        "@@adapter",
        *positions[-1:],
        "@@report",
        read(logs / "report.json"),
        "@@end",
    ]
    return "\n".join(parts) + "\n"


def local_status(dep: Deployment) -> list[DroneStatus]:
    """Every drone's row for an ``eamos run`` folder: its process, program and logs here."""
    assert dep.run_dir is not None
    pids = local_node_pids(dep.run_dir)
    return [
        parse_status_of(name, "local", local_status_text(dep.run_dir, name, pids.get(name)), "")
        for name in dep.drones
    ]


def format_status(dep: Deployment, rows: list[DroneStatus]) -> str:
    """The status table as text."""
    header = ("drone", "host", "up", "program", "current action", "x, y, z (m)")
    lines: list[tuple[str, ...]] = [header]
    for r in rows:
        if r.error:
            lines.append((r.drone, r.host, "?", "", r.error, ""))
            continue
        pos = ""
        if r.position is not None:
            pos = "{:.1f}, {:.1f}, {:.1f}".format(*r.position) + f" ({r.position_source})"
        up = f"up (pid {r.pid})" if r.up else "down"
        action = r.action + (f" [{'; '.join(r.notes)}]" if r.notes else "")
        lines.append((r.drone, r.host, up, r.program, action, pos))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    text = [f"mission {dep.mission} (id {dep.mission_id})"]
    for line in lines:
        text.append("  ".join(cell.ljust(w) for cell, w in zip(line, widths, strict=True)).rstrip())
    return "\n".join(text)


@dataclass
class FetchResult:
    """What ``eamos logs fetch`` collected."""

    run_dir: Path
    fetched: dict[str, float]  # drone -> seconds
    errors: list[DroneError]


def fetch_logs(dep: Deployment, run_dir: Path, say: Callable[[str], None]) -> FetchResult:
    """Copy every drone's ``logs/<Drone>/`` into ``run_dir/logs/<Drone>/`` over SSH."""
    logs = Path(run_dir) / "logs"
    logs.mkdir(parents=True, exist_ok=True)

    def one(target: SshTarget) -> float:
        t0 = time.monotonic()
        copy_from(target, f"{dep.dir_of(target.drone)}/logs/{target.drone}", logs, FETCH_TIMEOUT_S)
        return time.monotonic() - t0

    fetched, errors = for_each([dep.targets[d] for d in dep.drones], one)
    for name in dep.drones:
        if name in fetched:
            files = (
                sorted(p.name for p in (logs / name).iterdir()) if (logs / name).is_dir() else []
            )
            say(f"  {name}: {fetched[name]:.2f} s: {', '.join(files)}")
    return FetchResult(Path(run_dir), fetched, errors)


__all__ = [
    "DroneStatus",
    "FetchResult",
    "current_action",
    "fetch_logs",
    "fleet_status",
    "format_status",
    "parse_status",
    "status_script",
]
