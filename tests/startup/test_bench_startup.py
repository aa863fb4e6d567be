"""scripts/bench_startup.py's pure parts (a whole run takes seconds: it is run by hand)."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_startup.py"


def bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_startup", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_startup"] = module
    spec.loader.exec_module(module)
    return module


IMPORTTIME = """\
import time: self [us] | cumulative | imported package
import time:       100 |        100 |   _io
import time:       200 |        300 | io
bench_startup 1.0 2.0
import time:        50 |       1000 |     structlog.dev
import time:        10 |       2500 |   structlog
import time:        40 |       4000 | eamos.cli.node
"""


def test_import_total_sums_the_top_level_entries_only() -> None:
    assert bench().import_total_ms(IMPORTTIME) == 4.3


def test_cpu_time_of_a_live_process_is_read_and_grows() -> None:
    module = bench()
    before = module.cpu_ms_of(os.getpid())
    if before is None:
        pytest.skip("no /proc/PID/stat on this system")
    assert sum(range(2_000_000)) > 0  # some CPU work (counted in clock ticks)
    after = module.cpu_ms_of(os.getpid())
    assert after is not None and after >= before > 0
    assert module.cpu_ms_of(2**22 + 12345) is None  # no such process
