"""eamos-node's import set stays lean: its start-up is mostly imports (scripts/bench_startup.py).

One fresh interpreter imports what a simulated drone's node imports (``eamos.cli.node``,
then the simulated adapter it builds) and reports which heavy modules came with them.
Each of these was on the node's path once and cost it tens of ms; the test fails if one
comes back.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

#: Never on a drone's node at start: the console renderer's extras (structlog would pull
#: them in, see eamos/cli/node_imports.py), the compiler's graph and parser libraries; what
#: only a wrong name (difflib, eamos/hints.py) or the end of a flight (the report) needs;
#: secrets (with hmac and hashlib's OpenSSL bindings) for one random byte; asyncio (with
#: ssl), which structlog reads only in its async log methods (deferred, node_imports.py);
#: shutil (with bz2, lzma), which argparse's help formatter imports for the terminal width.
NOT_ON_THE_NODE = (
    "asyncio",
    "ssl",
    "shutil",
    "rich",
    "pygments",
    "networkx",
    "tree_sitter",
    "eamos.compiler",
    "eamos.ground",
    "importlib.metadata",
    "email",
    "difflib",
    "secrets",
    "eamos.actors.report",
)
#: Not loaded by importing the configs, the HAL or the plugin registry (plugin discovery
#: imports importlib.metadata when it runs; the simulator's adapter and logs come with
#: the adapter, not with its settings).
NOT_ON_IMPORT = ("importlib.metadata", "email", "eamos.hal.sim.adapter", "eamos.hal.sim.core")

#: A fresh interpreter: the node's imports (with the simulated adapter it builds), rich
#: still importable after them (the ground station's live table), and a log line with
#: a traceback written by structlog loaded without rich.
NODE = r"""
import json, pathlib, sys
import eamos.cli.node
import eamos.hal.sim.adapter
eamos.cli.node.build_parser().parse_args(["--config", "d1.toml"])
node = sorted(sys.modules)
import rich.table
from eamos.logs import close_logger, make_logger
log = make_logger(pathlib.Path(sys.argv[1]), drone="D1")
try:
    raise ValueError("boom")
except ValueError:
    log.exception("test.crash")
close_logger(log)
print(json.dumps(node))
"""
#: A fresh interpreter importing the configs, the HAL and the plugin registry, and making
#: a registry of the installed plugins that nothing has used yet.
LAYERS = r"""
import json, sys
import eamos.config, eamos.hal, eamos.program.plugins
registry = eamos.program.plugins.discover_plugins()
print(json.dumps(sorted(sys.modules)))
"""


def printed(code: str, *args: str, env: dict[str, str] | None = None) -> Any:
    """What ``code`` prints as JSON, run in a fresh interpreter (``env``: its environment)."""
    out = subprocess.run(
        [sys.executable, "-c", code, *args],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
        env=env,
    )
    return json.loads(out.stdout)


def loaded(code: str, *args: str) -> list[str]:
    """The modules loaded by ``code`` in a fresh interpreter (it prints them as JSON)."""
    result: list[str] = printed(code, *args)
    return result


def present(modules: list[str], names: tuple[str, ...]) -> list[str]:
    """The names of ``names`` in ``modules`` (a package counts with its submodules)."""
    return [n for n in names if any(m == n or m.startswith(n + ".") for m in modules)]


def test_the_node_imports_no_heavy_module_and_still_logs(tmp_path: Path) -> None:
    assert present(loaded(NODE, str(tmp_path / "x.log")), NOT_ON_THE_NODE) == []
    line = json.loads((tmp_path / "x.log").read_text().splitlines()[0])
    assert line["event"] == "test.crash"
    assert "ValueError: boom" in line["exception"]


def test_configs_hal_and_an_unused_plugin_registry_load_no_metadata_and_no_adapter() -> None:
    assert present(loaded(LAYERS), NOT_ON_IMPORT) == []


def test_the_help_is_as_wide_as_the_terminal_argparse_would_find(monkeypatch: Any) -> None:
    import argparse

    from eamos.cli.node import build_parser

    for columns in ("50", "120", "0", "wide"):  # "0" and "wide": as argparse, the fallback
        monkeypatch.setenv("COLUMNS", columns)
        ours = build_parser()
        # The same parser with argparse left to find the width itself (through shutil).
        reference = build_parser()
        reference.formatter_class = argparse.RawDescriptionHelpFormatter
        assert ours.format_help() == reference.format_help(), columns
        assert ours.format_usage() == reference.format_usage(), columns


def test_the_check_sees_a_heavy_module() -> None:
    # The check above must be able to fail.
    assert present(["rich.table", "zmq"], NOT_ON_THE_NODE) == ["rich"]
    assert present(["importlib.metadata"], NOT_ON_IMPORT) == ["importlib.metadata"]


#: A fresh interpreter: how many collections the cyclic garbage collector ran while
#: ``eamos.cli.node`` loaded, and whether it runs again afterwards.
COLLECTIONS = r"""
import gc, json
runs = []
gc.callbacks.append(lambda phase, info: runs.append(phase) if phase == "start" else None)
import eamos.cli.node
print(json.dumps({"collections": len(runs), "enabled": gc.isenabled()}))
"""


def test_the_node_loads_with_the_collector_paused_and_resumes_it(tmp_path: Path) -> None:
    # Byte-code read from a cache, as installed: compiling a module's source (this
    # environment may forbid writing byte-code) allocates before the module can pause.
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(tmp_path / "pycache")
    printed(COLLECTIONS, env=env)  # fills the cache
    # Without the pause the collector runs dozens of times over the new modules.
    assert printed(COLLECTIONS, env=env) == {"collections": 0, "enabled": True}


#: A fresh interpreter: the node's imports, then structlog's async log method (the one
#: reader of asyncio there) called under asyncio, through the stand-in it kept.
ASYNC_LOG = r"""
import io, json, sys
import eamos.cli.node
before = "asyncio" in sys.modules
import structlog, structlog._native
standing_in = type(structlog._native.asyncio).__name__
import asyncio
out = io.StringIO()
render = structlog.processors.JSONRenderer()
log = structlog.make_filtering_bound_logger(20)(structlog.PrintLogger(out), [render], {})
asyncio.run(log.ainfo("async.line"))
print(json.dumps({
    "before": before,
    "standing_in": standing_in,
    "same": structlog._native.asyncio.run is asyncio.run,
    "logged": out.getvalue().strip(),
}))
"""


def test_structlog_reads_asyncio_through_its_stand_in_only_when_an_async_method_runs() -> None:
    assert printed(ASYNC_LOG) == {
        "before": False,  # deferred while structlog loaded (node_imports.py)
        "standing_in": "Deferred",
        "same": True,  # the stand-in reads the real module
        "logged": '{"event": "async.line"}',
    }
