#!/usr/bin/env python3
"""Benchmark of ``eamos lsp``: how soon an edit's diagnostics reach the editor; prints JSON.

For experiment D and for a generated mission of about 2 000 lines: a real client
(pygls) starts ``python -m eamos.cli lsp`` over stdio, opens the mission, then makes
one-character edits (a digit changed back and forth) and times each from sending
``didChange`` to receiving its ``publishDiagnostics``.  The server publishes the checking
phases' findings at once and the whole compile's after it (see eamos/lsp/server.py); the figures
also give both in this process, without the protocol (``checked_findings``, ``findings``).
Targets: under 100 ms for experiment D, under 300 ms for the 2 000-line mission.

Usage: ``python scripts/bench_lsp.py --json [--edits N]``.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

from lsprotocol import types as lsp
from pygls.lsp.client import LanguageClient

from eamos.lsp import checked_findings, findings

REPO = Path(__file__).resolve().parents[1]
TARGETS_MS = {"experiment_d": 100.0, "generated_2000_lines": 300.0}


def generated_mission(lines: int = 2000, drones: int = 10) -> str:
    """A mission of about ``lines`` lines: drones taking turns through many PAR/SEQ blocks."""
    out = [f"var D{i} Quadcopter" for i in range(1, drones + 1)]
    out += ["", "func SEQ_Main() {"]
    out += [f"\tD{i}.Arm()" for i in range(1, drones + 1)]
    out += ["\tPAR_Up()"]
    steps = max(1, (lines - len(out) - 2 * drones - 10) // (drones + 4))
    out += [f"\tPAR_Step{s}()" for s in range(steps)]
    out += ["}", "", "func PAR_Up() {"]
    out += [f"\tD{i}.Takeoff(1.5)" for i in range(1, drones + 1)]
    out += ["}"]
    for s in range(steps):
        out += ["", f"func PAR_Step{s}() {{"]
        out += [f"\tD{i}.FlyByX({1 + (s + i) % 3})" for i in range(1, drones + 1)]
        out += ["}"]
    return "\n".join(out) + "\n"


def _edit(text: str, n: int) -> str:
    """The text after the ``n``-th one-character edit: the first '(1)' becomes '(2)' and back."""
    return text.replace("(1)", "(2)", 1) if n % 2 else text


def in_process_ms(text: str, edits: int, analyse: Callable[[str], object]) -> float:
    """Median milliseconds of ``analyse`` after each edit, in this process."""
    times = []
    for n in range(1, edits + 1):
        edited = _edit(text, n)
        t0 = time.perf_counter()
        analyse(edited)
        times.append((time.perf_counter() - t0) * 1000)
    return statistics.median(times)


async def over_stdio_ms(text: str, edits: int) -> list[float]:
    """Milliseconds from each didChange to its diagnostics, through a real server process."""
    client = LanguageClient("eamos-bench", "1")
    waiting: dict[int, asyncio.Future[float]] = {}

    @client.feature(lsp.TEXT_DOCUMENT_PUBLISH_DIAGNOSTICS)
    def on_diagnostics(params: lsp.PublishDiagnosticsParams) -> None:
        future = waiting.get(params.version or 0)
        if future is not None and not future.done():
            future.set_result(time.perf_counter())

    await client.start_io(sys.executable, "-m", "eamos.cli", "lsp")
    await client.initialize_async(lsp.InitializeParams(capabilities=lsp.ClientCapabilities()))
    client.initialized(lsp.InitializedParams())
    uri = "file:///bench/mission.go"
    loop = asyncio.get_running_loop()
    waiting[1] = loop.create_future()
    client.text_document_did_open(
        lsp.DidOpenTextDocumentParams(lsp.TextDocumentItem(uri, "eamos", 1, text))
    )
    await asyncio.wait_for(waiting[1], 120)
    times = []
    for n in range(1, edits + 1):
        version = n + 1
        waiting[version] = loop.create_future()
        t0 = time.perf_counter()
        client.text_document_did_change(
            lsp.DidChangeTextDocumentParams(
                lsp.VersionedTextDocumentIdentifier(version, uri),
                [lsp.TextDocumentContentChangeWholeDocument(_edit(text, n))],
            )
        )
        t1 = await asyncio.wait_for(waiting[version], 120)
        times.append((t1 - t0) * 1000)
    await client.shutdown_async(None)
    client.exit(None)
    await client.stop()
    return times


def measure(name: str, text: str, edits: int) -> dict[str, object]:
    """Latency figures for one mission."""
    stdio = asyncio.run(over_stdio_ms(text, edits))
    median = statistics.median(stdio)
    return {
        "lines": text.count("\n"),
        "diagnostics": len(findings(text)),
        "edits": edits,
        "stdio_median_ms": round(median, 1),
        "stdio_p90_ms": round(sorted(stdio)[int(0.9 * (len(stdio) - 1))], 1),
        "stdio_max_ms": round(max(stdio), 1),
        "in_process_checked_median_ms": round(in_process_ms(text, edits, checked_findings), 1),
        "in_process_whole_compile_median_ms": round(in_process_ms(text, edits, findings), 1),
        "target_ms": TARGETS_MS[name],
        "within_target": median < TARGETS_MS[name],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print JSON (the only output)")
    parser.add_argument("--edits", type=int, default=21, help="one-character edits per mission")
    args = parser.parse_args()
    missions = {
        "experiment_d": (REPO / "missions" / "experiment_d.go").read_text(encoding="utf-8"),
        "generated_2000_lines": generated_mission(),
    }
    result = {name: measure(name, text, args.edits) for name, text in missions.items()}
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
