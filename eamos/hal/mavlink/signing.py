"""MAVLink 2 message signing: the fleet's key, its file, and the rules both ends apply.

A fleet shares one 32-byte secret (``eamos keys`` writes it beside the CURVE
keys, as ``mavlink_signing.key``: 64 hex digits, file mode 0600).  Both the
adapter (``hal.signing_key = "<path>"``) and ``eamos-sim-vehicle``
(``--signing-key``) then:

* sign every message they send (pymavlink's ``setup_signing``);
* refuse every incoming message that is unsigned or wrongly signed, except
  RADIO_STATUS (a radio's own status, which cannot be signed): pymavlink
  turns those into BAD_DATA, which both ends drop;
* refresh their outgoing signing timestamp from the clock at least once a
  second (:func:`refresh_timestamp`): pymavlink only increments it per
  message, and a receiver rejects a new stream whose timestamp lags its own
  by more than a minute.

Provisioning (``hal.signing_setup = true``): the adapter sends SETUP_SIGNING
with the key to the vehicle, and accepts the vehicle's unsigned messages only
until the first correctly signed one arrives; a vehicle that still sends
unsigned ones ``hal.signing_timeout_s`` after connecting is refused (the run
stops with that reason).  The key itself is never logged.

Signing never downgrades silently: with a key, a vehicle whose HEARTBEATs come
unsigned is refused ("signing required, the vehicle sends unsigned messages"),
and one whose HEARTBEATs are signed with another key is refused too
(:func:`refused_frame` reads who sent a refused frame).  An autopilot without
MAVLink signing (PX4 main: it never answers SETUP_SIGNING and keeps sending
unsigned) flies only when its drone says ``hal.signing = "off"``; the run's
summary records, per drone, whether its link was signed.

Where ArduPilot enforces signing: once it has a key it signs everything it sends
on every channel, and its ``accept_unsigned_callback``
(``libraries/GCS_MAVLink/GCS_Signing.cpp``) lets unsigned or wrongly signed
messages through on its first MAVLink channel, ``MAVLINK_COMM_0`` ("assumed to be
secure channel ... USB": SERIAL0, the SITL's TCP 5760+10N, a flight controller's
USB port), and only RADIO_STATUS and RADIO on the others.  Fly signed links through
SERIAL1 or a later port (the SITL's TCP 5762+10N, a telemetry radio).

:class:`LinkSigning` applies these rules to the adapter's link.
"""

from __future__ import annotations

import base64
import binascii
import os
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from eamos.hal.api import AdapterError

if TYPE_CHECKING:
    from eamos.hal.mavlink.state import LinkState
    from eamos.logs import EventLog

#: RADIO_STATUS: the only message accepted unsigned.
MSG_RADIO_STATUS = 109
#: The signing timestamp counts 10 microsecond units since 2015-01-01 00:00 UTC.
SIGNING_EPOCH_S = 1_420_070_400
#: File name of the fleet's signing key, beside the CURVE keys.
SIGNING_KEY_FILE = "mavlink_signing.key"
KEY_BYTES = 32
#: HEARTBEAT's message id, and MAV_TYPE_GCS / MAV_AUTOPILOT_INVALID (not a vehicle).
MSG_HEARTBEAT = 0
_MAV_TYPE_GCS = 6
_MAV_AUTOPILOT_INVALID = 8
_MAV_AUTOPILOT_PX4 = 12
#: MAVLink 2's "signed" incompatibility flag.
_MAVLINK_IFLAG_SIGNED = 0x01


class SigningKeyError(ValueError):
    """A signing key file that cannot be used (its path and why)."""


def signing_timestamp(wall_s: float) -> int:
    """The MAVLink signing timestamp of wall-clock time ``wall_s`` (``time.time()``)."""
    return int(max(0.0, wall_s - SIGNING_EPOCH_S) * 100_000)


def refresh_timestamp(mav: Any, wall_s: float | None = None) -> None:
    """Move ``mav.signing.timestamp`` up to the clock (never backwards)."""
    now = signing_timestamp(time.time() if wall_s is None else wall_s)
    mav.signing.timestamp = max(mav.signing.timestamp, now)


def radio_status_only(mav: Any, msg_id: int) -> bool:
    """pymavlink's ``allow_unsigned_callback``: only RADIO_STATUS passes unsigned."""
    return msg_id == MSG_RADIO_STATUS


