"""The monitor page's state, built from what the ground station receives (pure: time injected).

:class:`MonitorState` takes the ground station's events (``apply(name, msg,
now)``: ``wire.Ready``, ``Progress``, ``TelemetrySample``, ``Resolved``,
``Report`` and :class:`~eamos.net.link.PeerStatus`) and the run's end
(:meth:`MonitorState.finish` with the summary).  Each call returns *patches*:
small JSON objects the page applies in order; :meth:`MonitorState.snapshot`
is the whole state at once (a page that connects late, or fell behind).

Patch kinds (``k``):

* ``drone``: one drone's panel and map marker (position, heading, battery,
  armed, mode, link, current action, last line) plus the trail points added
  since its previous ``drone`` patch.  Coalesced: at most one per drone every
  :data:`MIN_INTERVAL_S` (10 per second); a change in between is held and
  sent by :meth:`MonitorState.tick` -- nothing is lost, trail points included.
* ``node``: a node changed state (``waiting``, ``running``, ``done``,
  ``skipped``, ``failed``, ``cancelled``) or activation (loop counters).
  Never coalesced: every state change, in order.
* ``bar``: a timeline bar opened or closed (one per action run).
* ``link``: one link's (drone A -> drone B) external arcs in the MDG and the
  triggers sent and received on it so far, derived live from node states
  (:mod:`.links`); sent whenever a count changes.
* ``mission``: the mission's state (``waiting for drones``, ``running``, ``paused``
  (the operator's pause, until a resume), ``aborting``, then the outcome word:
  ``finished``, ``failed``, ``aborted``, ``timed out``), its start and end times.

A MAVLink drone's autopilot says its own flight mode and STATUSTEXTs (``Progress``
``autopilot``): ``autopilot`` and ``statustext`` (the latest :data:`STATUSTEXTS`
``[severity, text]``, MAVLink severities: 0 emergency ... 7 debug).

A MAVLink drone a pilot took over (``Progress`` ``taken_over``, or its report's
``vehicle.taken_over`` at the end) shows the mode ``taken over (LOITER)`` from then
on, whatever its telemetry says, and ``taken_over`` holds the words.

The ground station hears about action and Wait nodes (``Progress``); a node
that ran implies that a predecessor it has alone finished ``done`` (forks,
the If before a branch); the final state of every node comes from the
drones' reports at the end (:func:`final_node_states`), the same rule for a
live run and a replay.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from eamos.ground.display import format_event
from eamos.ground.links import LinkCount, LinkCounts
from eamos.ground.summary import DroneReport, RunSummary
from eamos.hal.api import TAKEN_OVER_PREFIX, TakenOver
from eamos.net import wire
from eamos.net.effects import PeerStatus
from eamos.program.uniform import GROUND_STATION

from .setup import MissionSetup

#: The autopilot messages (STATUSTEXT) a drone's panel keeps, latest last.
STATUSTEXTS = 5
#: Minimum time between two ``drone`` patches of one drone (10 updates per second).
MIN_INTERVAL_S = 0.1
_EPS = 1e-9  # 10.1 - 10.0 < 0.1 in floating point
#: A new trail point when the drone moved this far (m) ...
TRAIL_STEP_M = 0.02
#: ... or this long after the previous point (s), so the altitude strip has its hovers.
TRAIL_EVERY_S = 0.5
#: Trail points kept per drone; past it every other old point is dropped (the shape stays).
TRAIL_MAX = 4000

FINAL_NODE_STATES = frozenset({"done", "skipped", "failed", "cancelled"})
#: An action's result (ActionEntry.result) -> the node's state.
ACTION_TO_NODE = {
    "running": "running",
    "ok": "done",
    "failed": "failed",
    "caught": "failed",  # it failed, inside a Try whose OnFailure handles it
    "cancelled": "cancelled",
}
#: Progress.state (an action's, or a Wait's) -> the node's state.
PROGRESS_TO_NODE = {
    **ACTION_TO_NODE,
    "waiting": "running",  # a Wait/Pause holding until its condition changes
    "decided": "done",  # an If took a branch (detail: which, and the condition)
    "skipped": "skipped",
    "blocked": "failed",  # a dependency failed: the node is blocked
}
#: Progress states of a node that was triggered and ran (its predecessors finished).
RAN = frozenset({"running", "waiting", "decided", "ok", "failed", "caught", "cancelled"})


def final_node_states(setup: MissionSetup, name: str, report: DroneReport | None) -> dict[str, str]:
    """Every native node of ``name``'s final state as its report tells it ({} without one).

    Actions: the result of their last run (``ok`` -> ``done``); a node the
    drone lists as blocked: ``failed``; an action that never ran: ``skipped``
    if the drone resolved, else ``cancelled``; any other node: ``done`` if
    the drone resolved, else ``cancelled``.
    """
    part = setup.participant(name)
    if part is None or report is None:
        return {}
    last: dict[str, str] = {}
    for entry in sorted(report.actions, key=lambda a: (a.iteration, a.start)):
        last[entry.node] = ACTION_TO_NODE.get(entry.result, "failed")
    blocked = set(report.blocked_nodes)
    out = {}
    for node in part.nodes:
        if node.key in blocked:
            out[node.key] = "failed"
        elif node.key in last:
            out[node.key] = last[node.key]
        elif node.kind == "action":
            out[node.key] = "skipped" if report.resolved else "cancelled"
        else:
            out[node.key] = "done" if report.resolved else "cancelled"
    return out


@dataclass
class DroneLive:
    """One drone's live panel."""

    name: str
    x: float | None = None
    y: float | None = None
    z: float | None = None
    heading_deg: float | None = None
    battery: float | None = None
    armed: bool | None = None
    landed: bool | None = None
    mode: str = "starting"
    link: str = "up"
    action: str = ""
    node: str = ""
    line: str = ""
    ready: bool = False
    resolved: bool = False
    triggers_sent: int | None = None
    triggers_received: int | None = None
    taken_over: str = ""  # "taken over by the pilot in LOITER at (...)" once a pilot has it
    operator: str = ""  # the operator's last command's state ("held", "released ..."; "": none)
    failure: str = ""  # why its latest failed or blocked node failed
    lat: float | None = None  # where the fleet has a geographic home (0, 0 is none)
    autopilot: str = ""  # the autopilot's own flight mode (GUIDED, OFFBOARD ...; MAVLink)
    statustext: list[list[Any]] = field(default_factory=list)  # its latest [severity, text]
    lon: float | None = None
    trail: list[list[float]] = field(default_factory=list)  # [t, x, y, z]
    sent_trail: int = 0  # trail points already in a drone patch

    def fields(self) -> dict[str, Any]:
        return {
            "drone": self.name,
            "x": self.x,
            "y": self.y,
            "z": self.z,
            "heading": self.heading_deg,
            "battery": self.battery,
            "armed": self.armed,
            "landed": self.landed,
            "mode": self.mode,
            "link": self.link,
            "action": self.action,
            "node": self.node,
            "line": self.line,
            "ready": self.ready,
            "resolved": self.resolved,
            "triggers_sent": self.triggers_sent,
            "triggers_received": self.triggers_received,
            "taken_over": self.taken_over,
            "operator": self.operator,
            "failure": self.failure,
            "autopilot": self.autopilot,
            "statustext": self.statustext,
            "lat": self.lat,
            "lon": self.lon,
        }

    def sample(self, msg: wire.TelemetrySample, home: tuple[float, float], now: float) -> None:
        """Its telemetry, in the fleet frame (``home``): position, heading, state, trail."""
        hx, hy = home
        x, y, z = hx + msg.x_m, hy + msg.y_m, msg.z_m
        if self.x is not None and self.y is not None:
            dx, dy = x - self.x, y - self.y
            if math.hypot(dx, dy) >= TRAIL_STEP_M:
                self.heading_deg = round(math.degrees(math.atan2(dy, dx)), 1)
        self.x, self.y, self.z = x, y, z
        self.battery, self.armed, self.landed = msg.battery_pct, msg.armed, msg.landed
        if msg.lat_deg or msg.lon_deg:
            self.lat, self.lon = round(msg.lat_deg, 7), round(msg.lon_deg, 7)
        if self.mode not in ("resolved", "reported") and not self.taken_over:
            self.mode = "disarmed" if not msg.armed else ("landed" if msg.landed else "flying")
        last = self.trail[-1] if self.trail else None
        if (
            last is None
            or math.dist(last[1:], (x, y, z)) >= TRAIL_STEP_M
            or now - last[0] >= TRAIL_EVERY_S
        ):
            self.trail.append([round(now, 3), round(x, 3), round(y, 3), round(z, 3)])
            if len(self.trail) > TRAIL_MAX:
                # Halve the old part; keep what the page has not received yet.
                keep = len(self.trail) - self.sent_trail
                old = self.trail[: self.sent_trail][::2]
                self.trail = old + self.trail[-keep:] if keep else old
                self.sent_trail = len(old)

    def take(self, mode: str, words: str) -> None:
        """A pilot has the vehicle (in ``mode``): its panel says so from now on."""
        self.mode = f"taken over ({mode})" if mode else "taken over"
        self.taken_over = words


