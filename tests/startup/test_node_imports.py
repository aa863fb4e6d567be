"""What an ``eamos-node`` process loads, and who touches its garbage collector.

A drone's node runs a compiled program: the compiler (with networkx and
tree-sitter), the ground station, the language server and the monitor's web
server are other programs.  ``tests/test_layering.py`` checks the imports between
the project's own layers; here one fresh interpreter imports what a simulated
drone's node imports (``eamos.cli.node``, then the simulated adapter it builds)
and the test fails if any of those parts, or the libraries only they use, came
with it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

#: Never in a drone's node: the compiler and its graph and parser libraries, the
#: ground station, the language server, the monitor's web server.
NOT_ON_THE_NODE = (
    "networkx",
    "tree_sitter",
    "eamos.compiler",
    "eamos.ground",
    "eamos.lsp",
    "pygls",
    "eamos.monitor",
    "starlette",
    "uvicorn",
)

#: A fresh interpreter: the node's imports (with the simulated adapter it builds), then
#: a log line with a traceback, as a node writes it.
NODE = r"""
import json, pathlib, sys
import eamos.cli.node
import eamos.hal.sim.adapter
eamos.cli.node.build_parser().parse_args(["--config", "d1.toml"])
node = sorted(sys.modules)
from eamos.logs import close_logger, make_logger
log = make_logger(pathlib.Path(sys.argv[1]), drone="D1")
try:
    raise ValueError("boom")
except ValueError:
    log.exception("test.crash")
close_logger(log)
print(json.dumps(node))
"""


def printed(code: str, *args: str) -> Any:
    """What ``code`` prints as JSON, run in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    return json.loads(out.stdout)


def present(modules: list[str], names: tuple[str, ...]) -> list[str]:
    """The names of ``names`` in ``modules`` (a package counts with its submodules)."""
    return [n for n in names if any(m == n or m.startswith(n + ".") for m in modules)]


def test_the_node_loads_no_compiler_ground_station_or_servers_and_logs(tmp_path: Path) -> None:
    assert present(printed(NODE, str(tmp_path / "x.log")), NOT_ON_THE_NODE) == []
    line = json.loads((tmp_path / "x.log").read_text().splitlines()[0])
    assert (line["event"], line["level"], line["drone"]) == ("test.crash", "error", "D1")
    assert "ValueError: boom" in line["exception"]


def test_the_check_sees_a_module_that_should_not_be_there() -> None:
    # The check above must be able to fail.
    assert present(["networkx.classes", "zmq"], NOT_ON_THE_NODE) == ["networkx"]
    assert present(["eamos.compiler.phases"], NOT_ON_THE_NODE) == ["eamos.compiler"]
    assert present(["eamos.compilers"], NOT_ON_THE_NODE) == []


#: A fresh interpreter: the collector as importing ``eamos.cli.node`` left it, then as
#: its ``main()`` left it (``main([])`` stops at once: ``--config`` is required).  Frozen
#: counts are differences: an interpreter may start with objects frozen (3.12 does).
COLLECTOR = r"""
import gc, json, sys
start = gc.get_freeze_count()
import eamos.cli.node
imported = {"enabled": gc.isenabled(), "frozen": gc.get_freeze_count() - start}
try:
    code = eamos.cli.node.main(["--config", "/nonexistent/drone.toml"])
except SystemExit as exc:
    code = exc.code
frozen = gc.get_freeze_count() - start - imported["frozen"]
print(json.dumps({**imported, "code": code, "frozen_by_main": frozen > 0}))
"""


def test_importing_the_node_leaves_the_collector_alone_and_its_main_freezes() -> None:
    assert printed(COLLECTOR) == {
        "enabled": True,
        "frozen": 0,
        "code": 2,  # the config cannot be read (the runtime loaded and frozen first)
        "frozen_by_main": True,
    }
