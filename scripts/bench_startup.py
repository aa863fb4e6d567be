#!/usr/bin/env python3
"""Benchmark of one ``eamos-node``'s start-up: process start to its Ready held; prints JSON.

Each run writes a one-drone fleet (a two-action mission, fresh CURVE keys, a
config per participant: :func:`tests.support.netlab.write_fleet`), starts the
ground station's runtime in this process (:func:`eamos.ground.flight.ground_runtime`,
a real Out-/In-Bridge with ZAP), then times a real ``python -m eamos.cli.node
--config D1.toml`` (simulated adapter) from just before ``Popen`` until
:meth:`GroundStation.wait_ready` returns: the drone's Ready is held and the drone
subscribes to the ground station.  The mission is then flown to its end (so every
run also checks the node works) and the process is waited for.

The interpreter reads byte-code from a private cache (``PYTHONPYCACHEPREFIX`` in a
temporary folder, ``PYTHONDONTWRITEBYTECODE`` unset): a first run, not counted,
fills it, as a ``pip install`` would have.

The node is started as its console script does (``main()`` of :mod:`eamos.cli.node`),
through ``python -c`` with two wall-clock stamps on stderr: on entry, before any
import, and once ``eamos.cli.node`` is imported.

Printed per run set (``--runs N``, default 7): ``ready_ms`` median, min and max, and
the median of each phase over the runs (``phases_ms``), from those stamps and the node's
own log (``ts`` of ``mission.runtime.started`` with its ``seconds``, ``ts`` of
``mission.ready``):

* ``interpreter``: ``Popen`` to the entry stamp (the interpreter and ``site``);
* ``imports``: what ``import eamos.cli.node`` loads;
* ``before_runtime``: then to the start of the runtime's build: argument parsing, the
  config, the keys, the program, the adapter and what they import on first use (the
  simulator, plugin discovery);
* ``runtime_build``: the runtime's build (``mission.runtime.started``'s ``seconds``:
  sockets, CURVE, actors, the in-bridge's connections);
* ``node_up``: ``Popen`` to the runtime built, the sum of the above (all the node controls);
* ``ready_wait``: from then until the node sent Ready: every destination subscribed,
  i.e. the ground station's in-bridge connected to this node (ZeroMQ retries a refused
  connection after 100 ms, then doubling to at most 1 s: the ground station, started
  first, retries at about 0.1, 0.3, 0.7 s after its start, so ``ready_ms`` comes in
  those steps);
* ``ground``: from the node's Ready to the ground station holding it.

``node_cpu_ms_at_ready``: the CPU time the node process had used when its Ready was
held (``/proc/PID/stat``, in clock ticks of 10 ms): less disturbed by a busy machine
than the wall times.

Also ``importtime_total_ms``: the ``-X importtime`` total of everything a real node
imports, at start and later (top-level entries summed, one extra run; the tracing
inflates it), ``modules``: how many modules ``import eamos.cli.node`` loads, and
which of the parts a drone's node must not carry (:data:`NOT_ON_THE_NODE`: the
compiler, the ground station, the language server, the monitor's web server and the
libraries only they use) are among them (``not_on_the_node``: none expected).

``floor_ms``, in the same run and environment, the medians of a process doing
nothing (``python -c pass``) and of one importing only the
libraries a node cannot do without (pyzmq, pykka, msgpack, tomllib and structlog),
each from ``Popen`` to a stamp written as its last statement; and
``node_beyond_libraries_ms``: ``ready_ms``'s median minus the latter, what this
project's own code, configuration and start-up cost.

``--python PATH`` runs the node (and the floors) with another interpreter: a
venv where eamos is installed as on a drone (``pip install .``, not editable:
an editable install adds its import finder to every start-up).

Usage: ``python scripts/bench_startup.py --json [--runs 7] [--python PATH]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # tests.support.netlab

MISSION = """\
func SEQ_Startup() {
\tD1.Arm()
\tD1.Disarm()
}
"""
#: The node's entry: what the ``eamos-node`` console script runs, with two stamps.
ENTRY = (
    "import sys, time; entered = time.time(); import eamos.cli.node as node; "
    "sys.stderr.write(f'bench_startup {entered} {time.time()}\\n'); "
    "sys.exit(node.main(sys.argv[1:]))"
)
STAMP = "bench_startup "
#: The phases of ``phases_ms``, in order.
PHASES = (
    "interpreter",
    "imports",
    "before_runtime",
    "runtime_build",
    "node_up",
    "ready_wait",
    "ground",
)
#: Parts a drone's node does not carry (tests/startup/test_node_imports.py checks the same).
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
READY_TIMEOUT_S = 60.0
#: The floors (see the docstring): an empty process, and the libraries alone.
FLOORS = {
    "interpreter": "pass",
    "libraries": "import structlog, zmq, pykka, msgpack, tomllib",
}


class Quiet:
    """A display for :func:`eamos.ground.fly` that shows nothing (the JSON is the output)."""

    refresh_s = 0.5

    def __enter__(self) -> Quiet:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def watch(self, station: Any) -> None:
        return None

    def event(self, name: str, view: Any, msg: Any) -> None:
        return None

    def refresh(self) -> None:
        return None

    def say(self, text: str) -> None:
        return None


def child_env(cache: Path) -> dict[str, str]:
    """The node's environment: byte-code read from (and written to) ``cache``."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = str(cache)
    return env