@dataclass(frozen=True)
class RefusedFrame:
    """A frame the link refused for its signature: who sent it, and whether signed at all."""

    signed: bool  # signed, but not with our key (or replayed); False: unsigned
    system_id: int
    component_id: int
    msg_id: int
    #: For a HEARTBEAT: MAV_TYPE and MAV_AUTOPILOT (None for other messages).
    vehicle_type: int | None = None
    autopilot: int | None = None

    @property
    def vehicle_heartbeat(self) -> bool:
        """A HEARTBEAT from an autopilot (not from a ground station on a shared port)."""
        return (
            self.msg_id == MSG_HEARTBEAT
            and self.vehicle_type != _MAV_TYPE_GCS
            and self.autopilot != _MAV_AUTOPILOT_INVALID
        )


def refused_frame(data: bytes) -> RefusedFrame | None:
    """Who sent a raw MAVLink frame (pymavlink's BAD_DATA "Invalid signature"); None when
    it is not a whole frame.  Pure: reads the header (and a HEARTBEAT's payload), trusts
    nothing else in it."""
    if len(data) >= 10 and data[0] == 0xFD:  # MAVLink 2
        signed = bool(data[2] & _MAVLINK_IFLAG_SIGNED)
        system, component = data[5], data[6]
        msg_id = data[7] | data[8] << 8 | data[9] << 16
        payload = bytes(data[10 : 10 + data[1]])
    elif len(data) >= 6 and data[0] == 0xFE:  # MAVLink 1: never signed
        signed, system, component, msg_id = False, data[3], data[4], data[5]
        payload = bytes(data[6 : 6 + data[1]])
    else:
        return None
    if msg_id != MSG_HEARTBEAT:
        return RefusedFrame(signed, system, component, msg_id)
    payload = payload.ljust(9, b"\x00")  # MAVLink 2 trims trailing zero bytes
    return RefusedFrame(signed, system, component, msg_id, payload[4], payload[5])


def parse_key(text: str) -> bytes:
    """32 bytes from 64 hex digits or 44 base64 characters; ValueError otherwise."""
    text = text.strip()
    try:
        if len(text) == 2 * KEY_BYTES:
            key = bytes.fromhex(text)
        else:
            key = base64.b64decode(text, validate=True)
    except (ValueError, binascii.Error):
        key = b""
    if len(key) != KEY_BYTES:
        raise ValueError(f"expected {KEY_BYTES} bytes as 64 hex digits or base64")
    return key


def read_key(path: Path) -> bytes:
    """The key in ``path``; :class:`SigningKeyError` if missing, readable by others, or bad."""
    try:
        mode = path.stat().st_mode
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise SigningKeyError(f"{path}: cannot read the signing key ({exc})") from None
    if mode & (stat.S_IRWXG | stat.S_IRWXO):
        raise SigningKeyError(
            f"{path}: readable by others (mode {stat.S_IMODE(mode):o}); chmod 600 it"
        )
    try:
        return parse_key(text)
    except ValueError as exc:
        raise SigningKeyError(f"{path}: {exc}") from None


def create_signing_key(out: Path, force: bool = False) -> Path:
    """Write a new random fleet key to ``out/mavlink_signing.key`` (mode 0600); its path.

    An existing key is kept unless ``force`` (FileExistsError otherwise).
    """
    out.mkdir(parents=True, exist_ok=True)
    path = out / SIGNING_KEY_FILE
    if path.exists() and not force:
        raise FileExistsError(f"{path} exists (use --force to replace it)")
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="ascii") as file:
        file.write(os.urandom(KEY_BYTES).hex() + "\n")
    path.chmod(0o600)  # also when it existed with a looser mode
    return path


#: Refused (unsigned or wrongly signed) vehicle HEARTBEATs that end the wait to connect.
REFUSED_HEARTBEATS = 2
#: What a PX4 vehicle's refusal adds: PX4 main has no MAVLink signing.
NO_SIGNING_HINT = (
    " (PX4 has no MAVLink signing: it ignores SETUP_SIGNING; give this drone "
    'hal.signing = "off" to fly it unsigned)'
)