class MonitorState:
    """The page's state; ``apply``/``tick``/``finish`` return the patches to send, in order."""

    def __init__(self, setup: MissionSetup, now: float) -> None:
        self.setup = setup
        self.created = now
        self.drones = {name: DroneLive(name) for name in setup.drones}
        self.nodes: dict[str, dict[str, Any]] = {}  # key -> {state, iteration, count, t, owner}
        for part in setup.participants:
            for node in part.nodes:
                self.nodes[node.key] = {"state": "waiting", "iteration": [], "count": 0}
                self.nodes[node.key]["owner"] = part.name
        self._loops = {n.key: n.loops for p in setup.participants for n in p.nodes}
        self._kinds = {n.key: n.kind for p in setup.participants for n in p.nodes}
        self.bars: list[dict[str, Any]] = []
        self._open_bars: dict[tuple[str, str], int] = {}  # (drone, node) -> index in bars
        self.mission: dict[str, Any] = {
            "state": "waiting for drones",
            "started": None,
            "ended": None,
            "detail": "",
            "created": now,
        }
        self.links = LinkCounts(setup.links) if setup.links is not None else None
        self._last_emit: dict[str, float] = {}
        self._dirty: set[str] = set()
        self.coalesced = 0  # drone updates merged into a later patch
        self.forecast_view: dict[str, Any] | None = None  # the look-ahead's latest cycle

    # -- events ---------------------------------------------------------------------------

    def apply(self, name: str, msg: Any, now: float) -> list[dict[str, Any]]:
        """The patches for ``msg`` from participant ``name`` arriving at wall time ``now``."""
        out: list[dict[str, Any]] = []
        drone = self.drones.get(name)
        if isinstance(msg, wire.TelemetrySample):
            # Most events are telemetry (20 Hz per drone), and a sample has no line.
            if drone is not None:
                part = self.setup.participant(drone.name)
                drone.sample(msg, part.home if part is not None else (0.0, 0.0), now)
                return self._drone_patch(drone, now)
            return out
        line = format_event(name, msg, now)
        if drone is not None and line is not None:
            drone.line = line
        if isinstance(msg, wire.Progress):
            out += self._progress(name, msg, now)
        elif isinstance(msg, wire.Ready):
            if drone is not None:
                drone.ready, drone.mode = True, "ready"
                if all(d.ready for d in self.drones.values()):
                    out += self._mission(state="running", started=now)
                    if self.links is not None:
                        out += _link_patches(self.links.started())
                    # The start trigger follows at once: it is the initial node firing.
                    for part in self.setup.participants:
                        for node in part.nodes:
                            if node.kind == "init":
                                out += self._node(node.key, "done", [], now)
        elif isinstance(msg, wire.Resolved):
            if drone is not None:
                drone.resolved = True
            if self.links is not None:
                out += _link_patches(self.links.resolved(name))
        elif isinstance(msg, wire.Report):
            out += self._report(name, msg.report)
        elif isinstance(msg, PeerStatus) and drone is not None:
            drone.link = msg.state
        if drone is not None:
            out += self._drone_patch(drone, now)
        return out

    def _progress(self, name: str, msg: wire.Progress, now: float) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        drone = self.drones.get(name)
        detail = msg.detail if isinstance(msg.detail, dict) else {}
        if msg.state in ("taken_over", "warning"):  # about the vehicle, not a node
            if drone is not None and msg.state == "taken_over":
                words = str(detail.get("detail") or msg.action)
                drone.take(_taken_mode(words), words)
            return out
        if msg.state == "autopilot":  # the autopilot's own voice, not a node
            if drone is not None:
                drone.autopilot = str(detail.get("mode", ""))
                texts = detail.get("statustext")
                new = (
                    [list(t)[:2] for t in texts if isinstance(t, list)]
                    if isinstance(texts, list)
                    else []
                )
                drone.statustext = (drone.statustext + new)[-STATUSTEXTS:]
            return out
        command = detail.get("command")
        if msg.action.startswith("operator: ") and isinstance(command, str):
            return self._operator(name, drone, command, msg.state)
        if drone is not None:
            drone.action, drone.node = msg.action, msg.node
            if msg.state in ("failed", "blocked"):
                drone.failure = f"{msg.action or msg.node}: {detail.get('detail') or msg.state}"
        iteration = detail.get("iteration") or []
        state = PROGRESS_TO_NODE.get(msg.state)
        if state is None:
            return out
        out += self._node(msg.node, state, list(iteration), now)
        if self.links is not None:
            out += _link_patches(self.links.progress(msg.node, msg.state, tuple(iteration)))
        if msg.state in RAN:
            out += self._ran_before(msg.node, list(iteration), now)
        if self._kinds.get(msg.node) != "action" or msg.state not in ACTION_TO_NODE:
            return out  # the timeline has actions only
        key = (name, msg.node)
        if state == "running":
            if key not in self._open_bars:
                self.bars.append(
                    {"drone": name, "node": msg.node, "label": msg.action, "start": now,
                     "end": None, "result": "running", "iteration": list(iteration)}
                )  # fmt: skip
                self._open_bars[key] = len(self.bars) - 1
                out.append({"k": "bar", "i": len(self.bars) - 1, **self.bars[-1]})
        else:
            index = self._open_bars.pop(key, None)
            if index is None:  # its "running" was not seen (the drone sends the latest only)
                self.bars.append(
                    {"drone": name, "node": msg.node, "label": msg.action, "start": now,
                     "end": now, "result": msg.state, "iteration": list(iteration)}
                )  # fmt: skip
                index = len(self.bars) - 1
            else:
                self.bars[index].update(end=now, result=msg.state)
            out.append({"k": "bar", "i": index, **self.bars[index]})
        return out

    def _operator(
        self, name: str, drone: DroneLive | None, command: str, state: str
    ) -> list[dict[str, Any]]:
        """An operator's command obeyed by ``name``: its panel (or the mission) says so."""
        if drone is not None:
            drone.operator = "" if command == "resume" else state
            return []
        if name == GROUND_STATION and command in ("pause", "resume"):
            paused = command == "pause"
            if self.mission["state"] in ("running", "paused"):
                return self._mission(state="paused" if paused else "running")
        return []

    def _node(self, key: str, state: str, iteration: list[int], now: float) -> list[dict[str, Any]]:
        node = self.nodes.get(key)
        if node is None:
            return []
        if node["state"] == state and node["iteration"] == iteration:
            return []
        if iteration != node["iteration"] or node["count"] == 0:
            node["count"] += 1  # a new activation (a loop's next iteration)
        node.update(state=state, iteration=iteration, t=now)
        return [{"k": "node", "node": key, **node}]

    def _ran_before(self, key: str, iteration: list[int], now: float) -> list[dict[str, Any]]:
        """``key`` ran, so a node it depends on alone finished ``done``: up such chains.

        A node runs when a predecessor ran (dead-path elimination): with one
        predecessor, that one is done (forks, the If before its branch, an
        action whose "ok" the drone's latest-only progress did not send).  A node
        with several predecessors (a join) ends the walk: which one ran is unknown.
        """
        out: list[dict[str, Any]] = []
        preds = self.setup.preds.get(key, ())
        while len(preds) == 1:
            pred = preds[0]
            node = self.nodes.get(pred)
            if node is None or node["state"] in FINAL_NODE_STATES:
                break
            out += self._node(pred, "done", iteration[: self._loops.get(pred, 0)], now)
            preds = self.setup.preds.get(pred, ())
        return out

    def node_event(
        self, key: str, state: str, iteration: list[int], now: float, value: bool | None = None
    ) -> list[dict[str, Any]]:
        """A node's state from a drone's own log (a replay); ``value``: a condition's truth."""
        out = self._node(key, state, iteration, now)
        if self.links is not None:
            # A log's node states: "running" when triggered, else it resolved.
            event = "running" if state == "running" else "ok"
            out += _link_patches(self.links.progress(key, event, tuple(iteration)))
        node = self.nodes.get(key)
        if value is not None and node is not None and node.get("value") != value:
            node["value"] = value
            out = [p for p in out if p.get("node") != key] + [{"k": "node", "node": key, **node}]
        return out

    def _report(self, name: str, data: Mapping[str, Any]) -> list[dict[str, Any]]:
        try:
            report = DroneReport.from_json(data)
        except ValueError:
            return []
        return self._apply_report(name, report)

    def _apply_report(self, name: str, report: DroneReport) -> list[dict[str, Any]]:
        out: list[dict[str, Any]] = []
        drone = self.drones.get(name)
        if drone is not None:
            drone.triggers_sent = report.triggers_sent
            drone.triggers_received = report.triggers_received
            drone.mode = "reported"
            taken = TakenOver.from_json(report.vehicle.get("taken_over"))
            if taken is not None:
                drone.take(taken.mode, taken.describe())
            if report.final is not None:
                part = self.setup.participant(name)
                hx, hy = part.home if part is not None else (0.0, 0.0)
                drone.x, drone.y, drone.z = hx + report.final.x, hy + report.final.y, report.final.z
                drone.armed, drone.battery = report.final.armed, report.final.battery
        blocked = set(report.blocked_nodes)
        for key, state in final_node_states(self.setup, name, report).items():
            node = self.nodes[key]
            if (
                self._kinds.get(key) != "action"
                and key not in blocked
                and node["state"] in FINAL_NODE_STATES
            ):
                continue  # what it showed (a skipped Wait) is more than the report says
            if node["state"] != state:
                node.update(state=state, t=node.get("t"))
                out.append({"k": "node", "node": key, **node})
        out += self._report_bars(name, report)
        return out

    def _report_bars(self, name: str, report: DroneReport) -> list[dict[str, Any]]:
        """The drone's bars become its report's actions (the exact times), in place."""
        out = []
        mine = [i for i, b in enumerate(self.bars) if b["drone"] == name]
        for j, entry in enumerate(sorted(report.actions, key=lambda a: (a.start, a.node))):
            bar = {"drone": name, "node": entry.node, "label": entry.action,
                   "start": entry.start, "end": entry.end, "result": entry.result,
                   "iteration": list(entry.iteration)}  # fmt: skip
            if j < len(mine):
                index = mine[j]
                self.bars[index] = bar
            else:
                self.bars.append(bar)
                index = len(self.bars) - 1
            out.append({"k": "bar", "i": index, **bar})
        for index in mine[len(report.actions) :]:
            self.bars[index] = {**self.bars[index], "result": "dropped", "end": None}
            out.append({"k": "bar", "i": index, **self.bars[index]})
        self._open_bars = {k: v for k, v in self._open_bars.items() if k[0] != name}
        return out

    def _mission(self, **changes: Any) -> list[dict[str, Any]]:
        self.mission.update(changes)
        return [{"k": "mission", **self.mission}]

    def abort_requested(self, origin: str) -> list[dict[str, Any]]:
        """Someone asked for an abort (the page shows ``aborting`` until the end)."""
        if self.mission["ended"] is not None:
            return []
        return self._mission(state="aborting", detail=f"abort requested by {origin}")

    def finish(self, summary: RunSummary, now: float) -> list[dict[str, Any]]:
        """The run ended: every report applied, the outcome word; the last patches."""
        out: list[dict[str, Any]] = []
        for name, result in summary.drones.items():
            if result.report is not None:
                out += self._apply_report(name, result.report)
            elif name in self.drones:
                self.drones[name].mode = "no report"
        if summary.ground_station is not None:
            out += self._apply_report(GROUND_STATION, summary.ground_station)
        for name, link in summary.links.items():
            if name in self.drones:
                self.drones[name].link = link
        for drone in self.drones.values():
            out += self._drone_patch(drone, now, force=True)
        out += self._mission(
            state=summary.word,
            detail=summary.detail,
            started=summary.started,
            ended=summary.started + summary.duration_s,
        )
        return out

    # -- coalescing -----------------------------------------------------------------------

    def _drone_patch(self, drone: DroneLive, now: float, force: bool = False) -> list[dict]:
        last = self._last_emit.get(drone.name)
        if not force and last is not None and now - last < MIN_INTERVAL_S - _EPS:
            if drone.name in self._dirty:
                self.coalesced += 1
            self._dirty.add(drone.name)
            return []
        self._dirty.discard(drone.name)
        self._last_emit[drone.name] = now
        new = drone.trail[drone.sent_trail :]
        drone.sent_trail = len(drone.trail)
        return [{"k": "drone", **drone.fields(), "trail_add": new}]

    def amended(self, setup: MissionSetup, drones: list[str]) -> list[dict[str, Any]]:
        """An amendment was applied to ``drones``: ``setup`` is the mission as it flies now
        (their new nodes are shown from now on; the page draws their graphs again)."""
        self.setup = setup
        for part in setup.participants:
            for node in part.nodes:
                self.nodes.setdefault(node.key, {"state": "waiting", "iteration": [], "count": 0})
                self.nodes[node.key]["owner"] = part.name
                self._loops[node.key], self._kinds[node.key] = node.loops, node.kind
        return [{"k": "amended", "drones": list(drones)}]

    def forecast(self, record: Mapping[str, Any]) -> list[dict[str, Any]]:
        """The live look-ahead's latest cycle: predictions, expected end, tracks ahead."""
        keep = ("predictions", "end_in_s", "ahead", "cycle", "t")
        self.forecast_view = {k: record.get(k) for k in keep}
        return [{"k": "forecast", **self.forecast_view}]

    def tick(self, now: float) -> list[dict[str, Any]]:
        """The held ``drone`` patches whose time has come (call about every 0.1 s)."""
        out: list[dict[str, Any]] = []
        for name in sorted(self._dirty):
            if now - self._last_emit.get(name, -math.inf) >= MIN_INTERVAL_S - _EPS:
                out += self._drone_patch(self.drones[name], now)
        return out

    # -- the whole state --------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """Everything the page shows, at once (what the patches so far add up to)."""
        return {
            "setup": self.setup.to_json(),
            "mission": dict(self.mission),
            "drones": {n: {**d.fields(), "trail": list(d.trail)} for n, d in self.drones.items()},
            "nodes": {k: dict(v) for k, v in self.nodes.items()},
            "bars": [dict(b) for b in self.bars],
            "forecast": self.forecast_view,
            "links": {
                link_key(c.src, c.dst): c.to_json()
                for c in (self.links.counts() if self.links is not None else [])
            },
        }

    def node_states(self) -> dict[str, str]:
        """Every node's current state, by key."""
        return {k: v["state"] for k, v in self.nodes.items()}