def log_event(path: Path, event: str) -> dict[str, Any] | None:
    """The first line of JSON-lines log ``path`` whose event is ``event``."""
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError:
        return None
    for line in lines:
        if f'"{event}"' in line:
            data: dict[str, Any] = json.loads(line)
            if data.get("event") == event:
                return data
    return None


def one_run(
    work: Path,
    env: dict[str, str],
    ports: list[int],
    python_args: tuple[str, ...] = (),
    python: str = sys.executable,
) -> dict[str, Any]:
    """Start one node against a ground station here; its times (ms), exit code and stderr.

    ``python_args`` go to the node's interpreter ``python`` (``-X importtime``).
    """
    from eamos.actors.drone import net_settings
    from eamos.compiler import compile_mission
    from eamos.config import NodeConfig
    from eamos.ground import GroundStation
    from eamos.ground.flight import Limits, fly, ground_runtime
    from eamos.program.uniform import GROUND_STATION
    from tests.support.netlab import write_fleet

    compiled = compile_mission(MISSION, "startup.go")
    bind = {GROUND_STATION: f"tcp://127.0.0.1:{ports[0]}", "D1": f"tcp://127.0.0.1:{ports[1]}"}
    files = write_fleet(compiled.programs, work, bind, hal={"D1": {"adapter": "sim"}})
    gcs = NodeConfig.load(files.configs[GROUND_STATION])
    program = compiled.programs[GROUND_STATION]
    station = GroundStation(["D1"], program.mission_id)
    runtime = ground_runtime(program, station, net_settings(gcs), gcs.log_dir, gcs.hal)
    stop = threading.Event()
    proc = None
    held, ready_ms, held_wall, wall0, cpu_ms = False, 0.0, 0.0, 0.0, None
    err_path = work / "node.stderr"
    try:
        runtime.start()
        station.attach(runtime)
        argv = [python, *python_args, "-c", ENTRY, "--config", str(files.configs["D1"])]
        with err_path.open("wb") as err_file:
            wall0 = time.time()
            t0 = time.monotonic()
            proc = subprocess.Popen(
                argv,
                env=env,
                cwd=work,  # not the checkout: ``-c`` puts the folder first on sys.path
                stdout=subprocess.DEVNULL,
                stderr=err_file,
            )
        held = station.wait_ready(READY_TIMEOUT_S, stop)
        ready_ms = (time.monotonic() - t0) * 1000
        held_wall = time.time()
        cpu_ms = cpu_ms_of(proc.pid)
        fly(station, Quiet(), stop, Limits(READY_TIMEOUT_S, 120.0))  # type: ignore[arg-type]
    finally:
        runtime.stop()
        code = None
        if proc is not None:
            try:
                code = proc.wait(timeout=120)
            except subprocess.TimeoutExpired:  # a hung node: not left behind
                proc.kill()
                code = proc.wait()
    err = err_path.read_text(errors="replace") if err_path.exists() else ""
    mission_log = files.log_dirs["D1"] / "mission.log"
    started = log_event(mission_log, "mission.runtime.started")
    ready = log_event(mission_log, "mission.ready")
    out: dict[str, Any] = {
        "held": held,
        "ready_ms": ready_ms,
        "cpu_ms": cpu_ms,
        "exit_code": code,
        "stderr": err,
    }
    stamps = [line.split()[1:] for line in err.splitlines() if line.startswith(STAMP)]
    if started is not None and ready is not None and stamps:
        entered, imported = (float(t) for t in stamps[0])
        build_s = float(started["seconds"])
        build_start = float(started["ts"]) - build_s
        out["phases_ms"] = {
            "interpreter": (entered - wall0) * 1000,
            "imports": (imported - entered) * 1000,
            "before_runtime": (build_start - imported) * 1000,
            "runtime_build": build_s * 1000,
            "node_up": (float(started["ts"]) - wall0) * 1000,
            "ready_wait": (float(ready["ts"]) - float(started["ts"])) * 1000,
            "ground": (held_wall - float(ready["ts"])) * 1000,
        }
    return out