def refused_reason(st: LinkState, connection: str) -> str:
    """Why a vehicle whose HEARTBEATs were all refused for their signature is refused."""
    hint = NO_SIGNING_HINT if st.refused_autopilot == _MAV_AUTOPILOT_PX4 else ""
    if st.refused_signed:
        return (
            f"the vehicle on {connection} signs its messages with another key than "
            f"hal.signing_key (or a timestamp more than a minute old){hint}"
        )
    return (
        f"signing required, the vehicle sends unsigned messages (on {connection}; "
        f"hal.signing_key is set{'' if hint else ': provision it with hal.signing_setup = true'})"
        f"{hint}"
    )


class SigningLink(Protocol):
    """What :func:`await_signing` needs of the link (a :class:`.link.MavlinkLink`)."""

    cond: Any
    state: LinkState

    @property
    def signing(self) -> bool: ...

    def provisioning(self) -> bool: ...

    def wait_for(self, predicate: Callable[[], bool], deadline: float) -> bool: ...

    def close(self) -> None: ...


def await_signing(
    link: SigningLink, timeout_s: float, speedup: float, drone: str, log: EventLog
) -> None:
    """Provisioning (``hal.signing_setup``): the vehicle signs within ``timeout_s`` of its
    own seconds (``speedup`` times faster than the wall clock), or it is refused:
    :class:`~eamos.hal.api.AdapterError` (the link closed); never flown unsigned."""
    if not link.provisioning():
        log.info("adapter.signing", signed=link.signing, setup=False)
        return
    deadline = time.monotonic() + timeout_s / speedup
    if not link.wait_for(lambda: not link.provisioning(), deadline):
        with link.cond:
            autopilot = link.state.autopilot
        link.close()
        hint = NO_SIGNING_HINT if autopilot == _MAV_AUTOPILOT_PX4 else ""
        raise AdapterError(
            f"{drone}: signing setup failed: the vehicle still sends unsigned "
            f"messages {timeout_s:g} s after SETUP_SIGNING{hint}"
        )
    log.info("adapter.signing", signed=True, setup=True)


class LinkSigning:
    """The signing rules on one link: sign what goes out, refuse what comes in unsigned,
    keep the outgoing timestamp up with the clock, provision a vehicle without the key.

    ``setup`` (``hal.signing_setup``): the vehicle's unsigned messages are accepted, and
    SETUP_SIGNING is sent to it, until its first correctly signed message arrives.
    """

    def __init__(self, key: bytes, setup: bool) -> None:
        self._key = key
        self.setup = setup

    def install(self, conn: Any) -> None:
        """Turn signing on for a pymavlink connection ``conn``."""
        conn.setup_signing(self._key, sign_outgoing=True, allow_unsigned_callback=self._unsigned)

    def _unsigned(self, mav: Any, msg_id: int) -> bool:
        # Provisioning: the vehicle signs only once it has the key.
        return self.provisioning(mav) or radio_status_only(mav, msg_id)

    def provisioning(self, mav: Any) -> bool:
        """Whether the vehicle still needs the key (no correctly signed message from it yet)."""
        return self.setup and mav.signing.goodsig_count == 0

    def refresh(self, mav: Any) -> bool:
        """Move the outgoing timestamp up to the clock (under the link's send lock);
        whether the vehicle still needs the key."""
        refresh_timestamp(mav)
        return self.provisioning(mav)

    @staticmethod
    def signed(mav: Any) -> bool:
        """Whether correctly signed messages have arrived (the vehicle signs)."""
        return bool(mav.signing.goodsig_count > 0)

    def setup_fields(self, wall_s: float) -> tuple[list[int], int]:
        """SETUP_SIGNING's ``secret_key`` and ``initial_timestamp`` at wall-clock ``wall_s``."""
        return list(self._key), signing_timestamp(wall_s)


__all__ = [
    "MSG_HEARTBEAT",
    "MSG_RADIO_STATUS",
    "NO_SIGNING_HINT",
    "REFUSED_HEARTBEATS",
    "SIGNING_KEY_FILE",
    "LinkSigning",
    "RefusedFrame",
    "SigningKeyError",
    "SigningLink",
    "await_signing",
    "create_signing_key",
    "parse_key",
    "radio_status_only",
    "read_key",
    "refresh_timestamp",
    "refused_frame",
    "refused_reason",
    "signing_timestamp",
]
