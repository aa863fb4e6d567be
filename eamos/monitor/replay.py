"""Replay a finished run on the monitor page: its logs become the events the page saw.

:func:`load_replay` reads a run folder -- ``summary.json``, ``programs/``,
``graphs/`` and each participant's logs -- into a time-ordered list of
:class:`ReplayEvent`:

* ``adapter.position`` (``adapter.log``) -> a telemetry sample;
* each action of the drone's report -> ``running`` at its start, its result at its end;
* ``mission.node.triggered`` / ``mission.node.finished`` (``mission.log``) -> node states
  (a replay knows every node, not only actions); ``mission.condition`` -> the truth value;
* ``mission.resolved`` -> resolved; the ground station's ``mission.peer.*`` -> links.

:meth:`Replay.state_at` folds the events up to a time into a fresh
:class:`~.state.MonitorState`; from the end of the run on, the summary is applied
exactly as a live run applies it, so a replay ends on the same page.
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eamos.ground.summary import RunSummary
from eamos.net import wire
from eamos.net.effects import PeerStatus
from eamos.program.uniform import GROUND_STATION

from .hub import Hub
from .server import MonitorServer
from .setup import MissionSetup, MonitorError, load_setup
from .state import MonitorState


@dataclass(frozen=True)
class ReplayEvent:
    """One thing that happened at wall time ``t`` to participant ``name``."""

    t: float
    name: str
    msg: Any  # a wire message or PeerStatus, or a NodeChange


@dataclass(frozen=True)
class NodeChange:
    """A node's state from a drone's own log (replays only)."""

    node: str
    state: str
    iteration: tuple[int, ...]
    value: bool | None = None  # a condition's truth value


def _read_log(path: Path) -> list[dict[str, Any]]:
    if not path.is_file():
        return []
    out = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            continue  # a line cut short when the process ended
        if isinstance(record, dict) and isinstance(record.get("ts"), int | float):
            out.append(record)
    return out


def _telemetry(mission_id: str, name: str, r: dict[str, Any]) -> wire.TelemetrySample:
    z = float(r.get("z_m", 0.0))
    return wire.TelemetrySample(
        mission=mission_id,
        sender=name,
        time_s=float(r["ts"]),
        x_m=float(r.get("x_m", 0.0)),
        y_m=float(r.get("y_m", 0.0)),
        z_m=z,
        lat_deg=0.0,
        lon_deg=0.0,
        alt_m=z,
        battery_pct=float(r.get("battery_pct", 0.0)),
        armed=bool(r.get("armed", False)),
        landed=bool(r.get("landed", True)),
    )


def _progress(mid: str, name: str, state: str, node: str, action: str, it: tuple[int, ...]) -> Any:
    return wire.Progress(
        mission=mid,
        sender=name,
        state=state,
        node=node,
        action=action,
        detail={"iteration": list(it), "detail": ""},
    )


def _drone_events(mid: str, name: str, logs: Path, summary: RunSummary) -> list[ReplayEvent]:
    out: list[ReplayEvent] = []
    for r in _read_log(logs / "adapter.log"):
        if r.get("event") == "adapter.position":
            out.append(ReplayEvent(r["ts"], name, _telemetry(mid, name, r)))
    result = summary.drones.get(name)
    if name == GROUND_STATION:
        report = summary.ground_station
    else:
        report = result.report if result is not None else None
    for a in report.actions if report is not None else ():
        for t, state in ((a.start, "running"), (a.end, a.result)):
            out.append(
                ReplayEvent(t, name, _progress(mid, name, state, a.node, a.action, a.iteration))
            )
    for r in _read_log(logs / "mission.log"):
        event, ts = r.get("event"), r["ts"]
        it = tuple(int(i) for i in r.get("iteration") or ())
        if event == "mission.node.triggered":
            out.append(ReplayEvent(ts, name, NodeChange(str(r.get("node")), "running", it)))
        elif event == "mission.node.finished":
            state = {"done": "done", "skipped": "skipped"}.get(str(r.get("status")), "failed")
            out.append(ReplayEvent(ts, name, NodeChange(str(r.get("node")), state, it)))
        elif event == "mission.condition":
            value = r.get("value")
            change = NodeChange(str(r.get("node")), "running", it, bool(value))
            out.append(ReplayEvent(ts, name, change))
        elif event == "mission.resolved" and name != GROUND_STATION:
            out.append(ReplayEvent(ts, name, wire.Resolved(mission=mid, sender=name)))
        elif name == GROUND_STATION and str(event).startswith("mission.peer."):
            state = str(event).rsplit(".", 1)[1]
            peer = str(r.get("peer", ""))
            status = PeerStatus(peer, state, float(r.get("silent_s", 0.0)), len(out) + 1)
            out.append(ReplayEvent(ts, peer, status))
    return out


def _homes(run_dir: Path, names: list[str]) -> dict[str, tuple[float, float]]:
    """Each drone's home (m) as its adapter logged it (``adapter.start``'s ``home_m``)."""
    homes = {}
    for name in names:
        for r in _read_log(run_dir / "logs" / name / "adapter.log")[:5]:
            home = r.get("home_m")
            if r.get("event") == "adapter.start" and isinstance(home, list) and len(home) == 2:
                homes[name] = (float(home[0]), float(home[1]))
    return homes


class Replay:
    """A finished run as events in time; the page's state at any time."""

    def __init__(self, setup: MissionSetup, summary: RunSummary, events: list[ReplayEvent]) -> None:
        self.setup = setup
        self.summary = summary
        # Every drone was ready when the start trigger went out.
        ready = [
            ReplayEvent(
                summary.started,
                d,
                wire.Ready(mission=setup.mission_id, sender=d, program_checksum=""),
            )
            for d in setup.drones
        ]
        self.events = sorted([*events, *ready], key=lambda e: e.t)
        self._cached: tuple[int, bool, MonitorState] | None = None
        self._times = [e.t for e in self.events]
        self.start = min([summary.started, *self._times[:1]])
        self.end = max([summary.started + summary.duration_s, *self._times[-1:]])

    def span(self) -> dict[str, float]:
        """The replay's time range (wall-clock seconds) and the start trigger's time."""
        return {"start": self.start, "end": self.end, "started": self.summary.started}

    def state_at(self, t: float) -> dict[str, Any]:
        """The page's whole state at wall time ``t`` (the summary applied from the end on)."""
        return self._model(t).snapshot()

    def model_at(self, t: float) -> MonitorState:
        """The state model after every event up to ``t`` (a fresh one: the caller's to keep)."""
        self._cached = None
        state = self._model(t)
        self._cached = None  # a later seek must not change it
        return state

    def _model(self, t: float) -> MonitorState:
        """The model at ``t``; playing forward continues the last one instead of starting over."""
        upto = bisect.bisect_right(self._times, t)
        cached = self._cached
        if cached is not None and cached[0] <= upto and not cached[1]:
            done, state = cached[0], cached[2]
        else:
            done, state = 0, MonitorState(self.setup, self.start)
        for event in self.events[done:upto]:
            if isinstance(event.msg, NodeChange):
                c = event.msg
                state.node_event(c.node, c.state, list(c.iteration), event.t, c.value)
            else:
                state.apply(event.name, event.msg, event.t)
        state.tick(t + 1.0)
        finished = t >= self.end
        if finished:
            state.finish(self.summary, self.end)
        state.mission["clock"] = t
        self._cached = (upto, finished, state)
        return state


