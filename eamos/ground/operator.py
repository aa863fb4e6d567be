"""The operator's desk: commands to a running ground station from another process.

``eamos pause RUN_DIR``, ``eamos resume RUN_DIR`` and ``eamos drone RUN_DIR NAME
COMMAND`` reach the ground station that runs the mission of ``RUN_DIR`` (``eamos run``
or ``eamos start``) through a Unix socket in the run folder, :data:`SOCKET_NAME`,
which only its owner may use (mode 0600, like the run's keys).  One request per
connection: one JSON line ``{"command", "drone", "origin"}``; one JSON line back,
``{"ok": true}`` or ``{"ok": false, "error": "..."}``.  The ground station checks it
(:func:`~.station.command_refusal`), broadcasts it to the fleet and logs it with its
origin (:func:`command`).

A run folder whose path is too long for a Unix socket (over about 100 bytes) has no
desk: the ground station says so once, and ``eamos pause`` names the reason.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from eamos.net import wire
from eamos.program.uniform import GROUND_STATION

from .station import command_refusal

if TYPE_CHECKING:
    from .station import GroundStation

__all__ = [
    "SOCKET_NAME",
    "CommandRefused",
    "NoGroundStation",
    "OperatorDesk",
    "OperatorError",
    "PauseClock",
    "command",
    "desk_handler",
    "send_command",
    "snapshot",
]

#: The desk's socket, in the run folder.
SOCKET_NAME = "operator.sock"
#: The longest request read (a command is some 80 bytes).
MAX_REQUEST_BYTES = 4096
#: How long one client may take to send its request.
REQUEST_TIMEOUT_S = 5.0
#: The longest socket path Linux binds (sun_path is 108 bytes, NUL included).
MAX_SOCKET_PATH = 107

Handler = Callable[[str, str, str], str]


def command(station: GroundStation, command: str, drone: str, origin: str) -> str:
    """The operator's ``command`` for ``drone`` ("" for the mission), from ``origin``:
    checked, kept for the summary, broadcast to the fleet (:class:`~eamos.net.wire.Operator`)
    and logged in the ground station's mission log.  Why it was refused ("" when sent)."""
    why = command_refusal(command, drone, station.drones())
    why = why or station.take_command(command, drone, origin)
    runtime = station.runtime
    if why or runtime is None:
        return why or "the ground station is not running"
    msg = wire.Operator(
        mission=station.mission_id,
        sender=GROUND_STATION,
        command=command,  # type: ignore[arg-type]  # checked by command_refusal
        target=drone,
        origin=origin,
    )
    runtime.send(msg)
    if not drone:  # the ground station's own waits (PauseFor) pause and resume too
        runtime.operate(msg)
    else:
        runtime.log.warning("mission.operator", command=command, target=drone, origin=origin)
    return ""


def snapshot(station: GroundStation, run_dir: Path, why: str) -> None:
    """Write the mission's state now into ``run_dir/snapshot.json`` (:mod:`.snapshot`)."""
    from .snapshot import write_snapshot

    write_snapshot(
        run_dir, station.snapshot(), why, station.mission_id, station.paused, station.started
    )


class PauseClock:
    """How long the operator has kept the mission paused (pure: times are given)."""

    def __init__(self) -> None:
        self.total_s = 0.0
        self.since: float | None = None

    def pause(self, now: float) -> None:
        if self.since is None:
            self.since = now

    def resume(self, now: float) -> None:
        if self.since is not None:
            self.total_s += now - self.since
            self.since = None

    def paused_s(self, now: float) -> float:
        """Seconds paused so far (the running pause included)."""
        return self.total_s + (now - self.since if self.since is not None else 0.0)


