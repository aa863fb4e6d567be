"""The suite's own rules (tests/conftest.py, pyproject.toml): with ``EAMOS_NO_SKIP=1`` a
skipped test fails the run, also when pytest-xdist runs it on a worker process (the default
options); the tests of one ``xdist_group`` share one worker (and its module fixtures)."""

from __future__ import annotations

import pytest

from tests.support.runs import REPO

# The rule as the suite defines it, nothing else of tests/conftest.py.
CONFTEST = "from tests.conftest import pytest_sessionfinish  # noqa: F401\n"
TESTS = """
import pytest


def test_without_its_tool():
    pytest.skip("no such tool here")


def test_that_runs():
    pass
"""


def test_a_skip_fails_the_run_only_under_eamos_no_skip(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PYTHONPATH", str(REPO))
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_tools=TESTS)
    argv = ("-p", "no:cacheprovider")

    monkeypatch.setenv("EAMOS_NO_SKIP", "1")
    ci = pytester.runpytest_subprocess("-n", "1", *argv)  # the skip is reported by a worker
    assert ci.ret == pytest.ExitCode.TESTS_FAILED, ci.stdout.str()
    ci.stdout.fnmatch_lines(
        ["EAMOS_NO_SKIP=1 but skipped: test_tools.py::test_without_its_tool: *no such tool here"]
    )
    ci.assert_outcomes(passed=1, skipped=1)

    monkeypatch.delenv("EAMOS_NO_SKIP")
    laptop = pytester.runpytest_subprocess("-n", "0", *argv)
    assert laptop.ret == pytest.ExitCode.OK, laptop.stdout.str()
    laptop.assert_outcomes(passed=1, skipped=1)


GROUPED = """
import os

import pytest

pytestmark = pytest.mark.xdist_group("one-lab")


@pytest.mark.parametrize("i", range(6))
def test_in_the_group(i):
    with open({out!r}, "a") as f:
        f.write(os.environ["PYTEST_XDIST_WORKER"] + "\\n")
"""


def test_the_tests_of_one_xdist_group_share_one_worker(pytester: pytest.Pytester) -> None:
    # Ungrouped, two workers share six tests; pytest 9.2 with xdist 3.8 silently did that.
    out = pytester.path / "workers.txt"
    pytester.makepyfile(test_grouped=GROUPED.format(out=str(out)))
    result = pytester.runpytest_subprocess(
        "-n", "2", "--dist", "loadgroup", "-p", "no:cacheprovider"
    )
    result.assert_outcomes(passed=6)
    workers = out.read_text().split()
    assert len(workers) == 6 and len(set(workers)) == 1, workers
