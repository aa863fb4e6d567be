"""Fleet keys and the rules for who may connect: CURVE key pairs, ZAP, plain-on-loopback.

Every participant of a mission (each drone and the ground station) has one
CURVE key pair.  ``eamos keys`` (:func:`create_fleet_keys`) writes them in
ZeroMQ's certificate format (:func:`zmq.auth.create_certificates`)::

    OUT/public/<name>.key             every participant's public certificate
    OUT/<name>/<name>.key_secret      <name>'s own key pair (file mode 0600)
    OUT/<name>/public/<peer>.key      a copy of every public certificate

``OUT/<name>/`` is the folder shipped with participant ``<name>``'s program;
its config says ``[net] keys = "<that folder>"``.  :meth:`FleetKeys.load`
reads it back.

How the keys are used (see :mod:`eamos.net.bridges`): every Out-Bridge (XPUB)
is a CURVE *server* with its participant's key pair, and a ZAP handler
(:class:`FleetAuthenticator`, pyzmq's ZAP authenticator: :mod:`eamos.net.zap`)
lets in only clients whose public key is one of the fleet's.  Every In-Bridge
socket is a CURVE *client* with its own key pair and the public key of the
one peer it connects to, so it only accepts that peer: an impostor at the
peer's address fails the handshake.  Traffic is encrypted and authenticated
both ways; nothing without the fleet's keys gets in.

Plain (unauthenticated, unencrypted) sockets are for development only:
:func:`plain_refusal` allows them when every endpoint is local (loopback
``127.0.0.0/8``, ``::1``, ``localhost``, ``ipc://``, ``inproc://``).
"""

from __future__ import annotations

import ipaddress
import os
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import zmq
import zmq.auth

from eamos.logs import make_logger
from eamos.net.zap import ZapHandler, participant_domain

__all__ = [
    "FleetAuthenticator",
    "FleetKeys",
    "KeysError",
    "create_fleet_keys",
    "is_local_endpoint",
    "participants_of_compiled",
    "plain_refusal",
]


PUBLIC_DIR: Final = "public"
SECRET_SUFFIX: Final = ".key_secret"
PUBLIC_SUFFIX: Final = ".key"

# Denials are logged one by one up to this count per key, then every
# _LOG_EVERY-th: an intruder retrying every 100 ms must not fill the disk.
_LOG_FIRST: Final = 20
_LOG_EVERY: Final = 1000


class KeysError(ValueError):
    """A key folder is missing, incomplete or inconsistent."""


def _check_name(name: str) -> str:
    if not name or "/" in name or name.startswith(".") or name == PUBLIC_DIR:
        raise KeysError(f"{name!r} is not a usable participant name for a key file")
    return name


def create_fleet_keys(
    out_dir: Path, names: Iterable[str], *, force: bool = False, shipped: bool = True
) -> Path:
    """Write a fresh CURVE key pair per participant under ``out_dir``; return ``out_dir``.

    Refuses (``KeysError``) to overwrite existing keys unless ``force``: a new
    key set must be shipped to every drone, which is worth a deliberate choice.
    ``shipped``: give each participant's folder its copy of every public key (the
    folder shipped to it); a local run, whose participants all read ``out_dir``
    itself (:meth:`FleetKeys.load`), has no use for the N² copies.
    """
    out_dir = Path(out_dir)
    wanted = sorted({_check_name(str(n)) for n in names})
    if not wanted:
        raise KeysError("no participants to make keys for")
    existing = [n for n in wanted if (out_dir / n).exists()]
    if (out_dir / PUBLIC_DIR).exists():
        existing.append(PUBLIC_DIR)
    if existing and not force:
        raise KeysError(
            f"{out_dir}: keys already exist ({', '.join(existing)}); "
            "use --force to replace them (then ship the new folders to every drone)"
        )
    # Here, not at the top: a drone's node loads this module at start and never makes keys.
    import shutil

    public = out_dir / PUBLIC_DIR
    for path in [public, *(out_dir / n for n in wanted)]:
        if path.exists():
            shutil.rmtree(path)
    public.mkdir(parents=True)
    for name in wanted:
        own = out_dir / name
        own.mkdir()
        os.chmod(own, 0o700)
        pub_file, secret_file = zmq.auth.create_certificates(
            own, name, metadata={"participant": name}
        )
        os.chmod(secret_file, 0o600)
        # The participant's folder keeps only its secret certificate (which holds
        # the public key too); the public one goes to the fleet directory.
        Path(pub_file).replace(public / f"{name}{PUBLIC_SUFFIX}")
    if shipped:
        for name in wanted:
            shutil.copytree(public, out_dir / name / PUBLIC_DIR)
    return out_dir


def participants_of_compiled(mission_dir: Path) -> list[str]:
    """Participant names of a compiled mission folder (its ``programs/*.program.json``)."""
    programs = sorted((Path(mission_dir) / "programs").glob("*.program.json"))
    if not programs:
        raise KeysError(
            f"{mission_dir}: no programs/*.program.json (compile the mission first, "
            "or name the participants with --fleet)"
        )
    return [p.name.removesuffix(".program.json") for p in programs]


