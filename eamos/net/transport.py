"""What the link driver needs from the network, and the ZeroMQ bridges that provide it.

:class:`Transport` is the seam between :class:`~eamos.net.link.LinkDriver`
(threads, clock, the protocol session) and the sockets: it opens an outgoing
side (:class:`OutSide`: send, wait for subscribers) and an incoming side
(:class:`InSide`: calls back with each received message and at the end of
each batch).  :class:`ZmqTransport` is the real one: an Out-Bridge, an
In-Bridge and, with fleet keys, the ZAP authenticator.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import zmq

import eamos.net.wire as wire
from eamos.net.descriptors import raise_descriptor_limit
from eamos.net.in_bridge import InBridge
from eamos.net.keys import FleetAuthenticator, FleetKeys
from eamos.net.out_bridge import OutBridge
from eamos.net.receive_host import ReceiveHost
from eamos.net.settings import DEFAULT_HEARTBEAT_MS
from eamos.net.zap import ZapHandler

if TYPE_CHECKING:
    from eamos.logs import EventLog

__all__ = ["InSide", "OutSide", "Transport", "ZmqTransport"]


class OutSide(Protocol):
    """The outgoing side: thread-safe, non-blocking, order-preserving ``send``."""

    def start(self) -> None: ...
    def send(self, msg: wire.Message) -> bool: ...
    def wait_subscribed(self, topics: Iterable[bytes], timeout_s: float) -> bool: ...
    def close(self) -> None: ...

    @property
    def sent_counts(self) -> dict[str, int]: ...
    @property
    def sent_bytes(self) -> int: ...
    @property
    def sent_bytes_by_type(self) -> dict[str, int]: ...
    @property
    def auth_failures(self) -> int: ...


class InSide(Protocol):
    """The incoming side: delivers on its own thread once started."""

    def start(self) -> None: ...
    def close(self) -> None: ...
    def announce(self, peer: str) -> None: ...

    @property
    def dropped_by_reason(self) -> dict[str, int]: ...
    @property
    def auth_failures(self) -> int: ...


OutT_co = TypeVar("OutT_co", bound=OutSide, covariant=True)
InT_co = TypeVar("InT_co", bound=InSide, covariant=True)


class Transport(Protocol[OutT_co, InT_co]):
    """Opens the two sides of one participant's network (each returned unstarted)."""

    @property
    def secure(self) -> bool:
        """Whether the sides are encrypted and authenticated."""
        ...

    @property
    def auth_denied(self) -> int:
        """Peers refused for their keys."""
        ...

    def open_out(self, on_subscription: Callable[[bytes, bool], None]) -> OutT_co:
        """The outgoing side; ``on_subscription(topic, on)`` when a peer (un)subscribes."""
        ...

    def open_in(
        self,
        peers: Mapping[str, str],
        topics: Iterable[bytes],
        on_message: Callable[[wire.Message], None],
        on_batch_end: Callable[[], None],
        announced: Iterable[str] = (),
        on_stall: Callable[[float], None] | None = None,
    ) -> InT_co:
        """The incoming side, connected to ``peers`` (name -> endpoint), on ``topics``;
        those in ``announced`` once they announce themselves (:meth:`InSide.announce`);
        ``on_stall`` told how long a turn of the receive loop took when it took long."""
        ...

    def close(self) -> None:
        """Release what the transport holds besides the two sides."""
        ...


class ZmqTransport:
    """ZeroMQ: an Out-Bridge bound at ``bind``, an In-Bridge to the peers, CURVE with ``keys``.

    With ``keys`` the ZAP authenticator starts before the Out-Bridge binds: no
    handshake may happen unauthenticated.  Incoming messages must come from the
    peer of the socket they arrive on (``check_sender``).
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        bind: str,
        mission: str,
        log: EventLog,
        *,
        keys: FleetKeys | None = None,
        heartbeat_ms: int = DEFAULT_HEARTBEAT_MS,
        zap: ZapHandler | None = None,
        receivers: ReceiveHost | None = None,
    ) -> None:
        self.context = context
        self.zap = zap  # the context's shared ZAP handler (None: one of its own)
        # The process's receive thread (None: the In-Bridge has one of its own).
        self.receivers = receivers
        self.bind = bind
        self.mission = mission
        self.log = log
        self.keys = keys
        self.heartbeat_ms = heartbeat_ms
        self.auth: FleetAuthenticator | None = None

    @property
    def secure(self) -> bool:
        """Whether the links are CURVE-encrypted and authenticated."""
        return self.keys is not None

    @property
    def auth_denied(self) -> int:
        """Clients the ZAP authenticator refused."""
        return self.auth.denied if self.auth is not None else 0

    def open_out(self, on_subscription: Callable[[bytes, bool], None]) -> OutBridge:
        """Start the authenticator (with keys), then bind the Out-Bridge (not started)."""
        # Before any connection is accepted: idle clients must not exhaust the limit.
        raise_descriptor_limit(self.log)
        if self.keys is not None:
            self.auth = FleetAuthenticator(self.context, self.keys, self.log, zap=self.zap)
        try:
            return OutBridge(
                self.context,
                self.bind,
                self.log,
                curve=self.keys,
                heartbeat_ms=self.heartbeat_ms,
                on_subscription=on_subscription,
            )
        except BaseException:
            self.close()
            raise

    def open_in(
        self,
        peers: Mapping[str, str],
        topics: Iterable[bytes],
        on_message: Callable[[wire.Message], None],
        on_batch_end: Callable[[], None],
        announced: Iterable[str] = (),
        on_stall: Callable[[float], None] | None = None,
    ) -> InBridge:
        """Connect an In-Bridge (not started) to ``peers`` and subscribe it to ``topics``
        (``announced``: see :class:`InBridge`)."""
        return InBridge(
            self.context,
            peers,
            topics,
            on_message,
            self.mission,
            self.log,
            curve=self.keys,
            check_sender=True,
            heartbeat_ms=self.heartbeat_ms,
            on_batch_end=on_batch_end,
            announced=announced,
            on_stall=on_stall,
            host=self.receivers,
        )

    def close(self) -> None:
        """Stop the authenticator; idempotent."""
        if self.auth is not None:
            self.auth.stop()
