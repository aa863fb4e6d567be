#!/usr/bin/env python3
"""How fast every console command answers ``--help`` and ``--version``; prints JSON.

Each command is started as a user starts it, its console script in this Python's
``bin`` folder (``eamos``, ``eamos-node``, ``eamos-sim-vehicle``; ``--python``
names another installation's interpreter, whose ``bin`` is used), ``--runs`` times
(default 7), alternating between the commands so that a busy moment of the machine
falls on all of them; the wall time from ``Popen`` to its exit is recorded.  The
first round is not counted (it fills the byte-code cache as a ``pip install`` would
have).  As a floor, the same interpreter doing nothing (``python -c pass``).

Then, once per command, what it imported: the same entry point run through
``python -c`` (``sys.argv`` as the console script sets it), printing which of the
heavy libraries (the compiler, networkx, tree-sitter, pygls, Starlette, matplotlib,
ZeroMQ, Pykka, structlog, rich) ended up in ``sys.modules``, and how many modules.

Printed::

    {"python": ..., "runs": 7, "loadavg": [...], "floor_ms": {...},
     "commands": {"eamos --version": {"median_ms": ..., "min_ms": ..., "max_ms": ...,
                                      "exit_code": 0, "modules": 128, "heavy": []}, ...}}

Timings belong in docs/performance.md (dated), not in tests: ``tests/cli`` asserts only
which modules ``--version`` and ``--help`` import.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: Modules a command's ``--help``/``--version`` should not need (the brief of issue 29).
HEAVY = (
    "eamos.compiler",
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

#: (console script, its entry point module:function, arguments).
COMMANDS = (
    ("eamos", "eamos.cli.main:main", ("--version",)),
    ("eamos", "eamos.cli.main:main", ("--help",)),
    ("eamos", "eamos.cli.main:main", ("lsp", "--help")),
    ("eamos", "eamos.cli.main:main", ("run", "--help")),
    ("eamos", "eamos.cli.main:main", ("check", "--help")),
    ("eamos-node", "eamos.cli.node:main", ("--help",)),
    ("eamos-node", "eamos.cli.node:main", ("--version",)),
    ("eamos-sim-vehicle", "eamos.cli.sim_vehicle:main", ("--version",)),
)

_PROBE = """\
import json, sys
sys.argv = {argv!r}
from {module} import {function}
try:
    {function}()
except SystemExit:
    pass
heavy = {heavy!r}
found = sorted(h for h in heavy if h in sys.modules)
sys.stderr.write("@@" + json.dumps({{"modules": len(sys.modules), "heavy": found}}) + "\\n")
"""


def wall_ms(argv: list[str]) -> tuple[float, int]:
    """Milliseconds from ``Popen`` to the exit of ``argv`` (its output thrown away), exit code."""
    started = time.perf_counter()
    proc = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return (time.perf_counter() - started) * 1000.0, proc.returncode


def imported(python: str, script: str, entry: str, args: tuple[str, ...]) -> dict[str, object]:
    """Which heavy modules the entry point imported for ``args``, and how many modules."""
    module, function = entry.split(":")
    code = _PROBE.format(argv=[script, *args], module=module, function=function, heavy=HEAVY)
    proc = subprocess.run(
        [python, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    line = [ln for ln in proc.stderr.splitlines() if ln.startswith("@@")]
    if not line:
        raise SystemExit(f"{script} {' '.join(args)}: no probe output: {proc.stderr[-500:]}")
    result: dict[str, object] = json.loads(line[-1][2:])
    return result


def summary(times: list[float]) -> dict[str, float]:
    return {
        "median_ms": round(statistics.median(times), 1),
        "min_ms": round(min(times), 1),
        "max_ms": round(max(times), 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=7, help="timed runs per command (7)")
    parser.add_argument(
        "--python", default=sys.executable, help="the interpreter of the installation to time"
    )
    args = parser.parse_args()
    python = str(Path(args.python).absolute())
    bin_dir = Path(python).parent
    names = [f"{script} {' '.join(a)}" for script, _, a in COMMANDS]
    argvs = [[str(bin_dir / script), *a] for script, _, a in COMMANDS]
    for argv in argvs:
        if not Path(argv[0]).is_file():
            raise SystemExit(f"{argv[0]}: no such console script (pip install -e . first)")
    floor = [python, "-c", "pass"]
    times: dict[str, list[float]] = {name: [] for name in [*names, "python -c pass"]}
    codes: dict[str, int] = {}
    for round_ in range(args.runs + 1):
        for name, argv in [*zip(names, argvs, strict=True), ("python -c pass", floor)]:
            ms, codes[name] = wall_ms(argv)
            if round_:  # the first round warms the caches
                times[name].append(ms)
    commands: dict[str, dict[str, object]] = {}
    for name, (script, entry, a) in zip(names, COMMANDS, strict=True):
        commands[name] = {
            **summary(times[name]),
            "exit_code": codes[name],  # 0; 2 where the option does not exist
            **imported(python, script, entry, a),
        }
    print(
        json.dumps(
            {
                "python": python,
                "version": sys.version.split()[0],
                "runs": args.runs,
                "loadavg": [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]
                if os.path.exists("/proc/loadavg")
                else None,
                "floor_ms": summary(times["python -c pass"]),
                "commands": commands,
            },
            indent=1,
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
