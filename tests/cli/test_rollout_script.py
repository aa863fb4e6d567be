"""``scripts/rollout.sh`` finds the eamos the README's install made, or says how to.

Issue 29: after ``python3 -m venv .venv && .venv/bin/pip install -e .`` the venv is
not on PATH, and the script said ``eamos: command not found``.  Each test copies the
script into a checkout of its own (the script looks next to itself) and runs it with
a PATH that has no eamos on it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "rollout.sh"
#: The eamos console script of the Python running the tests (installed by pip).
INSTALLED = Path(sys.executable).parent / "eamos"


def checkout(tmp_path: Path, name: str = "my checkout") -> Path:
    """A folder laid out as a checkout (a space in its name, as a home folder may have)."""
    root = tmp_path / name
    (root / "scripts").mkdir(parents=True)
    shutil.copy(SCRIPT, root / "scripts" / "rollout.sh")
    return root


def run_script(root: Path, cwd: Path, **env: str) -> subprocess.CompletedProcess[str]:
    bash = shutil.which("bash")
    assert bash is not None
    clean = {k: v for k, v in os.environ.items() if k not in ("EAMOS", "VIRTUAL_ENV")}
    clean["PATH"] = "/usr/bin:/bin"  # no venv on it
    return subprocess.run(
        [bash, str(root / "scripts" / "rollout.sh"), "no-such-mission.go", "fleet.toml"],
        cwd=cwd,
        env={**clean, **env},
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_it_runs_the_eamos_of_the_checkouts_venv(tmp_path: Path) -> None:
    if not INSTALLED.is_file():
        pytest.skip(f"no console script {INSTALLED}: eamos is not pip-installed here")
    if shutil.which("eamos", path="/usr/bin:/bin"):
        pytest.skip("an eamos on /usr/bin or /bin would hide which one the script runs")
    root = checkout(tmp_path)
    (root / ".venv" / "bin").mkdir(parents=True)
    (root / ".venv" / "bin" / "eamos").symlink_to(INSTALLED)
    proc = run_script(root, cwd=tmp_path)
    # eamos itself answered: its own error about the missing fleet file, exit 2.
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "eamos rollout: fleet.toml: no such configuration file" in proc.stderr
    assert "command not found" not in proc.stderr and "rollout.sh: eamos not found" not in (
        proc.stderr
    )


def test_without_an_eamos_it_says_how_to_install_or_point_at_one(tmp_path: Path) -> None:
    if shutil.which("eamos", path="/usr/bin:/bin"):
        pytest.skip("an eamos on /usr/bin or /bin: the script would find it")
    root = checkout(tmp_path)
    proc = run_script(root, cwd=tmp_path)
    assert proc.returncode == 2
    assert f"rollout.sh: eamos not found: neither {root}/.venv/bin/eamos nor eamos on PATH" in (
        proc.stderr
    )
    assert f"cd {root} && python3 -m venv .venv && .venv/bin/pip install -q -e ." in proc.stderr
    assert "EAMOS=/path/to/venv/bin/eamos" in proc.stderr


def test_eamos_names_the_command_with_its_arguments(tmp_path: Path) -> None:
    root = checkout(tmp_path)
    proc = run_script(root, cwd=tmp_path, EAMOS=f"{sys.executable} -m eamos.cli")
    assert proc.returncode == 2 and "eamos rollout: fleet.toml: no such" in proc.stderr
