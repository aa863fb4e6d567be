"""Fixtures of the SITL tier: real ArduCopter and PX4 vehicles, started fresh per test.

The tier skips, with its reason, where the SITL builds are absent (a user's fresh
clone); ``.ci/run`` points it at ``../shared/sitl`` and forbids skips.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from .flights import SitlFleet
from .sitl_vehicles import find_sitl, runnable_sitl, scratch_lock

SCRATCH = Path("/tmp/eamos-sitl-scratch")
#: The tier's processes (this worker, the vehicles and eamos processes it starts) run at
#: this nice value where the user may raise priority (root, as in CI).
SITL_NICE = -10


@pytest.fixture(scope="session", autouse=True)
def cpu_first() -> Iterator[None]:
    """The real autopilots first on the CPU: the tier runs last, on one worker, while the
    other workers finish their flights (tests/conftest.py), and a vehicle starved of CPU
    misses heartbeats and flies late (a PX4 flight took 32 s of vehicle time at a load
    of 3.4, 24-26 s on a quiet machine).  Threads and processes started from here on
    inherit the value; it is put back afterwards.  Elsewhere (not root) nothing changes."""
    before = os.getpriority(os.PRIO_PROCESS, 0)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, SITL_NICE)
    except PermissionError:
        yield
        return
    try:
        yield
    finally:
        os.setpriority(os.PRIO_PROCESS, 0, before)


@pytest.fixture(scope="session")
def sitl() -> Path:
    """The SITL folder, runnable (see sitl_vehicles.runnable_sitl); skips when absent."""
    folder, why = find_sitl()
    if folder is None:
        pytest.skip(why)
    with scratch_lock(SCRATCH):
        return runnable_sitl(folder, SCRATCH)


@pytest.fixture
def sitl_fleet(sitl: Path, tmp_path: Path) -> Iterator[Callable[..., SitlFleet]]:
    """``sitl_fleet({"Drone1": "px4", ...}, speedup=10)``: vehicles started, each in its
    own fresh folder under ``tmp_path``, killed by their pid after the test."""
    made: list[SitlFleet] = []

    def factory(drones: dict[str, str], speedup: float, **options: object) -> SitlFleet:
        fleet = SitlFleet.start(sitl, tmp_path, drones, speedup, **options)  # type: ignore[arg-type]
        made.append(fleet)
        return fleet

    yield factory
    for fleet in made:
        fleet.stop()
