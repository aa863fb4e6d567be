"""The simulated vehicle's links: every client it serves, and where each message goes.

A real autopilot serves several ground stations at once (a companion computer,
QGroundControl, MAVProxy) and routes MAVLink as the protocol says: a message
addressed to a system (COMMAND_ACK, MISSION_REQUEST_INT, MISSION_ACK...) goes
only to the links that system was heard on; everything else (HEARTBEAT, the
telemetry streams, STATUSTEXT, PARAM_VALUE) goes to every link.  This module
does the same for ``eamos-sim-vehicle``:

* ``tcpin:HOST:PORT`` listens and accepts any number of clients (ArduPilot SITL
  style); a client that leaves is forgotten, a new one may come at any time;
* ``udpin:HOST:PORT`` binds and answers every peer that sends it a datagram;
* ``udpout:HOST:PORT`` sends to that address (PX4 SITL style) and also answers
  any other peer that sends to the vehicle's own port.

Each link parses its own byte stream (its own pymavlink parser, so two clients'
bytes never mix) and has its own signing state; one encoder numbers and signs
what the vehicle sends.  Nothing here blocks: :meth:`Links.receive` drains what
the sockets hold and returns at once, the vehicle's thread calls it every tick.
"""

from __future__ import annotations

import errno
import socket
from collections.abc import Iterator
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

#: Largest datagram read at once, and bytes read from a TCP client per call.
_DATAGRAM = 65535
_TCP_CHUNK = 65536
#: Bytes read from one link per tick at most (a flood must not starve the simulation).
_MAX_BYTES_PER_TICK = 256 * 1024
#: A TCP client that leaves this much unread is gone (its socket is closed).
_MAX_PENDING = 4 * 1024 * 1024


@dataclass(eq=False)
class Link:
    """One client: where its bytes come from, its parser, and the systems heard on it."""

    name: str
    parser: Any  # a pymavlink MAVLink object used only to parse this link's bytes
    sock: socket.socket | None = None  # TCP: the client's socket
    address: tuple[str, int] | None = None  # UDP: the peer's address
    systems: set[tuple[int, int]] = field(default_factory=set)  # (sysid, compid) heard here
    pending: bytearray = field(default_factory=bytearray)  # TCP: bytes the socket took not yet


