"""Fleet operations: roll a mission out to real drones over SSH, start, watch, abort, collect.

The paper's roll-out (Sections V-E, VI-E to VI-G, Table 7), for drones that are
computers on a network rather than processes on this machine:

* :mod:`.targets`  -- the fleet file's ``[ground]``, ``[defaults.ssh]``,
  ``[drones.X.ssh]`` and ``drones.X.bind`` settings, validated;
* :mod:`.ssh`      -- ``ssh``/``scp`` with timeouts and errors people can act on
  ("unreachable", "wrong key", "disk full", ...);
* :mod:`.rollout`  -- ``eamos rollout``: compile, probe, deploy only what changed,
  launch ``eamos-node`` detached on every drone; writes ``rollout.json``; its
  parts are :mod:`.identity` (fleet mission id, execution digests),
  :mod:`.probe`, :mod:`.plan` (what to copy, staging, launch) and :mod:`.record`
  (``rollout.json``, step timings);
* :mod:`.start`    -- ``eamos start`` (the ground station for a rolled-out fleet,
  watching the drones' nodes) and ``eamos abort``;
* :mod:`.status`   -- ``eamos status`` and ``eamos logs fetch``;
* :mod:`.deployment` -- what is deployed where (a run folder or the drones' stamps).

The commands themselves (argument parsers, exit codes) are in :mod:`eamos.cli.fleet`.

``docs/operations.md`` is the operator's guide.
"""

from .ssh import DroneError, FleetConnectError, FleetError, RunFolderError
from .targets import FleetTargets, SshTarget, load_targets

__all__ = [
    "DroneError",
    "FleetConnectError",
    "FleetError",
    "FleetTargets",
    "RunFolderError",
    "SshTarget",
    "load_targets",
]
