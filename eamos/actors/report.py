"""A drone's part of the run summary, as a typed value (:class:`DroneReport`).

The drone sends it to the ground station as JSON (``wire.Report``) and writes
it to ``report.json``; the ground station, ``eamos.ops`` and ``eamos report``
read it back with :meth:`DroneReport.from_json`.  The JSON keys are the ones
the first version wrote; :meth:`DroneReport.to_json` keeps them exactly, in
the same order.

A long mission's report stays small enough for one wire message (1 MiB): the
per-action list holds at most :data:`LISTED_ACTIONS_MAX_BYTES` of JSON, the
newest actions; the oldest are folded into counts (``actions_folded``, a
:class:`FoldedActions`, whose ``note`` says so in words).  Every action is
still in the drone's own ``uniform.log`` (``uniform.result``, docs/logs.md).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:  # the report itself needs only the standard library
    from ..hal.api import Telemetry
    from ..program.format import DroneProgram
    from .executive import ExecutiveSnapshot
    from .messages import ActionRecord

__all__ = [
    "LISTED_ACTIONS_MAX",
    "LISTED_ACTIONS_MAX_BYTES",
    "LISTED_BLOCKED_MAX",
    "ActionEntry",
    "DroneReport",
    "DroneReportError",
    "FinalState",
    "FoldedActions",
    "fold_actions",
]

LISTED_ACTIONS_MAX_BYTES: Final = 512 * 1024
"""JSON bytes of per-action entries a report lists (the rest are counted): half a wire message.

MessagePack (the wire) is smaller than JSON for these entries, so the list, with
everything else a report holds, stays well under ``wire.MAX_PAYLOAD_BYTES``."""
LISTED_ACTIONS_MAX: Final = 20_000
"""At most this many entries are listed, whatever their size (a wire list holds 65 536)."""
LISTED_BLOCKED_MAX: Final = 1_000
"""At most this many blocked nodes are named; ``blocked_nodes_more`` counts the rest."""


class DroneReportError(ValueError):
    """A report's JSON lacks a key or has a value of the wrong type."""