class Links:
    """The vehicle's sockets and their clients (see module docstring).

    ``mavlink``: pymavlink's generated dialect module (``mavutil.mavlink``).
    :attr:`mav` is the encoder every outgoing message goes through; its
    ``file`` is this object, so :meth:`write` decides where the bytes go.
    """

    def __init__(self, mavlink: ModuleType, connection: str, sysid: int) -> None:
        kind, _, rest = connection.partition(":")
        host, _, port_text = rest.rpartition(":")
        if kind not in ("tcpin", "udpin", "udpout") or not host or not port_text.isdigit():
            raise ValueError(f"connection must be tcpin:, udpin: or udpout:HOST:PORT: {connection}")
        self._mavlink = mavlink
        self._kind = kind
        self._sysid = sysid
        self._links: list[Link] = []
        self._rejected_before = 0  # reject counts of links that are gone
        self._destination: list[Link] | None = None  # set while one message is written
        self._signing: dict[str, Any] | None = None
        self.mav = mavlink.MAVLink(self, srcSystem=sysid, srcComponent=1)
        address = (host, int(port_text))
        if kind == "tcpin":
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._sock.bind(address)
            self._sock.listen(8)
        else:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            if kind == "udpin":
                self._sock.bind(address)
            else:
                self._sock.bind((host, 0))
                self._add(f"udp:{address[0]}:{address[1]}", address=address)
        self._sock.setblocking(False)

    # -- what others read ---------------------------------------------------------------

    @property
    def address(self) -> tuple[str, int]:
        """The vehicle's own socket address (where a client may send to it)."""
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)

    @property
    def clients(self) -> int:
        """How many links there are now (TCP clients connected, UDP peers heard or given)."""
        return len(self._links)

    @property
    def signing(self) -> bool:
        """True once messages are signed and unsigned ones refused."""
        return self._signing is not None

    @property
    def rejected(self) -> int:
        """Messages dropped as unsigned or wrongly signed, on every link so far."""
        return self._rejected_before + sum(
            int(link.parser.signing.reject_count) for link in self._links
        )

    # -- signing ----------------------------------------------------------------------------

    def sign(self, key: bytes, timestamp: int | None, allow_unsigned: Any) -> None:
        """Sign everything sent from now on with ``key`` and refuse unsigned messages on
        every link (but those ``allow_unsigned(mav, msg_id)`` lets through)."""
        self._signing = {"key": key, "allow": allow_unsigned}
        signing = self.mav.signing
        signing.secret_key = key
        signing.sign_outgoing = True
        signing.link_id = 0
        signing.allow_unsigned_callback = allow_unsigned
        if timestamp is not None:
            signing.timestamp = max(int(signing.timestamp), timestamp)
        for link in self._links:
            self._arm_parser(link.parser)

    def _arm_parser(self, parser: Any) -> None:
        if self._signing is not None:
            parser.signing.secret_key = self._signing["key"]
            parser.signing.allow_unsigned_callback = self._signing["allow"]

    # -- receiving -----------------------------------------------------------------------

    def receive(self) -> Iterator[tuple[Link, Any]]:
        """Every message the sockets hold now, with the link it came on (never blocks)."""
        if self._kind == "tcpin":
            self._accept()
            for link in list(self._links):
                yield from self._receive_tcp(link)
        else:
            yield from self._receive_udp()

    def _accept(self) -> None:
        while True:
            try:
                client, address = self._sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            client.setblocking(False)
            self._add(f"tcp:{address[0]}:{address[1]}", sock=client)

    def _receive_tcp(self, link: Link) -> Iterator[tuple[Link, Any]]:
        assert link.sock is not None
        read = 0
        while read < _MAX_BYTES_PER_TICK:
            try:
                data = link.sock.recv(_TCP_CHUNK)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                data = b""
            if not data:
                self._drop(link)  # the client went away
                return
            read += len(data)
            yield from self._parse(link, data)

    def _receive_udp(self) -> Iterator[tuple[Link, Any]]:
        read = 0
        while read < _MAX_BYTES_PER_TICK:
            try:
                data, address = self._sock.recvfrom(_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno == errno.ECONNREFUSED:
                    continue  # an ICMP from a peer not listening (yet): not our problem
                return
            read += len(data)
            peer = (str(address[0]), int(address[1]))
            link = next((x for x in self._links if x.address == peer), None)
            if link is None:
                link = self._add(f"udp:{peer[0]}:{peer[1]}", address=peer)
            yield from self._parse(link, data)

    def _parse(self, link: Link, data: bytes) -> Iterator[tuple[Link, Any]]:
        for msg in link.parser.parse_buffer(data) or ():
            if msg.get_type() != "BAD_DATA":
                link.systems.add((msg.get_srcSystem(), msg.get_srcComponent()))
            yield link, msg

    def _add(
        self, name: str, sock: socket.socket | None = None, address: tuple[str, int] | None = None
    ) -> Link:
        parser = self._mavlink.MAVLink(None, srcSystem=self._sysid, srcComponent=1)
        parser.robust_parsing = True
        self._arm_parser(parser)
        link = Link(name, parser, sock=sock, address=address)
        self._links.append(link)
        return link

    def _drop(self, link: Link) -> None:
        if link in self._links:
            self._links.remove(link)
            self._rejected_before += int(link.parser.signing.reject_count)
        if link.sock is not None:
            try:
                link.sock.close()
            except OSError:
                pass

    # -- sending ----------------------------------------------------------------------------

    def send(self, msg: Any) -> None:
        """Encode, number, sign and send ``msg``: to the links its target was heard on when
        it is addressed to a system seen here, else to every link."""
        target = int(getattr(msg, "target_system", 0) or 0)
        component = int(getattr(msg, "target_component", 0) or 0)
        links = self._links
        if target:
            heard = [
                link
                for link in self._links
                if any(s == target and component in (0, c) for s, c in link.systems)
            ]
            if heard:
                links = heard
        self._destination = links
        try:
            self.mav.send(msg)
        finally:
            self._destination = None

    def write(self, buf: bytes) -> None:
        """pymavlink's ``file.write``: the bytes of one message, to its destination links."""
        for link in list(self._destination if self._destination is not None else self._links):
            if link.sock is not None:
                link.pending += buf
                self._flush(link)
            elif link.address is not None:
                try:
                    self._sock.sendto(buf, link.address)
                except OSError:
                    pass  # nobody listening there (yet): UDP loses it, as a radio would

    def flush(self) -> None:
        """Send what TCP clients' sockets could not take before (each tick)."""
        for link in list(self._links):
            if link.pending:
                self._flush(link)

    def _flush(self, link: Link) -> None:
        assert link.sock is not None
        try:
            sent = link.sock.send(link.pending)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:
            self._drop(link)
            return
        del link.pending[:sent]
        if len(link.pending) > _MAX_PENDING:
            self._drop(link)  # a client that stopped reading: let it go

    def close(self) -> None:
        """Close every client and the vehicle's own socket. Idempotent."""
        for link in list(self._links):
            self._drop(link)
        try:
            self._sock.close()
        except OSError:
            pass


__all__ = ["Link", "Links"]