@dataclass(frozen=True)
class FleetKeys:
    """One participant's key pair and the fleet's public keys (raw z85 bytes)."""

    me: str
    public: bytes
    secret: bytes = field(repr=False)
    fleet: Mapping[str, bytes]

    @classmethod
    def load(cls, folder: Path, me: str) -> FleetKeys:
        """Read ``folder/<me>.key_secret`` and ``folder/public/*.key``.

        ``folder`` is the participant's own folder (``OUT/<me>``, what should be
        shipped to it) or the whole folder ``eamos keys`` wrote (``OUT``, which
        holds every participant's secret key: fine on the ground station).
        """
        folder = Path(folder)
        secret_file = folder / f"{me}{SECRET_SUFFIX}"
        if not folder.is_dir():
            raise KeysError(f"{folder}: no such key folder (make one with `eamos keys`)")
        if not secret_file.is_file() and (folder / me / secret_file.name).is_file():
            secret_file = folder / me / secret_file.name
        if not secret_file.is_file():
            raise KeysError(f"{folder}: no {secret_file.name} (this folder is not {me}'s keys)")
        try:
            public, secret = zmq.auth.load_certificate(secret_file)
        except (OSError, ValueError) as exc:
            raise KeysError(f"{secret_file}: not a ZeroMQ certificate: {exc}") from exc
        if not secret:
            raise KeysError(f"{secret_file}: holds no secret key")
        fleet: dict[str, bytes] = {}
        for cert in sorted((folder / PUBLIC_DIR).glob(f"*{PUBLIC_SUFFIX}")):
            try:
                key, _ = zmq.auth.load_certificate(cert)
            except (OSError, ValueError) as exc:
                raise KeysError(f"{cert}: not a ZeroMQ certificate: {exc}") from exc
            fleet[cert.name.removesuffix(PUBLIC_SUFFIX)] = key
        if fleet.get(me) != public:
            raise KeysError(
                f"{folder / PUBLIC_DIR}: {me}{PUBLIC_SUFFIX} is missing or does not match "
                f"{secret_file.name} (keys from two different `eamos keys` runs?)"
            )
        for key in (public, secret, *fleet.values()):
            if len(key) != 40:
                raise KeysError(f"{folder}: a key is not 40 z85 characters")
        return cls(me, public, secret, fleet)

    def missing(self, names: Iterable[str]) -> list[str]:
        """Which of ``names`` have no public key in this fleet."""
        return sorted(n for n in names if n not in self.fleet)


def is_local_endpoint(endpoint: str) -> bool:
    """Whether ``endpoint`` never leaves this machine (loopback TCP, ipc, inproc)."""
    scheme, sep, rest = endpoint.partition("://")
    if not sep:
        return False
    if scheme in ("inproc", "ipc"):
        return True
    if scheme != "tcp":
        return False
    # tcp://host:port, tcp://[::1]:port; a bind may also name a source (src;dst).
    host = rest.rsplit(";", 1)[-1].rsplit(":", 1)[0].strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False  # "*", interface names and host names may reach the network


def plain_refusal(endpoints: Iterable[str]) -> str | None:
    """Why plain sockets are refused for ``endpoints`` (None when all are local)."""
    remote = sorted({e for e in endpoints if not is_local_endpoint(e)})
    if not remote:
        return None
    return (
        "plain (unauthenticated) sockets are only allowed on loopback, and "
        f"{', '.join(remote)} is not; use fleet keys (`eamos keys`)"
    )


class _FleetCredentials:
    """pyzmq's credentials provider: admits the fleet's keys, logs (rate-limited) the others."""

    def __init__(self, keys: FleetKeys, log: Any) -> None:
        self._allowed = frozenset(keys.fleet.values())
        self._log = log
        self._lock = threading.Lock()
        self.denied: dict[bytes, int] = {}

    def callback(self, domain: str, key: bytes) -> bool:
        # ``key`` arrives z85-encoded (bytes), like the certificates.
        if key in self._allowed:
            return True
        with self._lock:
            count = self.denied[key] = self.denied.get(key, 0) + 1
        if count <= _LOG_FIRST or count % _LOG_EVERY == 0:
            self._log.warning(
                "net.auth.denied",
                reason="unknown_key",
                key=key.decode("ascii", "replace"),
                domain=domain,
                attempts=count,
            )
        return False


class FleetAuthenticator:
    """One participant's ZAP answers: only the fleet's keys join its Out-Bridge.

    ZAP handlers are per context (they bind ``inproc://zeromq.zap.01``).  Given
    the context's shared :class:`~eamos.net.zap.ZapHandler` (``zap``: several
    participants in one process, one context), it answers in the participant's
    own domain there; without one it starts a handler of its own, and a second
    such on the same context raises :class:`KeysError`.  Start it before binding
    any CURVE server socket (the sockets also set ``ZAP_ENFORCE_DOMAIN`` so a
    missing handler refuses everyone instead of admitting everyone).
    """

    def __init__(
        self,
        context: zmq.Context[Any],
        keys: FleetKeys,
        log: Any = None,
        *,
        zap: ZapHandler | None = None,
    ) -> None:
        self._log = log if log is not None else make_logger(None)
        self.credentials = _FleetCredentials(keys, self._log)
        self._own = zap is None
        self._zap = zap if zap is not None else ZapHandler(context)
        # The domain must be the one the participant's sockets name (ZAP_ENFORCE_DOMAIN).
        try:
            self._zap.admit(participant_domain(keys.me), self.credentials)
        except zmq.ZMQError as exc:
            raise KeysError(
                f"cannot start the ZAP authenticator ({exc}); one CURVE participant per "
                "ZeroMQ context, or participants sharing a ZapHandler"
            ) from exc
        self._stopped = False

    @property
    def denied(self) -> int:
        """Connection attempts refused (unknown keys)."""
        with self.credentials._lock:
            return sum(self.credentials.denied.values())

    def stop(self) -> None:
        """Stop its own authenticator (a shared one is its owner's to stop); idempotent."""
        if not self._stopped:
            self._stopped = True
            if self._own:
                self._zap.stop()
