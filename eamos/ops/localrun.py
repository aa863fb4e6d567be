"""An ``eamos run`` folder seen as a deployment, so ``eamos abort RUN_DIR`` works on it too.

``eamos run`` writes no ``rollout.json``: its drones are local processes whose
node configs (``configs/<Drone>.toml``) say everything an abort needs -- the
mission (from the programs they name), each drone's endpoint, the ground
station's endpoint and the fleet keys (``keys/GCS``).  If the run's own ground
station still runs, it is the one to signal (it aborts, collects the reports
and writes the summary); it is found as the parent of the drones' processes,
whose command lines name their configs.  If it is gone (killed), ``eamos abort``
becomes the ground station itself, as for a roll-out.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..config import ConfigError, NodeConfig
from ..program.format import ProgramError, load_program
from ..program.uniform import GROUND_STATION
from .deployment import Deployment
from .ssh import RunFolderError

__all__ = ["is_local_run", "local_deployment", "local_ground_pid", "local_node_pids"]


def is_local_run(run_dir: Path) -> bool:
    """``run_dir`` is an ``eamos run`` folder (node configs, no roll-out record)."""
    return (run_dir / "configs").is_dir() and any((run_dir / "configs").glob("*.toml"))


def local_deployment(run_dir: Path) -> Deployment:
    """The deployment an ``eamos run`` folder describes (RunFolderError if it cannot be read)."""
    configs: dict[str, NodeConfig] = {}
    try:
        for path in sorted((run_dir / "configs").glob("*.toml")):
            config = NodeConfig.load(path)
            configs[config.drone] = config
        if not configs:
            raise RunFolderError(f"{run_dir}: no node configs in configs/")
        first = next(iter(configs.values()))
        program = load_program(first.program)
    except (ConfigError, ProgramError, OSError) as exc:
        raise RunFolderError(f"{run_dir}: not a readable run folder: {exc}") from exc
    ground_bind = first.peers.get(GROUND_STATION)
    if ground_bind is None:
        raise RunFolderError(f"{first.path}: net.peers has no {GROUND_STATION}")
    keys = run_dir / "keys"  # the run's one key folder (a local run ships none)
    drones = sorted(configs)
    return Deployment(
        mission=program.mission,
        mission_id=program.mission_id,
        drones=drones,
        targets={},
        endpoints={n: configs[n].bind for n in drones},
        ground_bind=ground_bind,
        run_dir=run_dir.resolve(),
        keys_dir=keys if (keys / GROUND_STATION).is_dir() else None,
    )


def _node_processes(run_dir: Path, proc: Path) -> list[tuple[int, bytes, str]]:
    """``(pid, cmdline, status)`` of each process naming ``run_dir/configs/`` (Linux /proc)."""
    marker = str((run_dir / "configs").resolve()).encode() + b"/"
    try:
        entries = list(proc.iterdir())
    except OSError:
        return []
    found = []
    for entry in entries:
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes()
            if marker not in cmdline:
                continue
            found.append((int(entry.name), cmdline, (entry / "status").read_text()))
        except OSError:
            continue
    return found


def local_node_pids(run_dir: Path, proc: Path = Path("/proc")) -> dict[str, int]:
    """The pid of each drone's ``eamos-node`` still running in ``run_dir``, by drone."""
    pids = {}
    for pid, cmdline, status in _node_processes(run_dir, proc):
        if "\nState:\tZ" in status:
            continue  # a zombie: it has ended
        for arg in cmdline.split(b"\0"):
            if arg.endswith(b".toml") and b"/configs/" in arg:
                pids[Path(arg.decode(errors="replace")).stem] = pid
    return pids


def local_ground_pid(run_dir: Path, proc: Path = Path("/proc")) -> int | None:
    """The pid of the ``eamos run`` still running ``run_dir`` (None: none found).

    Its drones' ``eamos-node`` processes name ``run_dir/configs/...`` on their
    command line; their parent is the run.  Without ``/proc`` nothing is found.
    """
    for _pid, _cmdline, status in _node_processes(run_dir, proc):
        ppid = _ppid(status)
        if ppid is None or ppid <= 1 or ppid == os.getpid():
            continue
        try:
            parent = (proc / str(ppid) / "cmdline").read_bytes()
        except OSError:
            continue
        if b"eamos" in parent:
            return ppid
    return None


def _ppid(status: str) -> int | None:
    for line in status.splitlines():
        if line.startswith("PPid:"):
            try:
                return int(line.split()[1])
            except (IndexError, ValueError):
                return None
    return None
