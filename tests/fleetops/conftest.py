"""Fixtures for fleet operations: a namespace lab with real sshd hosts, fleet keys, run folders.

The lab needs root, ``ip``, OpenSSH's ``sshd``/``ssh``/``scp``/``ssh-keygen``;
without them the SSH tests skip with the reason (CI installs everything and
treats a skip as a failure).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from .fleet_lab import REPO, Lab, missing_tools

# Host numbers in the lab (198.18.0.<n+1>).
D1, D2, NOSSH, OLDVER, TINY, TINY16, SPARE = 1, 2, 3, 4, 5, 6, 7


@pytest.fixture(scope="session")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Lab]:
    """Hosts: d1, d2 (healthy), nossh (no sshd), oldver (eamos 0.0.9), tiny (64 kB disk),
    tiny16 (16 kB disk), spare (healthy, for tests that break it)."""
    why = missing_tools()
    if why:
        pytest.skip(f"fleet lab: {why}")
    lab = Lab(tmp_path_factory.mktemp("lab"), f"efo{os.getpid() % 100000}")
    try:
        lab.add_host("d1", D1)
        lab.add_host("d2", D2)
        lab.add_host("nossh", NOSSH, sshd=False)
        oldver = lab.add_host("oldver", OLDVER)
        lab.set_node(
            oldver,
            'if [ "$1" = --version ]; then echo "eamos 0.0.9"; exit 0; fi\n'
            f'exec {Path(sys.executable).parent / "eamos-node"} "$@"',
        )
        lab.add_host("tiny", TINY, tmpfs_kb=64)
        lab.add_host("tiny16", TINY16, tmpfs_kb=16)
        lab.add_host("spare", SPARE)
        yield lab
    finally:
        lab.close()


@pytest.fixture(scope="session")
def fleet_keys(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``eamos keys`` for the ground station and two drones."""
    out = tmp_path_factory.mktemp("keys") / "keys"
    proc = subprocess.run(
        [sys.executable, "-m", "eamos.cli", "keys", str(out), "--fleet", "GCS", "Drone1", "Drone2"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr
    return out


@pytest.fixture(scope="session")
def local_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh ``eamos run`` of experiment B (the notebook and report read it)."""
    run_dir = tmp_path_factory.mktemp("localrun") / "run"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "eamos.cli",
            "run",
            str(REPO / "missions" / "experiment_b.go"),
            "--speedup",
            "20",
            "--plain",
            "--no-svg",
            "--run-dir",
            str(run_dir),
        ],
        capture_output=True,
        text=True,
        timeout=240,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return run_dir
