"""An amendment checked, previewed and applied from the monitor page, in a real browser.

``tests/operator/four_lanes.go`` with ``--monitor`` (Debian's chromium), paused while
every drone flies its first leg; the page's Amendment section uploads a new text of the
mission and shows how ``eamos amend`` judges it.  Drone1 and Drone2 sent at each other is
refused with the separation finding at the new lines, a change to the leg Drone1 flies is
refused with the node named, and nothing is staged.  A change to
Drone3's and Drone4's later legs is accepted: the running nodes it touches are outlined on
the graphs, and each changed drone's graph is shown as it flies and as amended, side by
side, the new and changed nodes marked.  Applied with the Apply button and its
confirmation, the page draws the two drones' new graphs; resumed, they fly their new parts
and the other two their lanes as written.  The screenshots are ``docs/monitor-amend.png``
(the report and the outlined nodes) and ``docs/monitor-amend-preview.png`` (the graphs
side by side).
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
from tests.support.four_lanes import (
    HEAD_ON,
    LANES,
    LATER_PARTS,
    RUNNING_LEG,
    amended,
    line_of,
)

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-browser")]

__all__ = ["browser"]  # the fixture, shared with test_browser

from selenium.webdriver.common.by import By  # noqa: E402

AMEND_SHOT = SCREENSHOT.with_name("monitor-amend.png")
PREVIEW_SHOT = SCREENSHOT.with_name("monitor-amend-preview.png")


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


def preview(driver: Any) -> dict[str, Any]:
    """The graphs side by side: per drone, the nodes marked in each picture."""
    return dict(
        driver.execute_script(
            """const out = {};
            for (const pair of document.querySelectorAll('#amend-compare .amend-pair')) {
              const marked = (sel) => [...pair.querySelectorAll(sel)].map((g) => g.dataset.node);
              out[pair.dataset.participant] = {
                flying: marked('.amend-before g.node.amended'),
                amended: marked('.amend-after g.node.amended-new'),
              };
            }
            return out;"""
        )
    )


def graph_nodes(driver: Any, drone: str) -> list[str]:
    """The node keys of ``drone``'s graph in the page's graphs section."""
    return list(
        driver.execute_script(
            "const box = `#graphs .mdg-box[data-participant='${arguments[0]}']`;"
            "return [...document.querySelectorAll(`${box} g.node`)].map((g) => g.dataset.node);",
            drone,
        )
    )


def test_the_page_checks_previews_and_applies_an_amendment(tmp_path: Path, browser: Any) -> None:
    later, head_on = tmp_path / "later.go", tmp_path / "head_on.go"
    later.write_text(amended(*LATER_PARTS))
    head_on.write_text(amended(*HEAD_ON))
    run = start_live_run(tmp_path, LANES, speedup=1)
    run_dir = tmp_path / "run"
    try:
        browser.get(run.wait_for(URL).group(1))
        for drone in ("Drone1", "Drone2", "Drone3", "Drone4"):
            run.wait_for(re.compile(rf"{drone} running +FlyByX\(12\)"), 120)
        operator("pause", str(run_dir))
        wait_until(browser, lambda d: mission_state(d) == "paused", 60)
        # Two drones sent at each other: refused, located; nothing staged, nothing to apply.
        refused = check(browser, head_on)
        assert refused["verdict"] == "refused", refused
        text = amended(*HEAD_ON)
        assert f"uploaded.go:{line_of(text, 'Drone1.FlyByY(5)')}:" in refused["text"], refused
        assert "refused: the check of the rest" in refused["text"], refused
        assert not browser.find_element(By.ID, "amend-apply").is_displayed()
        # The leg Drone1 is flying: refused with the node named, nothing checked.
        running = tmp_path / "running.go"
        running.write_text(amended(*RUNNING_LEG))
        seen = check(browser, running)
        assert seen["verdict"] == "refused", seen
        leg = f"FlyByX(12) (line {line_of(amended(), 'Drone1.FlyByX(12)')}) is running"
        assert leg in seen["text"], seen
        assert not browser.find_element(By.ID, "amend-apply").is_displayed()
        assert not (run_dir / "amendments").exists() or not any((run_dir / "amendments").iterdir())
        # The later legs of Drone3 and Drone4: accepted, staged, previewed.
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
        staged = run_dir / "amendments" / "1"
        assert (staged / "amendment.json").is_file()
        shown = preview(browser)
        assert sorted(shown) == ["Drone3", "Drone4"], shown
        assert keys[("Drone3", "FlyByX(-12)")] in shown["Drone3"]["flying"], shown
        # Amended: the old way back changed (its key kept), one leg added; Drone4's climb.
        assert keys[("Drone3", "FlyByX(-12)")] in shown["Drone3"]["amended"], shown
        assert len(shown["Drone3"]["amended"]) == 2 and len(shown["Drone4"]["amended"]) == 1
        browser.execute_script(
            "document.getElementById('amend').scrollIntoView({block: 'start'});"
            "window.scrollBy(0, -60);"  # below the page's fixed header
        )
        assert browser.save_screenshot(str(AMEND_SHOT))
        browser.execute_script(
            "document.getElementById('amend-compare').scrollIntoView({block: 'start'});"
            "window.scrollBy(0, -60);"  # below the page's fixed header
        )
        assert browser.save_screenshot(str(PREVIEW_SHOT))
        # Apply, confirmed: the page draws the amended graphs.
        new_keys = set(shown["Drone4"]["amended"])
        assert not new_keys & set(graph_nodes(browser, "Drone4"))
        apply = browser.find_element(By.ID, "amend-apply")
        browser.execute_script("arguments[0].scrollIntoView({block: 'center'})", apply)
        apply.click()
        wait_until(browser, lambda d: d.find_element(By.ID, "amend-confirm").is_displayed(), 30)
        question = browser.find_element(By.ID, "amend-question").text
        assert "Apply amendment 1 to Drone3, Drone4?" in question, question
        browser.find_element(By.ID, "amend-yes").click()
        wait_until(
            browser,
            lambda d: d.find_element(By.ID, "amend-result").text.startswith("amendment 1 "),
            120,
        )
        result = browser.find_element(By.ID, "amend-result").text
        assert result == "amendment 1 applied.", result
        wait_until(browser, lambda d: new_keys <= set(graph_nodes(d, "Drone4")), 60)
        assert (staged / "applied.json").is_file()
        operator("resume", str(run_dir))
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS, 120)
        code = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = ended_ok(run, code, tmp_path)
    legs = {}
    for name, result_ in summary.drones.items():
        assert result_.report is not None
        legs[name] = [
            (a.action, list(a.args)) for a in result_.report.actions if a.action.startswith("FlyBy")
        ]
    assert legs["Drone1"] == legs["Drone2"] == [("FlyByX", [12.0]), ("FlyByX", [-12.0])], legs
    assert legs["Drone3"] == [("FlyByX", [12.0]), ("FlyByX", [-6.0]), ("FlyByX", [-6.0])], legs
    assert legs["Drone4"] == [("FlyByX", [12.0]), ("FlyByZ", [1.0]), ("FlyByX", [-12.0])], legs