def load_replay(run_dir: Path) -> Replay:
    """The replay of the run in ``run_dir`` (MonitorError when it is not a finished run)."""
    try:
        summary = RunSummary.read(run_dir / "summary.json")
    except FileNotFoundError as exc:
        raise MonitorError(f"{run_dir}: no summary.json (not a finished run folder)") from exc
    except (OSError, ValueError, TypeError, AttributeError) as exc:
        raise MonitorError(f"{run_dir / 'summary.json'}: cannot read it: {exc}") from exc
    names = [*summary.drones, GROUND_STATION]
    setup = load_setup(run_dir, _homes(run_dir, list(summary.drones)))
    events: list[ReplayEvent] = []
    for name in names:
        events += _drone_events(setup.mission_id, name, run_dir / "logs" / name, summary)
    return Replay(setup, summary, events)


def serve_replay(
    run_dir: Path,
    *,
    port: int = 0,
    host: str = "127.0.0.1",
    on_problem: Callable[[str], None] | None = None,
) -> MonitorServer:
    """Serve the replay of ``run_dir``; the server is started (stop it with ``stop()``).

    ``on_problem`` is told of refused requests (another site's page), at a bounded rate.
    """
    replay = load_replay(run_dir)
    hub = Hub(replay.setup)
    hub.state = replay.model_at(replay.end)
    server = MonitorServer(hub, host=host, port=port, replay=replay, on_problem=on_problem)
    return server.start()