def desk_handler(
    station: GroundStation,
    run_dir: Path,
    pauses: PauseClock | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> Handler:
    """The desk's handler for ``station``: :func:`command`; a pause also writes the
    mission's state (``snapshot.json``) once it is sent, and ``pauses`` counts it.
    Two requests are the desk's own: ``snapshot`` writes the mission's state now (an
    amendment is judged against it), ``amend`` with the amendment's number in ``drone``
    applies ``RUN_DIR/amendments/N/`` (:class:`~.amend.AmendmentApplier`)."""
    from .amend import AmendmentApplier

    applier = AmendmentApplier(station, run_dir)

    def handle(what: str, drone: str, origin: str) -> str:
        if what == "snapshot":
            snapshot(station, run_dir, f"asked by {origin or 'the operator'}")
            return ""
        if what == "amend":
            return applier.apply(drone, origin)
        why = command(station, what, drone, origin)
        if not why and what == "pause":
            snapshot(station, run_dir, "pause")
            if pauses is not None:
                pauses.pause(clock())
        elif not why and what == "resume" and not drone and pauses is not None:
            pauses.resume(clock())
        return why

    return handle


class OperatorError(ConnectionError):
    """The ground station of a run folder cannot be reached, or refused the command."""


class NoGroundStation(OperatorError):
    """No ground station runs the mission of the run folder (no one listens on its desk)."""


class CommandRefused(OperatorError):
    """The ground station refused the command; ``reason`` is why, as it said it."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"refused by the ground station: {reason}")
        self.reason = reason


class OperatorDesk:
    """Listens on ``run_dir/operator.sock`` and hands each command to ``handle(command,
    drone, origin)``, which returns why it was refused ("" when sent)."""

    def __init__(self, run_dir: Path, handle: Handler) -> None:
        self.path = Path(run_dir) / SOCKET_NAME
        self.handle = handle
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None

    def open(self) -> str:
        """Start listening; "" when listening, else why not (the run flies on without)."""
        if len(os.fsencode(self.path)) > MAX_SOCKET_PATH:
            return f"{self.path}: the run folder's path is too long for the operator's socket"
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()  # a socket left by a ground station that died
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            old = os.umask(0o177)  # created 0600: only its owner may command the fleet
            try:
                sock.bind(str(self.path))
            finally:
                os.umask(old)
            sock.listen(8)
        except OSError as exc:
            sock.close()
            return f"{self.path}: {exc.strerror or exc}"
        self._sock = sock
        self._thread = threading.Thread(target=self._serve, name="operator-desk", daemon=True)
        self._thread.start()
        return ""

    def close(self) -> None:
        """Stop listening and remove the socket; idempotent."""
        sock, self._sock = self._sock, None
        if sock is None:
            return
        with contextlib.suppress(OSError):
            sock.shutdown(socket.SHUT_RDWR)  # wakes the accept below
        sock.close()
        if self._thread is not None:
            self._thread.join(timeout=10)
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()

    def _serve(self) -> None:
        while True:
            sock = self._sock
            if sock is None:
                return
            try:
                conn, _ = sock.accept()
            except OSError:
                return  # closed
            with conn:
                try:
                    self._one(conn)
                except Exception as exc:  # one bad client must not end the desk
                    with contextlib.suppress(OSError):
                        conn.sendall(_reply(f"internal error: {exc!r}"))

    def _one(self, conn: socket.socket) -> None:
        conn.settimeout(REQUEST_TIMEOUT_S)
        data = b""
        try:
            while b"\n" not in data and len(data) <= MAX_REQUEST_BYTES:
                chunk = conn.recv(MAX_REQUEST_BYTES)
                if not chunk:
                    break
                data += chunk
        except OSError:
            return
        request, why = parse_request(data)
        if request is not None:
            why = self.handle(*request)
        conn.sendall(_reply(why))


def parse_request(data: bytes) -> tuple[tuple[str, str, str] | None, str]:
    """``(command, drone, origin)`` of one request line, or None and why it is not one."""
    if len(data) > MAX_REQUEST_BYTES:
        return None, f"request over {MAX_REQUEST_BYTES} bytes"
    try:
        body: Any = json.loads(data.split(b"\n", 1)[0])
    except (ValueError, RecursionError):
        return None, "the request is not a JSON line"
    if not isinstance(body, dict):
        return None, "the request is not a JSON object"
    values = [body.get(key, "") for key in ("command", "drone", "origin")]
    if not all(isinstance(v, str) and len(v) <= 200 for v in values):
        return None, "command, drone and origin must be short strings"
    return (values[0], values[1], values[2]), ""


def _reply(why: str) -> bytes:
    body = {"ok": True} if not why else {"ok": False, "error": why}
    return (json.dumps(body) + "\n").encode()


def send_command(
    run_dir: Path, command: str, drone: str, origin: str, timeout_s: float = 10.0
) -> None:
    """Send the operator's ``command`` to the ground station running ``run_dir``'s mission.

    Raises :class:`OperatorError` when none runs there or it refused the command.
    """
    path = Path(run_dir) / SOCKET_NAME
    if not Path(run_dir).is_dir():
        raise OperatorError(f"{run_dir}: not a run folder")
    if len(os.fsencode(path)) > MAX_SOCKET_PATH:
        raise OperatorError(f"{path}: the run folder's path is too long for the operator's socket")
    request = json.dumps({"command": command, "drone": drone, "origin": origin}) + "\n"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(timeout_s)
        try:
            sock.connect(str(path))
            sock.sendall(request.encode())
            data = b""
            while not data.endswith(b"\n"):
                chunk = sock.recv(MAX_REQUEST_BYTES)
                if not chunk:
                    break
                data += chunk
        except (FileNotFoundError, ConnectionRefusedError):
            raise NoGroundStation(
                f"{run_dir}: no ground station runs this mission (no {SOCKET_NAME}: is "
                "`eamos run` or `eamos start` running for this folder?)"
            ) from None
        except OSError as exc:
            raise OperatorError(f"{path}: {exc.strerror or exc}") from None
    try:
        answer = json.loads(data)
    except ValueError:
        raise OperatorError(f"{path}: the ground station gave no answer") from None
    if not isinstance(answer, dict) or answer.get("ok") is not True:
        error = answer.get("error") if isinstance(answer, dict) else None
        raise CommandRefused(str(error or "no reason given"))
