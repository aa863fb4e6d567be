"""An amendment checked from the monitor page, in a real browser (Debian's chromium).

``tests/operator/four_lanes.go`` with ``--monitor``, paused while every drone flies its
first leg; the page's Amendment section uploads a new text of the mission and shows how
``eamos amend`` judges it: a change to Drone3's and Drone4's later legs is accepted (the
running nodes it touches outlined on the graphs; staged in the run folder), Drone1 and
Drone2 sent at each other is refused with the separation finding at the new lines.
Nothing is applied: resumed, the run flies the mission as written.  The screenshot is
``docs/monitor-amend.png``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from eamos.compiler import compile_file
from tests.monitor.live import URL, ended_ok, start_live_run
from tests.monitor.test_browser import FINAL_WORDS, SCREENSHOT, browser, mission_state, wait_until
from tests.operator.runs import operator
from tests.support.four_lanes import HEAD_ON, LANES, LATER_PARTS, amended, line_of

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-browser")]

__all__ = ["browser"]  # the fixture, shared with test_browser

from selenium.webdriver.common.by import By  # noqa: E402

AMEND_SHOT = SCREENSHOT.with_name("monitor-amend.png")


def check(driver: Any, path: Path) -> dict[str, Any]:
    """Upload ``path`` in the Amendment section and press Check: the verdict, the report's
    text and the graph nodes outlined as touched."""
    driver.execute_script("document.getElementById('amend-report').dataset.verdict = ''")
    driver.find_element(By.ID, "amend-file").send_keys(str(path))
    wait_until(driver, lambda d: d.find_element(By.ID, "amend-check").is_enabled(), 30)
    button = driver.find_element(By.ID, "amend-check")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'})", button)
    button.click()
    verdicts = ("accepted", "refused", "bad")
    wait_until(driver, lambda d: d.find_element(By.ID, "amend-report").get_attribute(
        "data-verdict") in verdicts, 120)  # fmt: skip
    return dict(
        driver.execute_script(
            """const r = document.getElementById('amend-report');
            return {verdict: r.dataset.verdict, text: r.textContent,
                    touched: [...document.querySelectorAll('#graphs g.node.amended')]
                      .map((g) => g.dataset.node)};"""
        )
    )


def test_the_page_checks_an_amendment_against_the_paused_run(tmp_path: Path, browser: Any) -> None:
    later, head_on = tmp_path / "later.go", tmp_path / "head_on.go"
    later.write_text(amended(*LATER_PARTS))
    head_on.write_text(amended(*HEAD_ON))
    run = start_live_run(tmp_path, LANES, speedup=1)
    try:
        browser.get(run.wait_for(URL).group(1))
        for drone in ("Drone1", "Drone2", "Drone3", "Drone4"):
            run.wait_for(re.compile(rf"{drone} running +FlyByX\(12\)"), 120)
        operator("pause", str(tmp_path / "run"))
        wait_until(browser, lambda d: mission_state(d) == "paused", 60)
        seen = check(browser, later)
        assert seen["verdict"] == "accepted", seen
        assert "Drone3: switches at" in seen["text"] and "Drone4: switches at" in seen["text"]
        assert "not touched (not interrupted): GCS, Drone1, Drone2" in seen["text"], seen
        programs = compile_file(LANES).programs
        keys = {(n.drone, n.label): n.key for p in programs.values() for n in p.nodes if n.native}
        # Drone3's way back changes; Drone4's running leg is redirected to its new climb.
        assert keys[("Drone3", "FlyByX(-12)")] in seen["touched"], seen
        assert keys[("Drone4", "FlyByX(12)")] in seen["touched"], seen
        assert not {keys[("Drone1", "FlyByX(12)")], keys[("Drone2", "FlyByX(12)")]} & set(
            seen["touched"]
        )
        assert (tmp_path / "run" / "amendments" / "1" / "amendment.json").is_file()
        browser.execute_script("document.getElementById('amend').scrollIntoView({block: 'center'})")
        assert browser.save_screenshot(str(AMEND_SHOT))
        refused = check(browser, head_on)
        assert refused["verdict"] == "refused", refused
        text = amended(*HEAD_ON)
        assert f"uploaded.go:{line_of(text, 'Drone1.FlyByY(5)')}:" in refused["text"], refused
        assert "refused: the check of the rest" in refused["text"], refused
        operator("resume", str(tmp_path / "run"))
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS, 120)
        code = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = ended_ok(run, code, tmp_path)
    # Not applied: every drone flew its lane as written.
    for name, result in summary.drones.items():
        assert result.report is not None
        legs = [list(a.args) for a in result.report.actions if a.action.startswith("FlyBy")]
        assert legs == [[12.0], [-12.0]], (name, legs)
