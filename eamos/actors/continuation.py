"""Going on from what a mission did: a virtual run from a snapshot, a restarted node.

What a drone reported (its progress events: :func:`activations` keeps the last state
of every activation, node and loop counters, and when and where each action began)
is read into a :class:`Continuation`, from two sources:

* the ground station's ``RUN_DIR/snapshot.json`` (:mod:`eamos.ground.snapshot`), every
  drone's part and where its vehicle was (:func:`load_snapshot`, :func:`continuation`):
  :class:`~eamos.virtual.VirtualMission` (``continuation=``) runs the rest of the
  mission in virtual time, each vehicle starting where the snapshot saw it
  (:meth:`~eamos.hal.kinematics.Quadcopter.at`);
* a drone node's own journal of what it reported (:mod:`.rejoin`): a node restarted
  mid-mission replays its program up to where it was (:class:`Replay`).

Either way the programs run from their start, with these differences, so that what
happened is not done again and what did not happen yet happens from where the drones
are:

* an action recorded as ended (``ok``, ``failed``, ``cancelled``) ends at once with that
  result (and, for a node, its times), without commanding its vehicle; one recorded as
  running starts again for what it had left: a ``FlyByX/Y/Z`` as a ``FlyToXYZ`` to the
  end it was going to (where it began plus its offset), a ``PauseFor`` for the time it
  had left, any other action as it was;
* a condition decision the record shows is taken as it was (an ``If``'s branch, a
  wait that handed on, a ``Do`` whose Body ran or was skipped, a loop's iterations, a
  ``Whenever`` that fired); a watch (a ``Do``'s or loop's stop condition, a
  ``Whenever``) is not interrupted while the past is replayed unless it was; every
  other decision is taken from the vehicles' state, as always.

All of this is pure but for :func:`load_snapshot` (a file) and :class:`Replay`'s
bookkeeping (one drone's nodes on its dispatcher's threads).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeGuard

from ..hal.api import ActionResult
from ..hal.kinematics import VehicleState
from .logic import ConditionLogic, DoLogic, IfLogic, LoopLogic, WaitLogic, WheneverLogic
from .state import Iteration, holds

__all__ = [
    "ENDED",
    "Continuation",
    "DronePast",
    "Replay",
    "SnapshotError",
    "activations",
    "continuation",
    "install_continuation",
    "load_snapshot",
]

#: The states in which an action had ended (its record's result).
ENDED = frozenset({"ok", "failed", "cancelled"})
#: Relative moves: the axis of each (x, y, z).
_AXIS = {"FlyByX": 0, "FlyByY": 1, "FlyByZ": 2}
#: Watches: a decision that interrupts (or fires) only when the snapshot shows it did.
_WATCHES = frozenset({"do-watch", "loop-watch", "whenever"})

Activation = tuple[str, Iteration]  # (node key, loop counters)


class SnapshotError(ValueError):
    """A snapshot that cannot be continued from (the message says where and why)."""


@dataclass(frozen=True)
class Began:
    """A running action: when (the drone's wall-clock time) and where it began."""

    at: float | None
    position: tuple[float, float, float] | None


@dataclass(frozen=True)
class DronePast:
    """One participant's part of the snapshot."""

    states: Mapping[Activation, str] = field(default_factory=dict)
    details: Mapping[Activation, str] = field(default_factory=dict)
    began: Mapping[Activation, Began] = field(default_factory=dict)
    vehicle: VehicleState | None = None
    changed_at: Mapping[Activation, float] = field(default_factory=dict)  # its last state's time


@dataclass(frozen=True)
class Continuation:
    """What a snapshot says happened, for a virtual run going on from it."""

    mission_id: str
    taken_at: float  # the snapshot's wall-clock time
    why: str
    drones: Mapping[str, DronePast]

    def vehicle(self, drone: str) -> VehicleState | None:
        """Where ``drone``'s vehicle was (None: the snapshot has no telemetry of it)."""
        past = self.drones.get(drone)
        return past.vehicle if past is not None else None

    def state(self, drone: str, key: str, act: Iteration) -> str | None:
        """The last state ``drone`` reported for one activation (None: none)."""
        past = self.drones.get(drone)
        return past.states.get((key, act)) if past is not None else None

    def ended(self, drone: str, key: str, act: Iteration) -> ActionResult | None:
        """The result of an action that had ended (None: it had not)."""
        state = self.state(drone, key, act)
        if state not in ENDED:  # also a participant the snapshot does not hold
            return None
        if state == "ok":
            return ActionResult("ok")
        reason = self.drones[drone].details.get((key, act)) or f"{state} before the snapshot"
        return ActionResult("failed" if state == "failed" else "cancelled", reason)

    def rest(
        self,
        drone: str,
        key: str,
        act: Iteration,
        action: str,
        args: tuple[Any, ...],
        now_s: float | None = None,
    ) -> tuple[str, tuple[Any, ...]]:
        """What is left of an action: the action and arguments to run (as given if it had
        not begun).

        A ``FlyByX/Y/Z`` that began becomes a ``FlyToXYZ`` to the end it was flying to
        (where it began plus its offset): it needs no position now, which a vehicle
        found in flight may not have given yet.  A ``PauseFor`` keeps the time it had
        left at ``now_s`` (default: when the snapshot was taken).
        """
        past = self.drones.get(drone)
        began = past.began.get((key, act)) if past is not None else None
        if began is None:
            return action, args
        axis = _AXIS.get(action)
        if axis is not None and began.position is not None:
            end = list(began.position)
            end[axis] += float(args[0])
            return "FlyToXYZ", tuple(end)
        if action == "PauseFor" and began.at is not None:
            t = self.taken_at if now_s is None else now_s
            return action, (max(0.0, float(args[0]) - (t - began.at)), *args[1:])
        return action, args

    def decision(
        self, drone: str, logic: ConditionLogic, act: Iteration, purpose: str, turn: int
    ) -> bool | None:
        """The value the snapshot shows a condition had for ``purpose`` (None: it shows none).

        ``turn`` counts the decisions already asked of this activation for this
        purpose (a loop decides once per iteration).
        """
        key, kind = logic.key, logic.spec.kind
        state = self.state(drone, key, act)
        if purpose == "if" and isinstance(logic, IfLogic) and state == "decided":
            detail = self.drones[drone].details.get((key, act), "")
            branch = detail.split(":", 1)[0]
            return {"then": True, "else": False}.get(branch)
        if purpose == "wait" and isinstance(logic, WaitLogic) and state == "ok":
            return _value(kind, go=False)
        if purpose == "do" and isinstance(logic, DoLogic):
            body = self._route_states(logic, "body", act)
            if not body:
                return None
            return _value(kind, go=any(s != "skipped" for s in body))
        if purpose == "loop" and isinstance(logic, LoopLogic):
            if self._route_states(logic, "body", (*act, turn)):
                return _value(kind, go=True)
            if self._route_states(logic, "exit", act):  # what follows the loop began
                return _value(kind, go=False)
            return None
        if purpose == "whenever" and isinstance(logic, WheneverLogic):
            return state == "decided" and turn == 0
        return None

    def _route_states(self, logic: ConditionLogic, kind: str, act: Iteration) -> list[str]:
        """The states reported for the activations ``logic``'s ``kind`` arcs lead to."""
        out: list[str] = []
        for route in logic.routes:
            if route.kind == kind:
                state = self.state(route.drone, route.dst, act)
                if state is not None:
                    out.append(state)
        return out


#: What an activation's entry keeps from its first "running" event.
STARTED = ("action", "at", "from")


def activations(events: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The last state of every activation in progress ``events``, in the order first seen.

    Each event: ``state``, ``node``, ``iteration`` (loop counters), ``t`` (when),
    ``action``, ``detail``, and for ``running`` where the vehicle was (``position``).
    An entry is ``{"node", "iteration", "state", "t"}``, with ``detail`` where the last
    event gave one and, for an action that began, ``action``, ``at`` and ``from`` of its
    first ``running`` event (a suspended and resumed action began where it first did).
    Events of no node (a link's) and with junk loop counters are left out.
    """
    out: dict[Activation, dict[str, Any]] = {}
    for event in events:
        node, state = event.get("node"), event.get("state")
        if not (isinstance(node, str) and node and isinstance(state, str)):
            continue
        iteration = list(event.get("iteration") or [])
        if not all(isinstance(i, int) and not isinstance(i, bool) for i in iteration):
            continue
        entry: dict[str, Any] = {"node": node, "iteration": iteration, "state": state}
        if _number(event.get("t")):
            entry["t"] = event["t"]
        if event.get("detail"):
            entry["detail"] = str(event["detail"])
        if state == "running":  # when and where it began
            entry["action"], entry["at"] = event.get("action", ""), event.get("t")
            if event.get("position") is not None:
                entry["from"] = event["position"]
        key = (node, tuple(iteration))
        began = {k: v for k, v in out.get(key, {}).items() if k in STARTED}
        out[key] = {**entry, **began}
    return list(out.values())


class Replay:
    """A restarted node's past, replayed once: what its nodes ask while they catch up.

    ``pending``: the actions that had ended, not replayed yet; while there are any the
    node is still replaying (:meth:`replaying`), and a watch it does not record
    interrupting does not interrupt.  Shared by the drone's node actors (on its
    dispatcher's threads): each activation is one node's, so each is taken once.
    """

    def __init__(
        self,
        cont: Continuation,
        drone: str,
        acknowledged: frozenset[tuple[str, str, tuple[int, ...]]] = frozenset(),
    ) -> None:
        self.continuation = cont
        self.drone = drone
        # Triggers the node before sent and its peers acknowledged: not sent again.
        self.acknowledged = acknowledged
        past = cont.drones.get(drone, DronePast())
        self.pending = {k for k, state in past.states.items() if state in ENDED}

    def replaying(self) -> bool:
        """True while an action that had ended was not replayed yet."""
        return bool(self.pending)

    def ended(self, key: str, act: Iteration) -> tuple[ActionResult, float, float] | None:
        """An action that had ended: its result, start and end time (None: it had not)."""
        result = self.continuation.ended(self.drone, key, act)
        if result is None:
            return None
        self.pending.discard((key, act))
        past = self.continuation.drones[self.drone]
        began = past.began.get((key, act))
        end = past.changed_at.get((key, act), self.continuation.taken_at)
        start = began.at if began is not None and began.at is not None else end
        return result, start, end


def _value(kind: str, go: bool) -> bool:
    """The condition value with which a While/Until structure of ``kind`` goes on (or not)."""
    return go == holds(kind, True)


def watch_value(kind: str, purpose: str) -> bool | None:
    """While the past is replayed: the value that does not interrupt a watch (None: no watch)."""
    if purpose not in _WATCHES:
        return None
    return False if purpose == "whenever" else _value(kind, go=True)


def load_snapshot(path: Path) -> Any:
    """The JSON document in ``path`` (a run folder: its ``snapshot.json``)."""
    path = Path(path)
    if path.is_dir():
        path = path / "snapshot.json"
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SnapshotError(f"{path}: cannot read the snapshot ({exc.strerror})") from exc
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SnapshotError(f"{path}: not a snapshot (not JSON: {exc})") from exc


def continuation(doc: Any, where: str = "snapshot") -> Continuation:
    """Read a snapshot document (:func:`load_snapshot`); :class:`SnapshotError` if it is not one."""
    if not isinstance(doc, dict) or not isinstance(doc.get("participants"), dict):
        raise SnapshotError(f"{where}: not a snapshot (no 'participants' table)")
    mission_id = doc.get("mission_id")
    taken_at = doc.get("t")
    if not isinstance(mission_id, str) or not _number(taken_at):
        raise SnapshotError(f"{where}: 'mission_id' (text) and 't' (a time) are required")
    drones: dict[str, DronePast] = {}
    for drone, part in doc["participants"].items():
        drones[drone] = _drone_past(part, f"{where}: participants.{drone}")
    return Continuation(mission_id, float(taken_at), str(doc.get("why", "")), drones)


def _drone_past(part: Any, where: str) -> DronePast:
    if not isinstance(part, dict):
        raise SnapshotError(f"{where}: not a table")
    entries = part.get("activations")
    if not isinstance(entries, list):
        raise SnapshotError(
            f"{where}: no 'activations' list (a snapshot written before EAMOS could continue one)"
        )
    states: dict[Activation, str] = {}
    details: dict[Activation, str] = {}
    began: dict[Activation, Began] = {}
    changed_at: dict[Activation, float] = {}
    for i, entry in enumerate(entries):
        here = f"{where}.activations[{i}]"
        if not isinstance(entry, dict):
            raise SnapshotError(f"{here}: not a table")
        node, iteration, state = entry.get("node"), entry.get("iteration"), entry.get("state")
        if (
            not isinstance(node, str)
            or not isinstance(state, str)
            or not isinstance(iteration, list)
            or not all(isinstance(n, int) and not isinstance(n, bool) for n in iteration)
        ):
            raise SnapshotError(f"{here}: needs 'node' (text), 'iteration' (integers), 'state'")
        key = (node, tuple(iteration))
        states[key] = state
        if isinstance(entry.get("detail"), str):
            details[key] = entry["detail"]
        changed = _time(entry.get("t"))
        if changed is not None:
            changed_at[key] = changed
        if "at" in entry or "from" in entry:
            began[key] = Began(_time(entry.get("at")), _point(entry.get("from"), f"{here}.from"))
    vehicle = _vehicle(part.get("vehicle"), f"{where}.vehicle")
    return DronePast(states, details, began, vehicle, changed_at)


def _vehicle(data: Any, where: str) -> VehicleState | None:
    if data is None:
        return None
    if not isinstance(data, dict):
        raise SnapshotError(f"{where}: not a table")
    for name in ("x", "y", "z"):
        if not _number(data.get(name)):
            raise SnapshotError(f"{where}.{name}: a number is required")
    velocity = data.get("velocity") or [0.0, 0.0, 0.0]
    if not isinstance(velocity, list) or len(velocity) != 3 or not all(map(_number, velocity)):
        raise SnapshotError(f"{where}.velocity: three numbers (m/s) are required")
    battery = data.get("battery")
    x, y, z = float(data["x"]), float(data["y"]), float(data["z"])
    return VehicleState(
        x_m=x,
        y_m=y,
        z_m=z,
        vx_mps=float(velocity[0]),
        vy_mps=float(velocity[1]),
        vz_mps=float(velocity[2]),
        armed=bool(data.get("armed")),
        landed=bool(data.get("landed", z <= 0.0)),
        battery_pct=float(battery) if _number(battery) else 100.0,
    )


def _point(data: Any, where: str) -> tuple[float, float, float] | None:
    if data is None:
        return None
    if not isinstance(data, list) or len(data) != 3 or not all(map(_number, data)):
        raise SnapshotError(f"{where}: three numbers (x, y, z in metres) are required")
    return (float(data[0]), float(data[1]), float(data[2]))


def _time(data: Any) -> float | None:
    return float(data) if _number(data) else None


def _number(value: Any) -> TypeGuard[int | float]:
    return isinstance(value, int | float) and not isinstance(value, bool) and value == value


def install_continuation(
    cont: Continuation,
    logic: Mapping[str, Mapping[str, Any]],
    replaying: Callable[[], bool],
) -> None:
    """Make every condition node (``logic[drone][key]``) answer as ``cont`` shows, first.

    What the snapshot does not show is asked of the hook installed before (the
    check's explorer), or simulated; ``replaying()`` is True while the past is
    replayed, when a watch the snapshot does not show interrupting does not interrupt.
    """
    turns: dict[tuple[str, str, Iteration, str], int] = {}

    def answer(drone: str, node: ConditionLogic) -> Callable[[Iteration, str, bool], bool]:
        inner = node.override

        def override(act: Iteration, purpose: str, value: bool) -> bool:
            turn = turns.get((drone, node.key, act, purpose), 0)
            turns[(drone, node.key, act, purpose)] = turn + 1
            known = cont.decision(drone, node, act, purpose, turn)
            if known is None and replaying():
                known = watch_value(node.spec.kind, purpose)
            if known is not None:
                return known
            return value if inner is None else bool(inner(act, purpose, value))

        return override

    for drone, nodes in logic.items():
        for node in nodes.values():
            if isinstance(node, ConditionLogic):
                node.override = answer(drone, node)
