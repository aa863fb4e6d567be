"""scripts/bench_lsp.py measures what it says: a 2 000-line mission that compiles cleanly, and
latencies through a real server process (no figures are asserted: speed is for the script)."""

from __future__ import annotations

import asyncio
import importlib.util
import sys
from types import ModuleType

from eamos.compiler import compile_mission

from .lsp_helpers import REPO


def _bench() -> ModuleType:
    path = REPO / "scripts" / "bench_lsp.py"
    spec = importlib.util.spec_from_file_location("bench_lsp", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_lsp"] = module
    spec.loader.exec_module(module)
    return module


def test_the_generated_mission_has_2000_lines_and_compiles_cleanly() -> None:
    text = _bench().generated_mission()
    assert 1900 <= text.count("\n") <= 2000
    assert compile_mission(text, "big.go").warnings == ()


def test_each_edit_changes_one_character_and_gets_its_diagnostics() -> None:
    bench = _bench()
    text = (REPO / "missions" / "experiment_d.go").read_text(encoding="utf-8")
    edited = bench._edit(text, 1)
    assert len(edited) == len(text) and sum(a != b for a, b in zip(edited, text, strict=True)) == 1
    assert bench._edit(text, 2) == text
    times = asyncio.run(bench.over_stdio_ms(text, 2))
    assert len(times) == 2 and all(t > 0 for t in times)
