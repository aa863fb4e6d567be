"""Fixtures of the SITL tier: real ArduCopter and PX4 vehicles, started fresh per test.

The tier skips, with its reason, where the SITL builds are absent (a user's fresh
clone); ``.ci/run`` points it at ``../shared/sitl`` and forbids skips.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from .flights import SitlFleet
from .sitl_vehicles import find_sitl, runnable_sitl, scratch_lock

SCRATCH = Path("/tmp/eamos-sitl-scratch")


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