def _get(data: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    """``data[key]`` if present and of ``kind`` (a bool is not a number here)."""
    if key not in data:
        raise DroneReportError(f"{where}: no {key!r}")
    value = data[key]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        raise DroneReportError(f"{where}: {key!r} is {value!r}")
    return value


@dataclass(frozen=True)
class FinalState:
    """Where the vehicle was, and how, once its last action ended."""

    x: float
    y: float
    z: float
    armed: bool
    battery: float
    landed: bool | None = None  # None: a report from before it was written

    @classmethod
    def of(cls, sample: Telemetry) -> FinalState:
        """The final state a telemetry sample shows."""
        return cls(
            sample.x_m, sample.y_m, sample.z_m, sample.armed, sample.battery_pct, sample.landed
        )

    def to_json(self) -> dict[str, Any]:
        out = {"x": self.x, "y": self.y, "z": self.z, "armed": self.armed, "battery": self.battery}
        if self.landed is not None:
            out["landed"] = self.landed
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> FinalState:
        num = (int, float)
        return cls(
            float(_get(data, "x", num, "final")),
            float(_get(data, "y", num, "final")),
            float(_get(data, "z", num, "final")),
            bool(_get(data, "armed", bool, "final")),
            float(_get(data, "battery", num, "final")),
            bool(_get(data, "landed", bool, "final")) if "landed" in data else None,
        )


@dataclass(frozen=True)
class ActionEntry:
    """One action the drone ran (``reason`` only when there is one)."""

    node: str
    action: str
    args: tuple[float, ...]
    iteration: tuple[int, ...]
    start: float
    end: float
    result: str  # "ok" | "failed" | "cancelled"
    reason: str = ""

    @classmethod
    def of(cls, r: ActionRecord) -> ActionEntry:
        """The entry for one action record of the executive."""
        return cls(
            r.node, r.action, tuple(r.args), tuple(r.iteration), r.start, r.end, r.result, r.reason
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "node": self.node,
            "action": self.action,
            "args": list(self.args),
            "iteration": list(self.iteration),
            "start": self.start,
            "end": self.end,
            "result": self.result,
            **({"reason": self.reason} if self.reason else {}),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ActionEntry:
        where = "action"
        num = (int, float)
        return cls(
            node=_get(data, "node", str, where),
            action=_get(data, "action", str, where),
            args=tuple(float(a) for a in _get(data, "args", list, where)),
            iteration=tuple(int(i) for i in _get(data, "iteration", list, where)),
            start=float(_get(data, "start", num, where)),
            end=float(_get(data, "end", num, where)),
            result=_get(data, "result", str, where),
            reason=str(data.get("reason", "")),
        )


@dataclass(frozen=True)
class FoldedActions:
    """The oldest actions of a long mission, counted instead of listed (see the module doc)."""

    count: int
    ok: int
    failed: int
    cancelled: int
    first_start: float
    last_end: float
    caught: int = 0  # failed inside a Try's Body, handled by its OnFailure

    @classmethod
    def of(cls, entries: Sequence[ActionEntry]) -> FoldedActions:
        """The counts of ``entries`` (at least one)."""
        results = [a.result for a in entries]
        return cls(
            count=len(entries),
            ok=results.count("ok"),
            failed=results.count("failed"),
            cancelled=results.count("cancelled"),
            first_start=min(a.start for a in entries),
            last_end=max(a.end for a in entries),
            caught=results.count("caught"),
        )

    def merged(self, other: FoldedActions | None) -> FoldedActions:
        """These counts and ``other``'s together."""
        if other is None:
            return self
        return FoldedActions(
            self.count + other.count,
            self.ok + other.ok,
            self.failed + other.failed,
            self.cancelled + other.cancelled,
            min(self.first_start, other.first_start),
            max(self.last_end, other.last_end),
            self.caught + other.caught,
        )

    @property
    def note(self) -> str:
        """What the folding means, in words (written into the JSON for whoever reads it)."""
        return (
            f"the {self.count} oldest actions are counted here, not listed (a report lists "
            f"at most {LISTED_ACTIONS_MAX_BYTES // 1024} KiB of actions); every action is in "
            "the drone's uniform.log (event uniform.result)"
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "count": self.count,
            "ok": self.ok,
            "failed": self.failed,
            "cancelled": self.cancelled,
            **({"caught": self.caught} if self.caught else {}),
            "first_start": self.first_start,
            "last_end": self.last_end,
            "note": self.note,
        }

    @classmethod
    def from_json(cls, data: Any) -> FoldedActions:
        where = "actions_folded"
        if not isinstance(data, Mapping):
            raise DroneReportError(f"report: {where!r} is {data!r}")
        num = (int, float)
        return cls(
            count=_get(data, "count", int, where),
            ok=_get(data, "ok", int, where),
            failed=_get(data, "failed", int, where),
            cancelled=_get(data, "cancelled", int, where),
            first_start=float(_get(data, "first_start", num, where)),
            last_end=float(_get(data, "last_end", num, where)),
            caught=int(data.get("caught", 0)),
        )


def fold_actions(
    actions: Sequence[ActionEntry], folded: FoldedActions | None = None
) -> tuple[list[dict[str, Any]], FoldedActions | None]:
    """The JSON entries to list (the newest, within the limits) and the counts of the rest.

    ``actions`` are in start order; ``folded`` are counts already folded earlier
    (a report read back and written again).  Pure: tested without a drone.
    """
    listed: list[dict[str, Any]] = []
    size = 0
    keep = len(actions)
    for index in range(len(actions) - 1, -1, -1):
        entry = actions[index].to_json()
        size += len(json.dumps(entry)) + 2
        if size > LISTED_ACTIONS_MAX_BYTES or len(listed) >= LISTED_ACTIONS_MAX:
            break
        listed.append(entry)
        keep = index
    listed.reverse()
    if keep == 0:
        return listed, folded
    return listed, FoldedActions.of(actions[:keep]).merged(folded)


@dataclass(frozen=True)
class DroneReport:
    """One drone's part of the run summary (see the module docstring for its JSON)."""

    ok: bool
    resolved: bool
    aborted: bool
    abort_reason: str
    triggers_sent: int
    triggers_received: int
    external_out: int
    external_in: int
    mdg: Mapping[str, int]
    blocked_nodes: tuple[str, ...]
    actions: tuple[ActionEntry, ...]
    final: FinalState | None
    adapter_error: str = ""
    retransmissions: int = 0
    duplicates_dropped: int = 0
    net: Mapping[str, Any] = field(default_factory=dict)
    folded: FoldedActions | None = None  # the oldest actions, counted, when the list was cut
    blocked_nodes_more: int = 0  # blocked nodes beyond those named
    #: What the adapter knows about the vehicle (``Adapter.facts()``: whether its link was
    #: signed, a pilot's takeover); the JSON key ``vehicle``, present only when not empty.
    vehicle: Mapping[str, Any] = field(default_factory=dict)

    @property
    def action_count(self) -> int:
        """Every action the drone ran: those listed and those folded into counts."""
        return len(self.actions) + (self.folded.count if self.folded else 0)

    @classmethod
    def build(
        cls,
        program: DroneProgram,
        snap: ExecutiveSnapshot,
        *,
        triggers_sent: int,
        net: Mapping[str, Any],
        final: Telemetry | None,
        aborted: bool,
        abort_reason: str,
        adapter_error: str,
        vehicle: Mapping[str, Any] | None = None,
    ) -> DroneReport:
        """The report of a drone from what its runtime knows at the end."""
        stats = program.stats()
        actions = tuple(
            ActionEntry.of(r) for r in sorted(snap.records, key=lambda r: (r.start, r.node))
        )
        failed = any(a.result == "failed" for a in actions)
        blocked = tuple(sorted(k for k, s in snap.resolved.items() if s == "failed"))
        return cls(
            ok=snap.all_resolved and not failed and not blocked and not aborted,
            resolved=snap.all_resolved,
            aborted=aborted,
            abort_reason=abort_reason,
            triggers_sent=triggers_sent,
            triggers_received=snap.triggers_received,
            external_out=stats["external_out"],
            external_in=stats["external_in"],
            mdg=stats,
            blocked_nodes=blocked,
            actions=actions,
            final=None if final is None else FinalState.of(final),
            adapter_error=adapter_error,
            retransmissions=int(net.get("retransmissions", 0)),
            duplicates_dropped=int(net.get("duplicates_dropped", 0)),
            net=net,
            vehicle=dict(vehicle or {}),
        )

    @property
    def failed_actions(self) -> list[ActionEntry]:
        """The actions that ended ``failed``."""
        return [a for a in self.actions if a.result == "failed"]

    def to_json(self, *, fold: bool = True) -> dict[str, Any]:
        """The report as the first version's JSON object (same keys, same order).

        A long mission's oldest actions are folded into ``actions_folded`` and
        blocked nodes beyond :data:`LISTED_BLOCKED_MAX` into ``blocked_nodes_more``
        (keys present only then), so a report file or summary stays readable.
        ``fold=False`` lists every action (the wire: a report of any size goes in
        parts, :mod:`eamos.net.reports`).
        """
        if fold:
            listed, folded = fold_actions(self.actions, self.folded)
        else:
            listed, folded = [a.to_json() for a in self.actions], self.folded
        blocked = self.blocked_nodes[:LISTED_BLOCKED_MAX]
        more = self.blocked_nodes_more + len(self.blocked_nodes) - len(blocked)
        out = {
            "ok": self.ok,
            "resolved": self.resolved,
            "aborted": self.aborted,
            "abort_reason": self.abort_reason,
            "triggers_sent": self.triggers_sent,
            "triggers_received": self.triggers_received,
            "external_out": self.external_out,
            "external_in": self.external_in,
            "mdg": dict(self.mdg),
            "blocked_nodes": list(blocked),
            "actions": listed,
            "final": None if self.final is None else self.final.to_json(),
            "adapter_error": self.adapter_error,
            # Each trigger counts once above; what it took on the network is here.
            "retransmissions": self.retransmissions,
            "duplicates_dropped": self.duplicates_dropped,
            "net": dict(self.net),
        }
        if self.vehicle:
            out["vehicle"] = dict(self.vehicle)
        if folded is not None:
            out["actions_folded"] = folded.to_json()
        if more:
            out["blocked_nodes_more"] = more
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DroneReport:
        """Read a report back; :class:`DroneReportError` names a missing or mistyped key.

        Keys the summary adds around a report (``exit_code``, ``error`` ...) are ignored.
        """
        where = "report"
        final = data.get("final")
        if final is not None and not isinstance(final, Mapping):
            raise DroneReportError(f"{where}: 'final' is {final!r}")
        actions: Sequence[Any] = _get(data, "actions", list, where)
        return cls(
            ok=_get(data, "ok", bool, where),
            resolved=_get(data, "resolved", bool, where),
            aborted=_get(data, "aborted", bool, where),
            abort_reason=_get(data, "abort_reason", str, where),
            triggers_sent=_get(data, "triggers_sent", int, where),
            triggers_received=_get(data, "triggers_received", int, where),
            external_out=_get(data, "external_out", int, where),
            external_in=_get(data, "external_in", int, where),
            mdg=dict(_get(data, "mdg", dict, where)),
            blocked_nodes=tuple(_get(data, "blocked_nodes", list, where)),
            actions=tuple(ActionEntry.from_json(a) for a in actions),
            final=None if final is None else FinalState.from_json(final),
            adapter_error=str(data.get("adapter_error", "")),
            retransmissions=int(data.get("retransmissions", 0)),
            duplicates_dropped=int(data.get("duplicates_dropped", 0)),
            net=dict(data.get("net") or {}),
            folded=(
                None
                if data.get("actions_folded") is None
                else FoldedActions.from_json(data["actions_folded"])
            ),
            blocked_nodes_more=_get({"n": data.get("blocked_nodes_more", 0)}, "n", int, where),
            vehicle=dict(_get({"v": data.get("vehicle", {})}, "v", dict, where)),
        )
