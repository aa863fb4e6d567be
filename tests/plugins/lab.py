"""Install the test lab package (tests/plugins/lab_package) into a folder, as pip would.

The folder gets the package and ``eamos_labspray-1.0.dist-info/`` with ``METADATA`` and
``entry_points.txt``; with the folder on ``sys.path`` (or ``PYTHONPATH`` for a subprocess),
:func:`importlib.metadata.entry_points` finds the ``eamos.actions`` entry point.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

PACKAGE = Path(__file__).parent / "lab_package" / "eamos_labspray"

ENTRY_POINTS = """\
[eamos.actions]
Spray = eamos_labspray:SPRAY
"""

#: The lab's broken plugins too (``eamos_labspray/faults.py``).
FAULTY_ENTRY_POINTS = """\
[eamos.actions]
Spray = eamos_labspray:SPRAY
Quit = eamos_labspray.faults:QUIT
CtrlC = eamos_labspray.faults:CTRL_C
Stall = eamos_labspray.faults:STALL
Spin = eamos_labspray.faults:SPIN
"""


def install_lab(folder: Path, entry_points: str = ENTRY_POINTS) -> Path:
    """Install the lab package into ``folder``; returns ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copytree(PACKAGE, folder / "eamos_labspray", dirs_exist_ok=True)
    info = folder / "eamos_labspray-1.0.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: eamos-labspray\nVersion: 1.0\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(entry_points, encoding="utf-8")
    return folder


def env_with(folder: Path) -> dict[str, str]:
    """The environment of a subprocess that sees the package installed in ``folder``."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(folder), env.get("PYTHONPATH")) if p)
    return env