def cpu_ms_of(pid: int) -> float | None:
    """CPU time (user + system, ms) process ``pid`` used so far (Linux; None elsewhere)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    # utime and stime are fields 14 and 15 of stat(5), counted after the ")" from 3.
    return (int(fields[11]) + int(fields[12])) * 1000 / os.sysconf("SC_CLK_TCK")


def import_total_ms(stderr: str) -> float:
    """The total (ms) of the top-level entries of ``-X importtime`` lines in ``stderr``."""
    total_us = 0
    for line in stderr.splitlines():
        # "import time: self [us] | cumulative | imported package"; a top-level entry
        # has exactly one space of indent before its name.
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        name = line.rsplit("|", 1)[1]
        if not name.startswith("  "):
            total_us += int(line.split("|")[1])
    return total_us / 1000


def stamped_ms(argv: list[str], env: dict[str, str]) -> float:
    """Wall time (ms) from starting ``argv`` to the time it prints (its last statement)."""
    wall0 = time.time()
    done = subprocess.run(
        argv, env=env, check=True, timeout=120, capture_output=True, cwd=tempfile.gettempdir()
    )
    return (float(done.stdout) - wall0) * 1000


def floor_ms(env: dict[str, str], runs: int, python: str = sys.executable) -> dict[str, float]:
    """Median wall time (ms) from ``Popen`` to the last statement of each of :data:`FLOORS`."""
    out = {}
    for name, code in FLOORS.items():
        argv = [python, "-c", f"{code}\nimport time; print(time.time())"]
        stamped_ms(argv, env)  # fills the byte-code cache
        out[name] = round(statistics.median(stamped_ms(argv, env) for _ in range(runs)), 1)
    return out


def loaded_modules(env: dict[str, str], python: str = sys.executable) -> list[str]:
    """The modules loaded by ``import eamos.cli.node`` in a fresh interpreter."""
    code = "import sys, json, eamos.cli.node; print(json.dumps(sorted(sys.modules)))"
    proc = subprocess.run(
        [python, "-c", code],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tempfile.gettempdir(),
    )
    return list(json.loads(proc.stdout))


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the default)")
    parser.add_argument("--runs", type=int, default=7, help="timed runs (default 7)")
    parser.add_argument(
        "--python",
        default=sys.executable,
        help="the node's interpreter (default this one): e.g. a venv where eamos is "
        "installed as a drone has it (pip install, not editable)",
    )
    args = parser.parse_args()
    from eamos.ground import free_ports

    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="bench_startup-") as tmp:
        env = child_env(Path(tmp) / "pycache")
        for i in range(args.runs + 1):  # run 0 fills the byte-code cache
            result = one_run(Path(tmp) / f"run-{i}", env, free_ports(2), python=args.python)
            if i > 0:
                runs.append(result)
        traced = one_run(
            Path(tmp) / "importtime", env, free_ports(2), ("-X", "importtime"), args.python
        )
        traced_ms = import_total_ms(traced["stderr"])
        modules = loaded_modules(env, args.python)
        floors = floor_ms(env, args.runs, args.python)
    ok = [r for r in runs if r["held"] and r["exit_code"] == 0]
    for r in runs:
        r["stderr"] = r["stderr"].strip()[-500:]
    times = sorted(r["ready_ms"] for r in ok)
    cpu = sorted(r["cpu_ms"] for r in ok if r["cpu_ms"] is not None)
    phased = [r["phases_ms"] for r in ok if "phases_ms" in r]
    phases = (
        {p: round(statistics.median(x[p] for x in phased), 1) for p in PHASES} if phased else None
    )
    report = {
        "runs": len(runs),
        "ok_runs": len(ok),
        "ready_ms": {
            "median": round(statistics.median(times), 1) if times else None,
            "min": round(times[0], 1) if times else None,
            "max": round(times[-1], 1) if times else None,
        },
        "node_cpu_ms_at_ready": {
            "median": round(statistics.median(cpu), 1) if cpu else None,
            "min": round(cpu[0], 1) if cpu else None,
        },
        "phases_ms": phases,
        "floor_ms": floors,
        "node_beyond_libraries_ms": (
            round(statistics.median(times) - floors["libraries"], 1) if times else None
        ),
        "importtime_total_ms": round(traced_ms, 1),
        "modules": len(modules),
        "not_on_the_node": [
            n for n in NOT_ON_THE_NODE if any(m == n or m.startswith(n + ".") for m in modules)
        ],
        "failures": [r for r in runs if r not in ok],
    }
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
