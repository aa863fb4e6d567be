"""The receive thread of In-Bridges: one for a participant alone, one for every drone of a process.

An In-Bridge reads its sockets (a SUB socket and a monitor per peer) on one
thread that owns them.  Fifty drones in one process had fifty such threads, each
woken for each message it received and each queuing for the GIL with the
others; a :class:`ReceiveHost` instead waits on the sockets of every In-Bridge
given to it with one :class:`~eamos.net.readiness.SocketWatch`, and each turn
gives every bridge its share: the sockets of its that are ready
(:meth:`ReceiveMember.turn`).  A participant alone in its process (the ground
station, a drone of its own) has a host of its own, so both cases run the same
code.

What a bridge asks of its thread from elsewhere (subscribe, connect, leave) is a
call queued to the host (:meth:`ReceiveHost.call`) and run on its thread, in the
order asked, at the start of the next turn; a control socket wakes the thread.

Failure policy: a bridge whose own sockets fail (a :class:`zmq.ZMQError` in its
turn) is logged on its own log (``net.in.thread_error``) and leaves the host;
the others go on.  Nothing one message raises gets here: the bridge keeps it
(:class:`~eamos.net.in_bridge.ReceiveLedger`).  Only the end of the ZeroMQ
context, which every bridge of the host shares, ends the thread
(``net.in.context_terminated`` on each bridge's log).
"""

from __future__ import annotations

import collections
import threading
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, Protocol

import zmq

from eamos.net.readiness import SocketWatch
from eamos.net.sockets import CMD_STOP, CMD_WAKE, JOIN_TIMEOUT_S, control_pair

if TYPE_CHECKING:
    from eamos.logs import EventLog

__all__ = ["STALL_S", "ReceiveHost", "ReceiveMember"]

#: A turn of the receive thread longer than this is reported to its bridges
#: (:meth:`ReceiveMember.stalled`): far above a turn's usual length, and below a
#: link's own stall threshold.
STALL_S = 0.05

Socket = zmq.Socket[Any]


class ReceiveMember(Protocol):
    """An In-Bridge as its receive thread sees it (every method runs on that thread)."""

    @property
    def log(self) -> EventLog:
        """Where the thread reports what ended this member."""
        ...

    def sockets(self) -> Iterable[Socket]:
        """The sockets to watch for it."""
        ...

    def next_due(self) -> float | None:
        """When it next has something due without a message (monotonic seconds; None: never).
        Asked after each of its turns."""
        ...

    def turn(self, ready: list[Socket], host: ReceiveHost) -> None:
        """Its share of one turn: read ``ready`` (its sockets that are readable; empty when
        only something due brought the turn), do what is due.  Raises
        :class:`zmq.ZMQError` if its sockets fail."""
        ...

    def stalled(self, seconds: float) -> None:
        """A turn it was part of took ``seconds``, more than :data:`STALL_S`: what its
        peers sent meanwhile waited unread."""
        ...

    def ended(self) -> None:
        """It left the thread: close its sockets (monitors first)."""
        ...


