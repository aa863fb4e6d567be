"""What eamos writes by default stays out of git; secret keys stay out of the checkout.

Issue 29: ``eamos keys keys --fleet ...`` (the operations doc's command) wrote secret keys
into the checkout's root, which ``.gitignore`` did not cover.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from eamos.cli.keys import default_keys_folder

REPO = Path(__file__).resolve().parents[2]
LANDS = """\
var Drone1 Quadcopter

func SEQ_Main() {
    Drone1.Arm()
    Drone1.Takeoff(2)
    Drone1.Land()
}
"""


def eamos(cwd: Path, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "eamos.cli", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_keys_go_to_a_per_user_folder_by_default(tmp_path: Path) -> None:
    home = tmp_path / "home"
    checkout = tmp_path / "checkout"
    checkout.mkdir()
    env = {**os.environ, "HOME": str(home)}
    env.pop("XDG_DATA_HOME", None)
    proc = eamos(checkout, "keys", "--fleet", "Drone1", "Drone2", env=env)
    assert proc.returncode == 0, proc.stderr
    keys = home / ".local" / "share" / "eamos" / "keys"
    assert f"keys for GCS, Drone1, Drone2 in {keys}/" in proc.stdout
    assert f'[ground] keys = "{keys}"' in proc.stdout
    secret = keys / "Drone1" / "Drone1.key_secret"
    assert secret.is_file() and secret.stat().st_mode & 0o077 == 0
    assert list(checkout.iterdir()) == []  # nothing in the folder it ran in
    # XDG_DATA_HOME, when set, is the place.
    data = tmp_path / "data"
    proc = eamos(checkout, "keys", "--fleet", "D9", env={**env, "XDG_DATA_HOME": str(data)})
    assert proc.returncode == 0 and (data / "eamos" / "keys" / "D9").is_dir()


def test_default_keys_folder_follows_xdg() -> None:
    assert default_keys_folder({"XDG_DATA_HOME": "/srv/d"}) == Path("/srv/d/eamos/keys")
    # A relative XDG_DATA_HOME is invalid per the specification: ignored.
    assert default_keys_folder({"XDG_DATA_HOME": "rel"}) == (
        Path.home() / ".local" / "share" / "eamos" / "keys"
    )


def test_keys_without_participants_or_folder_is_bad_input(tmp_path: Path) -> None:
    proc = eamos(tmp_path, "keys")
    assert proc.returncode == 2
    assert "name the participants (--fleet GCS Drone1 ...)" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_every_default_output_is_ignored_by_the_checkouts_gitignore(tmp_path: Path) -> None:
    git = shutil.which("git")
    if git is None:
        pytest.skip("git is not installed: cannot ask it what it ignores")
    checkout = tmp_path / "checkout"
    checkout.mkdir()
    shutil.copy(REPO / ".gitignore", checkout / ".gitignore")
    (checkout / "lands.go").write_text(LANDS)
    env = {**os.environ, "HOME": str(tmp_path / "home"), "GIT_CONFIG_NOSYSTEM": "1"}
    subprocess.run([git, "init", "-q"], cwd=checkout, check=True, env=env)
    # What a newcomer runs in the checkout, each command with its default output folder.
    for args in [
        ("compile", "lands.go"),
        ("run", "lands.go", "--speedup", "20", "--plain"),
        ("report", "runs/latest"),
        ("keys", "keys", "--fleet", "Drone1"),  # the old docs' command: into ./keys
        ("keys", "fleet-keys", "--fleet", "Drone1"),
        ("keys", "out/lands"),
    ]:
        proc = eamos(checkout, *args, env=env)
        assert proc.returncode == 0, (args, proc.stdout, proc.stderr)
    assert (checkout / "keys" / "Drone1" / "Drone1.key_secret").is_file()
    status = subprocess.run(
        [git, "status", "--porcelain", "--untracked-files=all"],
        cwd=checkout,
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    assert sorted(status) == ["?? .gitignore", "?? lands.go"], status
