"""The operator's buttons on the monitor page, in a real browser (Debian's chromium).

Experiment C flies with ``--monitor`` on the hybrid fleet (Drone1 and Drone2 over MAVLink
to simulated PX4 and ArduCopter autopilots): their rows show the autopilot's own flight
mode and its STATUSTEXTs with their severity.  With the run's token: Pause, confirm -- the
page shows the mission ``paused`` and every drone ``paused``; then Drone2's Hold,
confirm -- its row says ``held``; the screenshot is ``docs/monitor-paused.png``.  Resume,
confirm: the mission ends ok, and the summary lists the three commands with the page as
origin.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from tests.monitor.live import URL, ended_ok, start_live_run
from tests.monitor.test_browser import (
    FINAL_WORDS,
    SCREENSHOT,
    browser,
    mission_state,
    positions,
    wait_until,
)
from tests.support.runs import REPO

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-browser")]

__all__ = ["browser"]  # the fixture, shared with test_browser

from selenium.webdriver.common.by import By  # noqa: E402

PAUSED = SCREENSHOT.with_name("monitor-paused.png")


def operator_state(driver: Any, drone: str) -> str:
    cell = driver.find_element(By.CSS_SELECTOR, f'tr[data-drone="{drone}"] td.mode')
    return str(cell.get_attribute("data-operator"))


def highest(driver: Any) -> float:
    """The highest drone's z on the page (0 before any position)."""
    return max((p[2] for p in positions(driver).values() if len(p) == 3), default=0.0)


def confirm(driver: Any, button: Any) -> None:
    """Click ``button``, see the confirmation step, confirm."""
    wait_until(driver, lambda d: button.is_enabled())
    button.click()
    assert driver.find_element(By.ID, "cmd-confirm").is_displayed()
    driver.find_element(By.ID, "cmd-yes").click()
    result = wait_until(driver, lambda d: d.find_element(By.ID, "cmd-result"))
    wait_until(driver, lambda d: result.is_displayed())


def test_pause_and_a_drone_command_from_the_page(tmp_path: Path, browser: Any) -> None:
    hybrid = str(REPO / "configs" / "experiment_c_hybrid.toml")
    run = start_live_run(tmp_path, "experiment_c", "--fleet", hybrid, speedup=1, timeout_s=300)
    try:
        url = run.wait_for(URL).group(1)
        browser.get(url)
        wait_until(browser, lambda d: highest(d) > 1.0)
        assert mission_state(browser) == "running"
        confirm(browser, browser.find_element(By.ID, "pause"))
        wait_until(browser, lambda d: mission_state(d) == "paused", 60)
        wait_until(
            browser,
            lambda d: all(operator_state(d, n) == "paused" for n in ("Drone1", "Drone2", "Drone3")),
            60,
        )
        hold = browser.find_element(
            By.CSS_SELECTOR, 'tr[data-drone="Drone2"] button[data-command="hold"]'
        )
        confirm(browser, hold)
        wait_until(browser, lambda d: operator_state(d, "Drone2") == "held", 60)
        assert "hold sent to Drone2" in browser.find_element(By.ID, "cmd-result").text
        # The autopilots' own voice: their flight mode, their messages with severity.
        for drone in ("Drone1", "Drone2"):
            mode = browser.find_element(By.CSS_SELECTOR, f'tr[data-drone="{drone}"] td.mode')
            assert mode.get_attribute("data-autopilot"), drone
        said = browser.find_element(By.CSS_SELECTOR, 'tr[data-line="Drone2"] td')
        wait_until(browser, lambda d: said.get_attribute("data-statustext"), 60)
        assert re.search(
            r"(INFO|NOTICE|WARNING|CRITICAL|ERROR): ", said.get_attribute("data-statustext")
        )
        browser.execute_script("window.scrollTo(0, 0)")
        assert browser.save_screenshot(str(PAUSED))
        confirm(browser, browser.find_element(By.ID, "resume"))
        wait_until(browser, lambda d: mission_state(d) != "paused", 60)
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS)
        assert mission_state(browser) == "finished"
        code = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = ended_ok(run, code, tmp_path)
    got = [(c["command"], c["drone"]) for c in summary.operator_commands]
    assert got == [("pause", ""), ("hold", "Drone2"), ("resume", "")]
    assert all(
        str(c["origin"]).startswith("monitor page at 127.0.0.1") for c in summary.operator_commands
    )
