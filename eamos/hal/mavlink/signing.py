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
until the first correctly signed one arrives.  The key itself is never logged.
:class:`LinkSigning` applies these rules to the adapter's link.
"""

from __future__ import annotations

import base64
import binascii
import os
import stat
import time
from pathlib import Path
from typing import Any

#: RADIO_STATUS: the only message accepted unsigned.
MSG_RADIO_STATUS = 109
#: The signing timestamp counts 10 microsecond units since 2015-01-01 00:00 UTC.
SIGNING_EPOCH_S = 1_420_070_400
#: File name of the fleet's signing key, beside the CURVE keys.
SIGNING_KEY_FILE = "mavlink_signing.key"
KEY_BYTES = 32


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

    def setup_fields(self, wall_s: float) -> tuple[list[int], int]:
        """SETUP_SIGNING's ``secret_key`` and ``initial_timestamp`` at wall-clock ``wall_s``."""
        return list(self._key), signing_timestamp(wall_s)


__all__ = [
    "MSG_RADIO_STATUS",
    "SIGNING_KEY_FILE",
    "LinkSigning",
    "SigningKeyError",
    "create_signing_key",
    "parse_key",
    "radio_status_only",
    "read_key",
    "refresh_timestamp",
    "signing_timestamp",
]
