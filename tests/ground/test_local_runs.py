"""Run folders, ``runs/latest`` and ports of ``eamos run``: runs started together never collide.

Issue 17 (concurrency): five ``eamos run`` of one mission started in the same second
overwrote each other's folder, configs and keys.  Issue 14: ``runs/latest`` names the
newest run folder.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
import zmq

from eamos.config import ConfigError
from eamos.ground.local import (
    PortReservation,
    fresh_folder,
    fresh_keys_folder,
    link_latest,
    new_run_dir,
    use_run_dir,
)
from tests.support.runs import MISSIONS, RUN_TIMEOUT_S

NOW = time.localtime(1_800_000_000)


def test_run_folders_of_the_same_second_are_distinct(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    with ThreadPoolExecutor(8) as pool:
        made = list(pool.map(lambda _: new_run_dir("m", root, now=NOW), range(40)))
    assert len(set(made)) == 40
    stamp = time.strftime("%Y%m%d-%H%M%S", NOW)
    assert root / f"m-{stamp}" in made and root / f"m-{stamp}-40" in made
    assert all(p.is_dir() and not any(p.iterdir()) for p in made)


def test_a_long_mission_name_still_makes_a_folder(tmp_path: Path) -> None:
    folder = new_run_dir("M" * 300, tmp_path, now=NOW)
    assert folder.is_dir() and len(folder.name) < 160


def test_keys_of_a_run_before_are_moved_aside_never_overwritten(tmp_path: Path) -> None:
    assert fresh_keys_folder(tmp_path) == tmp_path / "keys"
    (tmp_path / "keys" / "GCS").mkdir()
    (tmp_path / "keys" / "GCS" / "secret").write_text("first run")
    assert fresh_keys_folder(tmp_path) == tmp_path / "keys"
    assert not any((tmp_path / "keys").iterdir())
    assert (tmp_path / "keys.old" / "GCS" / "secret").read_text() == "first run"
    (tmp_path / "keys" / "x").mkdir()
    fresh_keys_folder(tmp_path)
    assert (tmp_path / "keys.old-2" / "x").is_dir()


def test_fresh_folder_never_reuses_one(tmp_path: Path) -> None:
    (tmp_path / "keys").mkdir()
    (tmp_path / "keys" / "GCS").mkdir()
    assert fresh_folder(tmp_path / "keys") == tmp_path / "keys-2"
    assert fresh_folder(tmp_path / "keys") == tmp_path / "keys-3"
    assert (tmp_path / "keys" / "GCS").is_dir()


def test_latest_is_a_relative_link_replaced_in_place(tmp_path: Path) -> None:
    root = tmp_path / "runs"
    first = new_run_dir("m", root, now=NOW)
    second = new_run_dir("m", root, now=NOW)
    assert link_latest(first, root) == root / "latest"
    assert os.readlink(root / "latest") == first.name
    link_latest(second, root)
    assert (root / "latest").resolve() == second.resolve()
    assert sorted(p.name for p in root.iterdir()) == sorted([first.name, second.name, "latest"])


def test_latest_never_replaces_a_real_folder(tmp_path: Path) -> None:
    (tmp_path / "latest").mkdir()
    assert link_latest(new_run_dir("m", tmp_path), tmp_path) is None
    assert (tmp_path / "latest").is_dir() and not (tmp_path / "latest").is_symlink()


def test_a_reserved_port_is_taken_by_zeromq_only() -> None:
    with PortReservation(3) as reserved:
        assert len(set(reserved.ports)) == 3
        port = reserved.ports[0]
        plain = socket.socket()
        with pytest.raises(OSError):
            plain.bind(("127.0.0.1", port))
        plain.close()
        # No automatic bind (what another run's reservation does) gets a reserved port.
        others = [PortReservation(50) for _ in range(4)]
        assert not set(reserved.ports) & {p for o in others for p in o.ports}
        for other in others:
            other.release()
        ctx = zmq.Context()
        try:
            listener = ctx.socket(zmq.XPUB)
            listener.bind(f"tcp://127.0.0.1:{port}")  # the node's out-bridge
            second = ctx.socket(zmq.XPUB)
            with pytest.raises(zmq.ZMQError):
                second.bind(f"tcp://127.0.0.1:{port}")
            second.close(0)
            listener.close(0)
        finally:
            ctx.term()


@pytest.mark.e2e
def test_five_runs_started_together_all_succeed(tmp_path: Path) -> None:
    """Five ``eamos run`` of one mission, same folder, no --run-dir: five good runs."""
    argv = [
        sys.executable,
        "-m",
        "eamos.cli",
        "run",
        str(MISSIONS / "experiment_b.go"),
        "--speedup",
        "20",
        "--plain",
        "--no-svg",
        "--no-check",
        "--timeout",
        "150",
    ]
    procs = [
        subprocess.Popen(argv, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        for _ in range(5)
    ]
    outputs = [p.communicate(timeout=RUN_TIMEOUT_S * 2)[0] for p in procs]
    for proc, raw in zip(procs, outputs, strict=True):
        text = raw.decode(errors="replace")
        assert proc.returncode == 0, text
        assert "Address already in use" not in text and "internal error" not in text
    runs = tmp_path / "runs"
    folders = sorted(p for p in runs.iterdir() if not p.is_symlink())
    assert len(folders) == 5, folders
    publics = set()
    for folder in folders:
        summary = json.loads((folder / "summary.json").read_text())
        assert summary["ok"] is True, folder
        publics.add((folder / "keys" / "public" / "GCS.key").read_bytes())
        for drone in ("Drone1", "Drone2"):
            assert "net.auth.failed" not in (folder / "logs" / drone / "mission.log").read_text()
    assert len(publics) == 5  # each run its own keys
    assert (runs / "latest").resolve() in {f.resolve() for f in folders}


def test_a_run_folder_that_is_a_file_is_bad_input(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    with pytest.raises(ConfigError, match=r"--run-dir .*afile is a file, not a folder"):
        use_run_dir(tmp_path / "afile")
    with pytest.raises(ConfigError, match=r"afile is a file, not a folder"):
        use_run_dir(tmp_path / "afile" / "run")
    assert use_run_dir(tmp_path / "a" / "b").is_dir()
    assert use_run_dir(tmp_path / "a" / "b").is_dir()  # an existing folder is fine


def test_a_runs_folder_that_is_a_file_is_bad_input(tmp_path: Path) -> None:
    (tmp_path / "runs").write_text("x")
    with pytest.raises(ConfigError, match=r"the runs folder .*runs is a file, not a folder"):
        new_run_dir("m", tmp_path / "runs")
