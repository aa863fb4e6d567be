"""Suite-wide rules.

A test that needs a system tool (Graphviz, OpenSSH, iptables, root for network
namespaces) skips with a visible reason on a laptop without it.  CI installs
every tool and sets ``EAMOS_NO_SKIP=1``: there, any skip fails the run, so CI
always runs everything.
"""

from __future__ import annotations

import os

import pytest


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
# test ever imports a conftest.
pytest_plugins = ["tests.support.sim_fixtures"]
