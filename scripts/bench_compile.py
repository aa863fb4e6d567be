#!/usr/bin/env python3
"""Compiler stress test, after the paper's Section VIII-E.

Generates missions of growing size, compiles each in a fresh Python process
(so the peak memory is that mission's alone) and reports, per mission, the
number of drones and MEG nodes, the compile time of ``compile_mission``
(interpreter start-up and imports excluded) and the peak resident memory of
the process.

    python scripts/bench_compile.py            # a table
    python scripts/bench_compile.py --json     # a JSON list, one object per mission
    python scripts/bench_compile.py --json --mission missions/fleets/fleet100.go

The paper's figures: a 1-drone mission with a 34-node MEG compiled in 50 ms
and 4.4 MB; a 20-drone mission with more than 5000 MEG nodes in 2.34 s and
24 MB (Go).  Our target: the 5000-node mission in at most 0.5 s and 150 MB.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

# What the child process runs: warm up, compile once for time and peak memory,
# then once more phase by phase for the per-phase times.
_CHILD = r"""
import gc, json, sys, time
from pathlib import Path

def rss(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024.0
    return float("nan")

from eamos.compiler import compile_mission
from eamos.compiler.check import check_mission, drone_types
from eamos.compiler.dependency_graph import fleet, slice_dependency_graphs
from eamos.compiler.execution_graph import build_execution_graph
from eamos.compiler.instantiate import instantiate
from eamos.compiler.libraries import load_libraries
from eamos.compiler.mission_tree import build_mission_tree
from eamos.compiler.parse import parse_with_warnings
from eamos.compiler.synthesis import synthesize_program

text = open(sys.argv[1], encoding="utf-8").read()
compile_mission("func SEQ_W() {\n\tDrone1.Arm()\n}\n", "warmup.go")
gc.collect()
base = rss("VmRSS")
t0 = time.perf_counter()
compiled = compile_mission(text, sys.argv[1])
seconds = time.perf_counter() - t0
peak = rss("VmHWM")
meg_nodes = compiled.meg.number_of_nodes()
drones = len(compiled.programs) - 1
mdg_nodes = {d: g.number_of_nodes() for d, g in compiled.mdgs.items()}
del compiled
gc.collect()

phases = {}
t = time.perf_counter()
mission, _ = parse_with_warnings(text)
mission = load_libraries(mission, Path(sys.argv[1]).parent).mission
phases["parse_seconds"] = time.perf_counter() - t
t = time.perf_counter()
check_mission(mission)
phases["check_seconds"] = time.perf_counter() - t
t = time.perf_counter()
mission, _ = instantiate(mission)  # block copies, loops and groups written out
phases["expand_seconds"] = time.perf_counter() - t
t = time.perf_counter()
amt = build_mission_tree(mission)
phases["amt_seconds"] = time.perf_counter() - t
t = time.perf_counter()
meg = build_execution_graph(amt)
phases["meg_seconds"] = time.perf_counter() - t
t = time.perf_counter()
mdgs = slice_dependency_graphs(meg)
phases["slice_seconds"] = time.perf_counter() - t
t = time.perf_counter()
types = drone_types(mission)
everyone = fleet(meg)
for name, mdg in mdgs.items():
    synthesize_program(mdg, mission_id="bench", fleet=everyone,
                       drone_type=types[name].name if name in types else "")
phases["synthesis_seconds"] = time.perf_counter() - t

print(json.dumps({
    "drones": drones, "meg_nodes": meg_nodes, "seconds": round(seconds, 4),
    "peak_rss_mb": round(peak, 1), "baseline_rss_mb": round(base, 1),
    "largest_mdg_nodes": max(v for k, v in mdg_nodes.items() if k != "GCS"),
    **{k: round(v, 4) for k, v in phases.items()},
}))
"""


def single_drone_mission(actions: int = 33) -> str:
    """One drone, one sequence of ``actions`` actions: a MEG of ``actions + 1`` nodes."""
    moves = ["FlyByX(1)", "FlyByY(1)", "FlyByX(-1)", "FlyByY(-1)", "PauseFor(1)"]
    body = ["\tDrone1.Arm()", "\tDrone1.Takeoff(1.5)"]
    while len(body) < actions - 2:
        body.append(f"\tDrone1.{moves[len(body) % len(moves)]}")
    body += ["\tDrone1.Land()", "\tDrone1.Disarm()"]
    return "package Stress1\n\nfunc SEQ_Main() {\n" + "\n".join(body[:actions]) + "\n}\n"


def fleet_mission(drones: int, steps: int, actions: int = 12, groups: int = 4) -> str:
    """``drones`` drones flying ``steps`` rounds, shaped like the paper's stress test.

    Each round is a PAR block of ``groups`` nested PAR blocks, each holding one
    SEQ block of ``actions`` actions per drone of the group; between rounds one
    drone climbs alone, so every round waits for all drones of the last one.
    MEG nodes: about ``steps * (1 + groups + drones * actions + 1)``.
    """
    moves = [
        "FlyByX(1)",
        "FlyByY(1)",
        "FlyByX(-1)",
        "FlyByY(-1)",
        "PauseFor(1)",
        "FlyByZ(0.5)",
        "FlyByZ(-0.5)",
    ]
    names = [f"Drone{i}" for i in range(1, drones + 1)]
    per_group = -(-drones // groups)
    out = [f"package Stress{drones}x{steps}\n"]
    out += [f"var {n} Quadcopter" for n in names]
    main = ["func SEQ_Main() {"]
    for s in range(steps):
        main.append(f"\tPAR_Round{s}()")
        main.append(f"\t{names[s % drones]}.FlyByZ(0.5)")
    main.append("}")
    out += ["", *main]
    for s in range(steps):
        out += ["", f"func PAR_Round{s}() {{"]
        gs = [names[g * per_group : (g + 1) * per_group] for g in range(groups)]
        out += [f"\tPAR_Round{s}Group{g}()" for g, members in enumerate(gs) if members]
        out.append("}")
        for g, members in enumerate(gs):
            if not members:
                continue
            out += ["", f"func PAR_Round{s}Group{g}() {{"]
            out += [f"\tSEQ_Round{s}{n}()" for n in members]
            out.append("}")
            for n in members:
                out += ["", f"func SEQ_Round{s}{n}() {{"]
                out += [f"\t{n}.{moves[(s + a) % len(moves)]}" for a in range(actions)]
                out.append("}")
    return "\n".join(out) + "\n"


def cases() -> list[tuple[str, str]]:
    """The stress missions: name and text."""
    return [
        ("1 drone, 34-node MEG", single_drone_mission(33)),
        ("20 drones, ~5000 nodes", fleet_mission(20, steps=21)),
        ("20 drones, ~10000 nodes", fleet_mission(20, steps=41)),
        ("20 drones, ~20000 nodes", fleet_mission(20, steps=82)),
    ]


def measure(text: str, timeout: float = 600.0, folder: Path | None = None) -> dict[str, object]:
    """Compile ``text`` in a fresh interpreter and return its figures.

    ``folder``: where the mission's libraries are looked up first (its own folder).
    """
    with tempfile.NamedTemporaryFile(
        "w", suffix=".go", delete=False, encoding="utf-8", dir=folder
    ) as f:
        f.write(text)
        path = f.name
    try:
        env = {
            **os.environ,
            "PYTHONPATH": os.pathsep.join(
                p for p in (str(REPO), os.environ.get("PYTHONPATH", "")) if p
            ),
        }
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, path],
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            check=False,
        )
    finally:
        os.unlink(path)
    if done.returncode != 0:
        raise RuntimeError(f"the compile child failed:\n{done.stderr}")
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main(argv: list[str] | None = None) -> int:
    """Run the stress missions and print a table or (``--json``) a JSON list."""
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--json", action="store_true", help="print a JSON list")
    parser.add_argument("--quick", action="store_true", help="skip the 10000/20000-node missions")
    parser.add_argument("--write", metavar="DIR", help="also write the generated missions to DIR")
    parser.add_argument("--mission", metavar="FILE", help="measure this mission file instead")
    args = parser.parse_args(argv)
    selected = cases()[:2] if args.quick else cases()
    if args.mission:
        selected = [(Path(args.mission).name, Path(args.mission).read_text(encoding="utf-8"))]
    results = []
    for name, text in selected:
        if args.write:
            Path(args.write).mkdir(parents=True, exist_ok=True)
            slug = name.split(",")[0].replace(" ", "_") + f"_{text.count(chr(10))}lines.go"
            (Path(args.write) / slug).write_text(text, encoding="utf-8")
        figures = measure(text, folder=Path(args.mission).parent if args.mission else None)
        results.append(figures)
        if not args.json:
            f = figures
            print(
                f"{name:<26} {f['meg_nodes']:>6} MEG nodes  {f['seconds']:>7.3f} s  "
                f"{f['peak_rss_mb']:>6.1f} MB peak  (parse {f['parse_seconds']:.3f} s, "
                f"slice {f['slice_seconds']:.3f} s)",
                flush=True,
            )
    if args.json:
        print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
