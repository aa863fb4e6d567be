"""Suite-wide rules.

Skips: a test that needs a system tool (Graphviz, OpenSSH, iptables, root for
network namespaces, Chromium, node) skips with a visible reason on a laptop
without it.  CI installs every tool and sets ``EAMOS_NO_SKIP=1``: there, any
skip fails the run, so CI always runs everything.

Order: the tiers that start no process run first and the tests marked ``e2e``
(they fly in real time: ``eamos`` processes, simulated vehicles, namespaces,
SSH, a browser) last, so a broken compiler or node logic fails in seconds, not
after the flights; the real autopilots (``tests/sitl``) last of all.
``pytest -m "not e2e"`` runs only the first part (``.ci/run`` runs it, for the
computing tiers, on the other interpreters).

Parallel: the default options spread tests over every core
(``-n auto --dist loadgroup``, pytest-xdist).  Ports are ephemeral and
namespace names carry the worker's PID, so tests do not collide; tests that
share one expensive module or session fixture (the SSH lab, a browser, one
live run) carry an ``xdist_group`` mark and run on one worker.  ``-n 0`` runs
in this process, for a debugger.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# Hypothesis times every example on the wall clock (a 200 ms deadline, the too_slow health
# check): on a loaded machine (CI, parallel workers, other jobs) that fails tests whose logic
# is right.  Where the suite bounds work it measures CPU time (tests/compiler/hostile.py).
settings.register_profile("eamos", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("eamos")

#: The order in which the tiers run (the top-level entries of tests/): the ones without
#: processes first; then those whose real-time tests last longest, so that the parallel
#: workers finish together.  Unlisted entries run after the listed ones; tests marked e2e
#: run after every unmarked test whatever their tier.
TIERS = (
    "test_layering.py",
    "test_sizes.py",
    "test_docs_tables.py",
    "test_readme.py",
    "test_suite_rules.py",
    "test_config_toml.py",
    "compiler",
    "config",
    "check",
    "virtual",
    "lookahead",
    "actors",
    "startup",
    "lsp",
    "net",
    "cli",
    "plugins",
    "hal",
    "ground",
    "fleetops",
    "netfaults",
    "faults",
    "monitor",
    "e2e",
    "mavlink",
    "scale",
)
HERE = Path(__file__).parent


#: The tier that flies the real autopilots (tests/sitl).  Its vehicles miss heartbeats and
#: mode changes when the machine is far beyond its cores, so its tests run one after the
#: other on one worker (an ``xdist_group``), last: by then the other workers have little
#: left to do.  They fly in real time, so they are ``e2e`` too (``-m "not e2e"`` leaves
#: them out).
SITL_TIER = "sitl"


def _top(item: pytest.Item) -> str:
    try:
        return item.path.relative_to(HERE).parts[0]
    except ValueError:  # a test file outside tests/
        return ""


def _rank(item: pytest.Item) -> tuple[bool, bool, int]:
    top = _top(item)
    tier = TIERS.index(top) if top in TIERS else len(TIERS)
    return item.get_closest_marker("e2e") is not None, top == SITL_TIER, tier


# First: pytest-xdist's own hook reads the xdist_group marks (it names each test's group in
# its node id), so the SITL tier's group must be marked before it runs.
@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if _top(item) == SITL_TIER:
            item.add_marker(pytest.mark.e2e)
            item.add_marker(pytest.mark.xdist_group(SITL_TIER))
    # A stable sort: within a tier, tests keep the order pytest collected them in.  Every
    # xdist worker sorts the same way, so all report the same collection.
    items.sort(key=_rank)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if os.environ.get("EAMOS_NO_SKIP") != "1":
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = reporter.stats.get("skipped", []) if reporter is not None else []
    if skipped:
        for report in skipped:
            reason = (
                report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
            )
            print(f"\nEAMOS_NO_SKIP=1 but skipped: {report.nodeid}: {reason}")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


# Fixtures shared across test packages live in tests/support and load as a plugin, so no
# test ever imports a conftest; pytester runs the suite's own rules on a small suite.
pytest_plugins = ["tests.support.sim_fixtures", "pytester"]
