"""``--help`` and ``--version`` answer without loading what only the commands need.

Issue 29: ``eamos --version`` took about 1.8 s on a loaded machine because building the
parser imported the compiler, networkx, tree-sitter, ZeroMQ, structlog... for every
command.  The heavy libraries now load inside the commands that use them.  This test
asserts what is imported (in a fresh interpreter, through the console scripts' entry
points), not a time: ``scripts/bench_cli_help.py`` measures the time.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: What no ``--help``/``--version`` of ``eamos`` or ``eamos-sim-vehicle`` may import.
HEAVY = (
    "eamos.compiler",
    "eamos.ops",
    "eamos.ground",
    "eamos.actors",
    "eamos.net",
    "eamos.config",
    "networkx",
    "tree_sitter",
    "pygls",
    "lsprotocol",
    "starlette",
    "uvicorn",
    "matplotlib",
    "zmq",
    "pykka",
    "structlog",
    "rich",
    "pymavlink",
)

PROBE = """\
import json, sys
sys.argv = {argv!r}
from {module} import main
try:
    code = main()
except SystemExit as exc:
    code = exc.code
print(json.dumps({{"code": code, "heavy": [m for m in {heavy!r} if m in sys.modules]}}))
"""


def imported(module: str, argv: list[str]) -> dict:
    code = PROBE.format(argv=argv, module=module, heavy=HEAVY)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    result: dict = json.loads(proc.stdout.splitlines()[-1])
    return result


@pytest.mark.parametrize(
    "args",
    [
        ["--version"],
        ["--help"],
        ["lsp", "--help"],
        ["run", "--help"],
        ["check", "--help"],
        ["compile", "--help"],
        ["graph", "--help"],
        ["monitor", "--help"],
        ["report", "--help"],
        ["keys", "--help"],
        ["rollout", "--help"],
        ["start", "--help"],
        ["pause", "--help"],
        ["resume", "--help"],
        ["drone", "--help"],
    ],
    ids=" ".join,
)
def test_eamos_help_and_version_import_nothing_heavy(args: list[str]) -> None:
    found = imported("eamos.cli.main", ["eamos", *args])
    assert found == {"code": 0, "heavy": []}


@pytest.mark.parametrize("args", [["--version"], ["--help"]], ids=" ".join)
def test_eamos_sim_vehicle_help_and_version_import_nothing_heavy(args: list[str]) -> None:
    found = imported("eamos.cli.sim_vehicle", ["eamos-sim-vehicle", *args])
    assert found == {"code": 0, "heavy": []}


@pytest.mark.parametrize("args", [["--version"], ["--help"]], ids=" ".join)
def test_eamos_node_help_and_version_import_nothing_heavy(args: list[str]) -> None:
    # The node's runtime (ZeroMQ, Pykka, structlog) loads once a config is to be run.
    found = imported("eamos.cli.node", ["eamos-node", *args])
    assert found == {"code": 0, "heavy": []}


def test_the_probe_sees_a_heavy_import_when_there_is_one() -> None:
    # The probe can fail: a command that does its work imports the compiler.
    found = imported("eamos.cli.main", ["eamos", "compile", "--stats", "no-such-file.go"])
    assert found["code"] == 2 and "eamos.compiler" in found["heavy"]
