"""scripts/bench_startup.py's pure parts (a whole run takes seconds: it is run by hand)."""

from __future__ import annotations

import os
import runpy
from pathlib import Path
from typing import Any

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_startup.py"


def bench() -> dict[str, Any]:
    """The script's names (its ``main`` not run)."""
    return runpy.run_path(str(SCRIPT), run_name="bench_startup")


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
    assert bench()["import_total_ms"](IMPORTTIME) == 4.3


def test_cpu_time_of_a_live_process_is_read_and_grows() -> None:
    cpu_ms_of = bench()["cpu_ms_of"]
    before = cpu_ms_of(os.getpid())
    if before is None:
        pytest.skip("no /proc/PID/stat on this system")
    assert sum(range(2_000_000)) > 0  # some CPU work (counted in clock ticks)
    after = cpu_ms_of(os.getpid())
    assert after is not None and after >= before > 0
    assert cpu_ms_of(2**22 + 12345) is None  # no such process
