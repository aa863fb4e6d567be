"""The roll-out's probe: one SSH call per drone asks what it has before anything is touched.

The probe creates the mission folder, runs ``eamos-node --version`` (it must
equal this eamos), reads the free space, the stamp of what is deployed there,
the checksums of the program and config, and whether a node still runs.
"""

from __future__ import annotations

import json
import re
import shlex
from dataclasses import dataclass
from typing import Any

from .. import __version__
from .ssh import DroneError, remote_error, run_remote
from .targets import SshTarget

PROBE_TIMEOUT_S = 60.0


@dataclass(frozen=True)
class Probe:
    """What a drone told about itself before the roll-out touched anything."""

    version_output: str
    free_kb: int | None
    stamp: dict[str, Any] | None
    sums: dict[str, str]  # path relative to the mission folder -> sha256 hex
    pid: int | None
    alive: bool

    @property
    def version(self) -> str | None:
        match = re.search(r"eamos\s+(\S+)", self.version_output)
        return match.group(1) if match else None


def sections(text: str) -> dict[str, list[str]]:
    """A remote script's output split at its ``@@name`` markers: name -> non-empty lines."""
    out: dict[str, list[str]] = {}
    current = ""
    for line in text.splitlines():
        if line.startswith("@@"):
            current = line[2:].split(" ", 1)[0]
            out[current] = [line[2 + len(current) :].strip()]
        elif current:
            out[current].append(line)
    return {k: [ln for ln in v if ln.strip()] for k, v in out.items()}


# A pid file may outlive its process, and the pid be reused: a process counts as
# the drone's node only if its command line names the drone's config.
RUNNING_SH = r"""running() {
  kill -0 "$1" 2>/dev/null || return 1
  [ -r "/proc/$1/cmdline" ] || return 0
  tr '\0' ' ' < "/proc/$1/cmdline" | grep -q -- "configs/$N.toml"
}
"""


def probe_script(target: SshTarget, mission: str) -> str:
    """The remote shell script of the probe step (POSIX sh)."""
    d = shlex.quote(target.mission_dir(mission))
    drone = shlex.quote(target.drone)
    node = target.node_command
    return f"""
D={d}; N={drone}
{RUNNING_SH}mkdir -p "$D/programs" "$D/configs" "$D/logs" "$D/state" || exit 90
cd "$D" || exit 90
rm -rf ".incoming/$N" && mkdir -p ".incoming/$N" || exit 90
echo "@@version"
{node} --version 2>&1
echo "@@df"
df -Pk . 2>&1 | tail -n 1
echo "@@stamp"
cat "state/$N.deployed.json" 2>/dev/null
echo
echo "@@sums"
sha256sum "programs/$N.program.json" "configs/$N.toml" 2>/dev/null
echo "@@pid"
if [ -f "state/$N.pid" ]; then
  p=$(cat "state/$N.pid")
  if running "$p"; then echo "alive $p"; else echo "dead $p"; fi
fi
echo "@@end"
"""


def parse_probe(stdout: str) -> Probe:
    """Read the probe script's output."""
    sec = sections(stdout)
    free_kb: int | None = None
    df = sec.get("df") or []
    if df:
        fields = df[-1].split()
        if len(fields) >= 4 and fields[3].isdigit():
            free_kb = int(fields[3])
    stamp: dict[str, Any] | None = None
    stamp_text = "\n".join(sec.get("stamp", [])).strip()
    if stamp_text:
        try:
            loaded = json.loads(stamp_text)
            stamp = loaded if isinstance(loaded, dict) else None
        except json.JSONDecodeError:
            stamp = None  # a damaged stamp means: redeploy
    sums: dict[str, str] = {}
    for line in sec.get("sums", []):
        parts = line.split(None, 1)
        if len(parts) == 2:
            sums[parts[1].strip().lstrip("*")] = parts[0]
    pid: int | None = None
    alive = False
    for line in sec.get("pid", []):
        parts = line.split()
        if len(parts) == 2 and parts[1].isdigit():
            pid, alive = int(parts[1]), parts[0] == "alive"
    return Probe(
        version_output="\n".join(sec.get("version", [])).strip(),
        free_kb=free_kb,
        stamp=stamp,
        sums=sums,
        pid=pid,
        alive=alive,
    )


def probe(target: SshTarget, mission: str) -> Probe:
    """Run the probe on one drone; :class:`DroneError` if unreachable or unusable."""
    result = run_remote(target, probe_script(target, mission), PROBE_TIMEOUT_S)
    if result.returncode == 90:
        raise remote_error(target, result, "cannot use the folder")
    if result.returncode != 0 or "@@end" not in result.stdout:
        raise remote_error(target, result, "probe failed")
    return parse_probe(result.stdout)


def check_version(target: SshTarget, found: Probe) -> None:
    """The drone's eamos must be the operator's: programs and wire format are versioned."""
    wanted = __version__
    fix = f"run `pip install eamos=={wanted}` on the drone"
    if found.version is None:
        output = found.version_output.splitlines()[-1] if found.version_output else "no output"
        raise DroneError(
            target.drone,
            target.label,
            "eamos not found",
            f"`{target.node_command} --version` failed ({output}): {fix}, "
            "or set ssh.node_command in the fleet file",
        )
    if found.version != wanted:
        raise DroneError(
            target.drone,
            target.label,
            "version mismatch",
            f"drone has eamos {found.version}, operator {wanted}: {fix}",
        )


__all__ = [
    "PROBE_TIMEOUT_S",
    "RUNNING_SH",
    "Probe",
    "check_version",
    "parse_probe",
    "probe",
    "probe_script",
    "sections",
]