class ReceiveHost:
    """One thread reading the sockets of the In-Bridges it hosts (see the module doc).

    ``context``: the ZeroMQ context of its control socket (the bridges' own).  The
    thread starts with the first :meth:`add` and ends with :meth:`stop`.
    """

    def __init__(self, context: zmq.Context[Any], name: str = "eamos-inbridges") -> None:
        self._ctrl_rx, self._ctrl_tx = control_pair(context, "receive")
        self._lock = threading.Lock()  # guards _ctrl_tx, _calls and the lifecycle flags
        self._calls: collections.deque[tuple[ReceiveMember, Callable[[], None]]]
        self._calls = collections.deque()
        self._started = False
        self._open = True  # calls are taken (the thread has not ended)
        self._members: dict[ReceiveMember, list[Socket]] = {}
        self._owner: dict[Socket, ReceiveMember] = {}
        self._due: dict[ReceiveMember, float] = {}  # members with something due, and when
        self._watch = SocketWatch()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)

    # -- any thread ------------------------------------------------------------------

    def call(self, member: ReceiveMember, fn: Callable[[], None]) -> bool:
        """Run ``fn`` for ``member`` on the host's thread, after what was asked before;
        False if the thread ended.  Should ``fn`` raise, ``member`` fails (module doc)."""
        with self._lock:
            if not self._open:
                return False
            self._calls.append((member, fn))
            if not self._started:
                self._started = True
                self._thread.start()
            self._ctrl_tx.send(CMD_WAKE)
        return True

    def add(self, member: ReceiveMember) -> bool:
        """Watch ``member``'s sockets from the next turn on; False if the host ended."""
        return self.call(member, lambda: self._add(member))

    def remove(self, member: ReceiveMember, done: threading.Event | None = None) -> bool:
        """Let ``member`` go (its sockets closed on the thread); ``done`` is set then.
        False if the host ended (then it let every member go already)."""

        def leave() -> None:
            self._remove(member)
            if done is not None:
                done.set()

        return self.call(member, leave)

    def on_its_thread(self) -> bool:
        """Whether the caller is the host's thread."""
        return threading.current_thread() is self._thread

    @property
    def alive(self) -> bool:
        """Whether the thread runs."""
        return self._thread.is_alive()

    def stop(self, timeout_s: float = JOIN_TIMEOUT_S) -> bool:
        """End the thread (members left are let go); idempotent.  False if it did not end
        within ``timeout_s``."""
        with self._lock:
            if not self._open:
                started = self._started
            elif not self._started:
                self._open = False
                self._close_control()
                self._watch.close()
                return True
            else:
                started = True
                self._ctrl_tx.send(CMD_STOP)
        if started and not self.on_its_thread():
            self._thread.join(timeout_s)
            return not self._thread.is_alive()
        return True

    # -- the host's thread -------------------------------------------------------------

    def again(self, sock: Socket) -> None:
        """``sock`` may be readable without a new signal: look at it next turn (thread only)."""
        self._watch.again(sock)

    def _add(self, member: ReceiveMember) -> None:
        socks = list(member.sockets())
        self._members[member] = socks  # first: should a socket fail, all are let go
        for sock in socks:
            self._owner[sock] = member
            self._watch.add(sock)
        at = member.next_due()
        if at is not None:
            self._due[member] = at

    def _remove(self, member: ReceiveMember) -> None:
        socks = self._members.pop(member, None)
        self._due.pop(member, None)
        if socks is None:
            return  # already gone (its sockets failed)
        for sock in socks:
            self._owner.pop(sock, None)
            self._watch.discard(sock)
        member.ended()

    def _run(self) -> None:
        watch, ctrl = self._watch, self._ctrl_rx
        watch.add(ctrl)
        try:
            while True:
                ready = watch.wait(self._timeout_s())
                turn_began = time.monotonic()
                if ctrl in ready and not self._take_calls():
                    return
                share: dict[ReceiveMember, list[Socket]] = {}
                for sock in ready:
                    owner = self._owner.get(sock)
                    if owner is not None:
                        share.setdefault(owner, []).append(sock)
                for member, at in list(self._due.items()):
                    if at <= turn_began:
                        share.setdefault(member, [])
                for member, socks in share.items():
                    self._turn(member, socks)
                took = time.monotonic() - turn_began
                if took > STALL_S:
                    for member in list(self._members):
                        member.stalled(took)
        except zmq.ContextTerminated:
            for member in self._members:
                member.log.warning("net.in.context_terminated")
        except zmq.ZMQError as exc:  # the control socket: nothing a member did
            for member in self._members:
                member.log.error("net.in.thread_error", error=str(exc))
        finally:
            with self._lock:
                self._open = False
                unseen = [m for m, _ in self._calls if m not in self._members]
                self._calls.clear()
                self._close_control()
            for member in list(self._members):
                self._remove(member)
            for member in unseen:  # added while the thread ended: never watched
                member.ended()
            watch.close()

    def _timeout_s(self) -> float | None:
        if not self._due:
            return None
        return max(0.0, min(self._due.values()) - time.monotonic())

    def _turn(self, member: ReceiveMember, ready: list[Socket]) -> None:
        if member not in self._members:
            return  # it left in this turn
        try:
            member.turn(ready, self)
        except zmq.ContextTerminated:
            raise
        except zmq.ZMQError:
            self._failed(member)
            return
        at = member.next_due()
        if at is None:
            self._due.pop(member, None)
        else:
            self._due[member] = at

    def _take_calls(self) -> bool:
        """Run the calls queued (those asked before a stop too); False when a stop came."""
        stop = False
        while True:
            try:
                stop = self._ctrl_rx.recv(zmq.NOBLOCK) == CMD_STOP or stop
            except zmq.Again:
                break
        while True:
            with self._lock:
                if not self._calls:
                    return not stop
                member, fn = self._calls.popleft()
            try:
                fn()
            except zmq.ContextTerminated:
                raise
            except Exception:  # a member's request failed: that member leaves
                self._failed(member)

    def _failed(self, member: ReceiveMember) -> None:
        member.log.exception("net.in.thread_error")
        self._remove(member)

    def _close_control(self) -> None:
        self._ctrl_tx.close(linger=0)
        self._ctrl_rx.close(linger=0)