def _taken_mode(words: str) -> str:
    """The mode in "taken over by the pilot in LOITER at (...)" ("" when not there)."""
    _, _, rest = words.partition(f"{TAKEN_OVER_PREFIX} in ")
    return rest.split(" ", 1)[0].rstrip(":") if rest else ""


def link_key(src: str, dst: str) -> str:
    """A link's key in the page's state (``"Drone1>Drone2"``)."""
    return f"{src}>{dst}"


def _link_patches(counts: list[LinkCount]) -> list[dict[str, Any]]:
    return [{"k": "link", **c.to_json()} for c in counts]


def apply_patches(snapshot: dict[str, Any], patches: Iterable[dict[str, Any]]) -> None:
    """Apply ``patches`` to a snapshot in place (what the page does; tests use it)."""
    for p in patches:
        kind = p["k"]
        body = {k: v for k, v in p.items() if k != "k"}
        if kind == "drone":
            drone = snapshot["drones"].setdefault(p["drone"], {"trail": []})
            drone["trail"] = drone.get("trail", []) + body.pop("trail_add", [])
            drone.update(body)
        elif kind == "node":
            snapshot["nodes"][body.pop("node")] = body
        elif kind == "bar":
            index = body.pop("i")
            bars = snapshot["bars"]
            bars.extend({} for _ in range(index + 1 - len(bars)))
            bars[index] = body
        elif kind == "mission":
            snapshot["mission"] = body
        elif kind == "link":
            snapshot.setdefault("links", {})[link_key(body["src"], body["dst"])] = body
        elif kind == "forecast":
            snapshot["forecast"] = body
