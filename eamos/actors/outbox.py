"""The Out-Bridge (paper Figures 10, 11): packs messages for remote drones onto the wire."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterable
from typing import Any, cast

from ..logs import EventLog, LogLine, log_line
from ..net import wire
from ..net.link import Link
from .messages import SendInterrupt, SendTrigger, Trigger

__all__ = ["Outbox"]


def _write(line: LogLine) -> None:
    log_line(*line)


class Outbox:
    """Takes messages with ``tell`` like an actor, but handles them in the caller's thread.

    The link's ``send`` (:class:`~eamos.net.link.Link`, which numbers reliable
    messages and retransmits them until acknowledged) is already a thread-safe
    hand-over to the bridge's socket thread, and a second queue would only add a
    context switch to every cross-drone trigger.  ``triggers_sent`` counts each
    trigger once, however often the link had to retransmit it (the Table 7
    check).  After :meth:`seal` (the drone aborted on an internal failure) node
    triggers are dropped: only :meth:`release` speaks for this drone's nodes.

    ``acknowledged``: a resumed node's triggers that the node before it sent and its
    peers acknowledged (:mod:`.rejoin`).  Replaying its past sends them again; they are
    counted as sent but not put on the wire (``mission.outbridge.acknowledged``).
    """

    def __init__(
        self,
        bridge: Link,
        drone: str,
        mission_id: str,
        log: EventLog,
        acknowledged: frozenset[tuple[str, str, tuple[int, ...]]] = frozenset(),
    ) -> None:
        self.bridge = bridge
        self.drone = drone
        self.mission_id = mission_id
        self.log = log
        self._lock = threading.Lock()
        self.triggers_sent = 0
        self.sent_by_dest: dict[str, int] = {}
        self._sent: set[tuple[str, str, tuple[int, ...]]] = set()  # (src, dst, iteration)
        self._sealed = False
        self._acknowledged = acknowledged

    def tell(self, message: SendTrigger | SendInterrupt | wire.Message) -> None:
        """Send ``message`` (a :class:`SendTrigger`, :class:`SendInterrupt` or wire message)."""
        if isinstance(message, SendTrigger):
            line = self.send_trigger(message.dest, message.trigger)
            if line is not None:
                _write(line)
        elif isinstance(message, SendInterrupt):
            if self._is_sealed():
                return
            i = message.interrupt
            self.bridge.send(
                wire.Interrupt(
                    mission=self.mission_id,
                    sender=self.drone,
                    dest=message.dest,
                    scope=str(i.scope),
                    iteration=i.iteration,
                    mode=cast(wire.InterruptMode, i.mode),  # the node logic's modes
                )
            )
            self.log.info(
                "mission.outbridge.interrupt",
                dest=message.dest,
                scope=i.scope,
                iteration=list(i.iteration),
                mode=i.mode,
            )
        else:
            self.bridge.send(message)

    def _is_sealed(self) -> bool:
        with self._lock:
            return self._sealed

    def send_trigger(self, dest: str, t: Trigger) -> LogLine | None:
        """Send a node's trigger; its ``mission.outbridge.sent`` line, for the caller to write.

        None: not sent (sealed).  A node writes the line with its turn's other lines,
        after its triggers to other drones went out (:mod:`.node`).
        """
        return self._send_trigger(dest, t, sealed_ok=False)

    def _send_trigger(self, dest: str, t: Trigger, sealed_ok: bool) -> LogLine | None:
        key = (t.src, t.dst, tuple(t.iteration))
        with self._lock:
            if (self._sealed and not sealed_ok) or (sealed_ok and key in self._sent):
                return None
            self._sent.add(key)
            self.triggers_sent += 1
            self.sent_by_dest[dest] = self.sent_by_dest.get(dest, 0) + 1
        fields = {
            "dest": dest,
            "src": t.src,
            "dst": t.dst,
            "iteration": list(t.iteration),
            "status": t.status,
        }
        if key in self._acknowledged:  # the node before sent it, and it arrived
            return (self.log, "info", "mission.outbridge.acknowledged", fields, time.time())
        msg = wire.Trigger(
            mission=self.mission_id,
            sender=self.drone,
            dest=dest,
            src_node=t.src,
            dst_node=t.dst,
            iteration=tuple(t.iteration),
            status=t.status,
        )
        self.bridge.send(msg)
        return (self.log, "info", "mission.outbridge.sent", fields, time.time())

    def seal(self) -> None:
        """Drop node triggers and interrupts from now on (the drone's nodes no longer speak)."""
        with self._lock:
            self._sealed = True

    def release(self, arcs: Iterable[tuple[str, str, str]]) -> int:
        """Send ``failed`` on each ``(dest, src, dst)`` arc of activation () not sent yet.

        Dead-path elimination for a drone that aborted: the nodes waiting for it
        on other drones are blocked and finish, instead of waiting for ever.
        Returns how many triggers went out.
        """
        sent = 0
        for dest, src, dst in arcs:
            line = self._send_trigger(dest, Trigger(src, dst, (), "failed"), sealed_ok=True)
            if line is not None:
                _write(line)
                sent += 1
        return sent

    def counts(self) -> dict[str, Any]:
        """Triggers sent (each once), in all and per destination."""
        with self._lock:
            return {"triggers_sent": self.triggers_sent, "by_dest": dict(self.sent_by_dest)}
