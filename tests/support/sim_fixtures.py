"""Fixtures for tests of simulated drones: adapters that are always closed (a pytest plugin)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from eamos.hal.sim.adapter import SimAdapter, SimSettings
from eamos.logs import close_logger, make_logger

SimFactory = Callable[..., SimAdapter]


@pytest.fixture
def make_sim(tmp_path: Path) -> Iterator[SimFactory]:
    """``make_sim(speedup=20, **settings)``: an unstarted SimAdapter logging to tmp_path.

    The adapter log goes to ``tmp_path / f"{drone}-adapter.log"``.
    """
    made: list[tuple[SimAdapter, Any]] = []

    def factory(drone: str = "D1", **settings: Any) -> SimAdapter:
        settings.setdefault("speedup", 20)
        log = make_logger(tmp_path / f"{drone}-adapter.log", drone=drone)
        adapter = SimAdapter(drone, SimSettings.from_mapping(settings), log)
        made.append((adapter, log))
        return adapter

    yield factory
    for adapter, log in made:
        adapter.close()
        close_logger(log)
