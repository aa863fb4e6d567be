"""Fault tests on separate hosts: they need root, iproute2 and iptables.

Without them every test here is skipped with the reason shown (CI installs the
tools, runs as root, and fails on any skip).  Namespaces left by a crashed
earlier run are removed first; each fleet is torn down after its test, also
when it fails.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.support.netlab import cleanup_stale, lab_unavailable

from .netfault_helpers import LabFleet

REASON = lab_unavailable()
_fleet_ids = itertools.count()  # unique namespace names within this test session


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if REASON is None:
        return
    here = Path(__file__).parent
    for item in items:
        if here in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.skip(reason=f"fault tests on namespaces: {REASON}"))


@pytest.fixture(scope="session", autouse=True)
def _no_stale_namespaces() -> None:
    if REASON is None:
        cleanup_stale()


@pytest.fixture
def lab_fleet(tmp_path: Path) -> Iterator[Any]:
    made: list[LabFleet] = []

    def make(mission: Any, **kw: Any) -> LabFleet:
        fleet = LabFleet(tmp_path / f"f{len(made)}", mission, tag=str(next(_fleet_ids)), **kw)
        made.append(fleet)
        return fleet

    yield make
    for fleet in made:
        fleet.close()
