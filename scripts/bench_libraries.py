#!/usr/bin/env python3
"""What parameterised blocks and libraries cost the compiler: expansion vs. the same text by hand.

Compiles, in this process, a mission calling the standard library's
``shapes.SEQ_Orbit`` N times on D drones (each call with its own centre, so
each makes its own copy) and the same mission written out by hand (one
parameterless block per call, every argument a literal).  Both have the same
graphs; the difference is the price of importing, checking and expanding.

    python scripts/bench_libraries.py            # JSON, one object per size
"""

from __future__ import annotations

import gc
import json
import math
import sys
import time

from eamos.compiler import compile_mission

R = 0.7071067811865476


def generic(calls: int, drones: int) -> str:
    """A mission of ``calls`` orbits on ``drones`` drones, through the library."""
    body = "".join(f"\tshapes.SEQ_Orbit(D{i % drones}, {i}, 0, 4, 3)\n" for i in range(calls))
    return f'import "shapes"\n\nfunc SEQ_Main() {{\n{body}}}\n'


def by_hand(calls: int, drones: int) -> str:
    """The same mission with every call written out as its own block."""
    out = ["func SEQ_Main() {\n"]
    out += [f"\tSEQ_Orbit{i}()\n" for i in range(calls)]
    out.append("}\n")
    for i in range(calls):
        d = f"D{i % drones}"
        points = [
            (i + 4, 0),
            (i + 4 * R, 4 * R),
            (i, 4),
            (i - 4 * R, 4 * R),
            (i - 4, 0),
            (i - 4 * R, -4 * R),
            (i, -4),
            (i + 4 * R, -4 * R),
            (i + 4, 0),
        ]
        moves = "".join(f"\t{d}.FlyToXYZ({x!r}, {y!r}, 3)\n" for x, y in points)
        out.append(f"func SEQ_Orbit{i}() {{\n{moves}}}\n")
    return "".join(out)


def best_of(source: str, runs: int = 3) -> tuple[float, int]:
    """Fastest compile time of ``source`` in seconds, and its MEG node count."""
    times = []
    nodes = 0
    for _ in range(runs):
        gc.collect()
        start = time.perf_counter()
        compiled = compile_mission(source, "<mission>")
        times.append(time.perf_counter() - start)
        nodes = compiled.meg.number_of_nodes()
    return min(times), nodes


def main() -> int:
    rows = []
    for calls, drones in ((10, 2), (100, 5), (1000, 20), (4000, 20)):
        lib_s, lib_nodes = best_of(generic(calls, drones))
        hand_s, hand_nodes = best_of(by_hand(calls, drones))
        assert lib_nodes == hand_nodes, (lib_nodes, hand_nodes)
        rows.append(
            {
                "calls": calls,
                "drones": drones,
                "meg_nodes": lib_nodes,
                "library_s": round(lib_s, 4),
                "by_hand_s": round(hand_s, 4),
                "ratio": round(lib_s / hand_s, 2) if hand_s > 0 else math.nan,
            }
        )
    json.dump(rows, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
