"""Do the issue-16 tests fail against the old MAVLink adapter?  (Issue 16, item 7; not CI.)

"The tests for 1-6 must fail against today's adapter and pass against the new
one."  This script makes that reproducible: it copies the working tree twice
into a temporary directory, puts the MAVLink adapter of ``--old`` (default
``dce376d^``, the commit before issue 16 was built) into one copy, and runs
the same tests in both copies with the same interpreter (``PYTHONPATH`` points
at the copy, so ``eamos`` and every ``eamos-*`` subprocess load it, not the
editable install).  Only the modules the old adapter had are replaced; modules
it did not have stay (the simulated vehicle and ``eamos keys`` import
``eamos.hal.mavlink.signing``), and nothing else changes: the simulated
vehicle (``eamos/hal/sitl``) is today's, the one that fails the way real
autopilots did.

It prints JSON: for each test id, its outcome against the old and the new
adapter, and the lists ``fail_old_pass_new`` (what the issue asks for),
``pass_both`` (tests that cannot tell the adapters apart, e.g. tests of the
simulated vehicle alone), ``fail_both`` and ``pass_old_fail_new``.

    .venv/bin/python scripts/old_adapter_check.py --json
    .venv/bin/python scripts/old_adapter_check.py --json -- tests/mavlink/test_mavlink_estimator.py
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ADAPTER_DIR = "eamos/hal/mavlink"
#: The tests written for issue 16 (items 1-6), and the ones added for it later.
ISSUE_16_TESTS = (
    "tests/mavlink/test_mavlink_real_autopilots.py",
    "tests/mavlink/test_mavlink_tuning_units.py",
    "tests/mavlink/test_mavlink_units.py",
    "tests/mavlink/test_mavlink_vehicle_death.py",
    "tests/mavlink/test_mavlink_signing.py",
    "tests/mavlink/test_mavlink_estimator.py",
    "tests/mavlink/test_sitl_realism.py",
    "tests/mavlink/test_hybrid_run.py",
    "tests/e2e/test_mavlink_braking.py",
)


def _git(*args: str) -> str:
    return subprocess.run(
        ["git", "-C", str(REPO), *args], check=True, capture_output=True, text=True
    ).stdout


def copy_tree(dest: Path) -> None:
    """The working tree (tracked and untracked, not ignored files) copied to ``dest``."""
    listed = _git("ls-files", "-z", "--cached", "--others", "--exclude-standard")
    for rel in filter(None, listed.split("\0")):
        src = REPO / rel
        if not src.is_file():
            continue  # deleted in the working tree
        target = dest / rel
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target)


def install_old_adapter(dest: Path, old: str) -> list[str]:
    """Replace the adapter modules that existed at ``old`` with their old text; the names."""
    names = _git("ls-tree", "--name-only", old, f"{ADAPTER_DIR}/").split()
    for rel in names:
        text = subprocess.run(
            ["git", "-C", str(REPO), "show", f"{old}:{rel}"],
            check=True,
            capture_output=True,
        ).stdout
        (dest / rel).write_bytes(text)
    return names


def run_tests(tree: Path, tests: list[str], report: Path) -> dict[str, str]:
    """Run ``tests`` inside ``tree``; outcome by test id (passed, failed, error, skipped)."""
    env = dict(os.environ, PYTHONPATH=str(tree), PYTHONDONTWRITEBYTECODE="1")
    present = [t for t in tests if (tree / t.split("::")[0]).exists()]
    if not present:
        return {}
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-o",
            "addopts=",
            f"--junitxml={report}",
            *present,
        ],
        cwd=tree,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        check=False,
    )
    return parse_junit(report)


def parse_junit(report: Path) -> dict[str, str]:
    """pytest's JUnit XML as {test id: outcome}."""
    if not report.exists():
        return {}
    outcomes: dict[str, str] = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        module = case.get("classname", "")
        parts = module.split(".")
        # classname is "tests.mavlink.test_x" or "tests.mavlink.test_x.TestClass".
        for cut in range(len(parts), 0, -1):
            path = "/".join(parts[:cut]) + ".py"
            if (REPO / path).exists() or cut == 1:
                test_id = "::".join([path, *parts[cut:], case.get("name", "")])
                break
        outcome = "passed"
        for child in case:
            if child.tag in ("failure", "error"):
                outcome = "failed" if child.tag == "failure" else "error"
            elif child.tag == "skipped":
                outcome = "skipped"
        outcomes[test_id] = outcome
    return outcomes


def compare(old: dict[str, str], new: dict[str, str]) -> dict[str, list[str]]:
    """Tests sorted by (old outcome, new outcome) (pure)."""
    groups: dict[str, list[str]] = {
        "fail_old_pass_new": [],
        "pass_both": [],
        "fail_both": [],
        "pass_old_fail_new": [],
        "skipped_or_missing": [],
    }
    for test_id in sorted(set(old) | set(new)):
        before, after = old.get(test_id, "missing"), new.get(test_id, "missing")
        bad_before = before in ("failed", "error", "missing")
        if before == "skipped" or after in ("skipped", "missing"):
            groups["skipped_or_missing"].append(test_id)
        elif bad_before and after == "passed":
            groups["fail_old_pass_new"].append(test_id)
        elif before == "passed" and after == "passed":
            groups["pass_both"].append(test_id)
        elif before == "passed":
            groups["pass_old_fail_new"].append(test_id)
        else:
            groups["fail_both"].append(test_id)
    return groups


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", default="dce376d^", help="commit of the old adapter")
    parser.add_argument("--json", action="store_true", help="print JSON (the only output)")
    parser.add_argument("--keep", action="store_true", help="keep the temporary copies")
    parser.add_argument("tests", nargs="*", help="test files or ids (default: issue 16's)")
    args = parser.parse_args(argv)
    tests = args.tests or list(ISSUE_16_TESTS)
    work = Path(tempfile.mkdtemp(prefix="eamos-old-adapter-"))
    began = time.monotonic()
    try:
        old_tree, new_tree = work / "old", work / "new"
        copy_tree(old_tree)
        copy_tree(new_tree)
        replaced = install_old_adapter(old_tree, args.old)
        old = run_tests(old_tree, tests, work / "old.xml")
        new = run_tests(new_tree, tests, work / "new.xml")
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    groups = compare(old, new)
    result = {
        "old": args.old,
        "old_commit": _git("rev-parse", args.old).strip(),
        "replaced": replaced,
        "tests": tests,
        "seconds": round(time.monotonic() - began, 1),
        "counts": {k: len(v) for k, v in groups.items()},
        **groups,
        "outcomes": {
            t: {"old": old.get(t, "missing"), "new": new.get(t, "missing")}
            for t in sorted(set(old) | set(new))
        },
        "kept": str(work) if args.keep else None,
    }
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
