"""``ssh`` and ``scp`` to the drones: bounded in time, with errors an operator can act on.

Every call runs the system OpenSSH client (so ``~/.ssh/config``, agents and
jump hosts keep working) with ``BatchMode=yes`` (never a password prompt that
would hang the roll-out), a connect timeout, and an overall timeout on the
process.  What ssh and the remote commands print on failure is translated into
one line per drone::

    Drone1 (ubuntu@198.18.0.2:22): unreachable: ssh: connect to host 198.18.0.2 port 22: ...
    Drone2 (ubuntu@198.18.0.3:22): wrong key: Permission denied (publickey) for key ...
    Drone2 (ubuntu@198.18.0.3:22): disk full: No space left on device (...)
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

from .targets import SshTarget

T = TypeVar("T")

SSH_FAILED = 255  # ssh's own exit code for connection and authentication failures

# (substring of ssh/scp/remote output, kind, hint).  First match wins; matched
# case-insensitively against every line of stderr.
_PATTERNS: tuple[tuple[str, str, str], ...] = (
    ("no space left on device", "disk full", "free space in the drone's folder"),
    ("disk quota exceeded", "disk full", "free space in the drone's folder"),
    ("permission denied (publickey", "wrong key", ""),
    ("too many authentication failures", "wrong key", ""),
    ("remote host identification has changed", "host key changed", ""),
    ("host key verification failed", "host key changed", ""),
    ("connection refused", "unreachable", "is sshd running on the drone?"),
    ("connection timed out", "unreachable", "is the drone on and on this network?"),
    ("operation timed out", "unreachable", "is the drone on and on this network?"),
    ("no route to host", "unreachable", "is the drone on and on this network?"),
    ("network is unreachable", "unreachable", "is the drone on and on this network?"),
    ("could not resolve hostname", "unreachable", "check ssh.host in the fleet file"),
    ("name or service not known", "unreachable", "check ssh.host in the fleet file"),
    ("connection closed by", "unreachable", ""),
    ("connection reset", "unreachable", ""),
    ("broken pipe", "unreachable", "the connection dropped"),
)


class DroneError(Exception):
    """One drone could not do one step; the message names the drone and its host."""

    def __init__(self, drone: str, where: str, kind: str, detail: str) -> None:
        self.drone = drone
        self.where = where
        self.kind = kind
        self.detail = detail
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.drone} ({self.where}): {self.kind}: {self.detail}"


class FleetError(Exception):
    """A fleet operation failed; ``errors`` says which drones and why."""

    def __init__(self, message: str, errors: Sequence[DroneError] = ()) -> None:
        self.message = message
        self.errors = list(errors)
        super().__init__(str(self))

    def __str__(self) -> str:
        return "\n".join([self.message, *(f"  {e}" for e in self.errors)])


class RunFolderError(FleetError):
    """A run folder is not a roll-out's (no or a damaged ``rollout.json``): bad input.

    A :class:`FleetError` so that code catching fleet failures still catches it;
    the command line tells it apart (it is the operator's input, not the fleet).
    """


class FleetConnectError(FleetError):
    """This machine could not connect to the fleet (the ground station's port taken or
    unreachable): "could not connect" on the command line."""


def classify(text: str) -> tuple[str, str] | None:
    """``(kind, line)`` for the first recognised failure in ssh/scp/remote output."""
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    for needle, kind, hint in _PATTERNS:
        for line in lines:
            if needle in line.lower():
                line = line.strip("@ ").strip()
                return kind, f"{line} ({hint})" if hint else line
    return None


def _explain(target: SshTarget, text: str, fallback_kind: str) -> DroneError:
    found = classify(text)
    if found is not None:
        kind, detail = found
        if kind == "wrong key":
            key = str(target.identity) if target.identity else "ssh's default keys"
            detail = f"{detail}: the drone does not accept {key}"
        elif kind == "host key changed":
            detail = (
                f"{detail}: the drone's host key is not the one known; if it was reinstalled, "
                f"run `ssh-keygen -R {target.host}`"
                + (f" -f {target.known_hosts}" if target.known_hosts else "")
            )
        return DroneError(target.drone, target.label, kind, detail)
    last = [ln for ln in text.splitlines() if ln.strip()]
    return DroneError(
        target.drone, target.label, fallback_kind, last[-1].strip() if last else "no output"
    )


@dataclass(frozen=True)
class Remote:
    """What a remote command printed and returned."""

    returncode: int
    stdout: str
    stderr: str


def _run(argv: list[str], timeout_s: float, stdin: str | None = None) -> Remote:
    proc = subprocess.run(
        argv,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=timeout_s,
        stdin=None if stdin is not None else subprocess.DEVNULL,
        check=False,
    )
    return Remote(proc.returncode, proc.stdout, proc.stderr)


def run_remote(target: SshTarget, command: str, timeout_s: float) -> Remote:
    """Run a shell command line on the drone; raise :class:`DroneError` if ssh itself failed.

    A remote command's own non-zero exit is returned, not raised: the caller
    knows what it means.  Exit 255 is ssh's (connection or authentication).
    """
    try:
        result = _run(target.ssh_argv(command), timeout_s)
    except subprocess.TimeoutExpired as exc:
        raise DroneError(
            target.drone, target.label, "unreachable", f"no answer within {timeout_s:g} s"
        ) from exc
    except FileNotFoundError as exc:
        raise DroneError(
            target.drone, target.label, "no ssh", "the `ssh` client is not installed here"
        ) from exc
    if result.returncode == SSH_FAILED:
        raise _explain(target, result.stderr, "ssh failed")
    return result


def copy_to(target: SshTarget, sources: Iterable[Path], remote_dir: str, timeout_s: float) -> None:
    """``scp`` files into a folder on the drone; :class:`DroneError` on failure."""
    try:
        result = _run(target.scp_argv(sources, remote_dir), timeout_s)
    except subprocess.TimeoutExpired as exc:
        raise DroneError(
            target.drone, target.label, "copy failed", f"not done within {timeout_s:g} s"
        ) from exc
    if result.returncode != 0:
        raise _explain(target, result.stderr, "copy failed")


def copy_from(target: SshTarget, remote_path: str, local_dir: Path, timeout_s: float) -> None:
    """``scp -r`` a file or folder from the drone into ``local_dir``."""
    local_dir.mkdir(parents=True, exist_ok=True)
    try:
        result = _run(target.scp_from_argv(remote_path, local_dir), timeout_s)
    except subprocess.TimeoutExpired as exc:
        raise DroneError(
            target.drone, target.label, "copy failed", f"not done within {timeout_s:g} s"
        ) from exc
    if result.returncode != 0:
        raise _explain(target, result.stderr, "copy failed")


def remote_error(target: SshTarget, result: Remote, fallback_kind: str) -> DroneError:
    """A :class:`DroneError` from a remote command's failing output."""
    return _explain(target, result.stderr + "\n" + result.stdout, fallback_kind)


def for_each(
    targets: Iterable[SshTarget], work: Callable[[SshTarget], T]
) -> tuple[dict[str, T], list[DroneError]]:
    """Run ``work`` for every drone in parallel; collect results and :class:`DroneError` s.

    Drones are independent computers: a slow one must not make the others wait
    in line.  Other exceptions propagate (they are bugs, not drone problems).
    """
    items = list(targets)
    results: dict[str, T] = {}
    errors: list[DroneError] = []
    if not items:
        return results, errors

    def one(target: SshTarget) -> tuple[str, T | DroneError]:
        try:
            return target.drone, work(target)
        except DroneError as exc:
            return target.drone, exc

    with ThreadPoolExecutor(max_workers=min(16, len(items))) as pool:
        for name, outcome in pool.map(one, items):
            if isinstance(outcome, DroneError):
                errors.append(outcome)
            else:
                results[name] = outcome
    return results, errors


__all__ = [
    "DroneError",
    "FleetConnectError",
    "FleetError",
    "Remote",
    "RunFolderError",
    "classify",
    "copy_from",
    "copy_to",
    "for_each",
    "remote_error",
    "run_remote",
]
