"""The live look-ahead on the monitor page, in a real browser (Debian's chromium).

``missions/crossing.go`` with ``configs/crossing_slow.toml`` and ``--monitor``: Drone2
flies at half its type's speed, so the flight heads into a separation conflict.  The
page's look-ahead panel lists the predicted conflict (both drones, how far ahead), the map
draws each drone's predicted track and a ring where the conflict would be, the dependency
graphs outline the two legs heading into it; the screenshots are
``docs/monitor-lookahead.png`` and ``docs/monitor-lookahead-graphs.png``.  The look-ahead
holds both drones; the operator resumes Drone2 from the page, then Drone1 once Drone2 is
past: the mission ends ok.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from eamos.compiler import compile_file
from tests.monitor.live import URL, ended_ok, start_live_run
from tests.monitor.test_browser import FINAL_WORDS, SCREENSHOT, browser, mission_state, wait_until
from tests.monitor.test_browser_operator import confirm, operator_state
from tests.support.runs import MISSIONS, REPO

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-browser")]

__all__ = ["browser"]  # the fixture, shared with test_browser

from selenium.webdriver.common.by import By  # noqa: E402

LOOK_AHEAD = SCREENSHOT.with_name("monitor-lookahead.png")
ON_THE_GRAPHS = SCREENSHOT.with_name("monitor-lookahead-graphs.png")


def predicted(driver: Any) -> list[tuple[str, str]]:
    """(check, drones) of each prediction the page's look-ahead panel lists (read at once:
    the page redraws the panel on every update)."""
    items = driver.execute_script(
        """return [...document.querySelectorAll('#forecast li[data-check]')].map(
            (li) => [li.dataset.check, li.dataset.drones]);"""
    )
    return [(str(c), str(d)) for c, d in items]


def drawn(driver: Any) -> dict[str, Any]:
    """What the page shows of the look-ahead now: the drones with a predicted track, the
    predicted conflicts on the map, the conflict's line in the panel."""
    return dict(
        driver.execute_script(
            """const q = (s) => [...document.querySelectorAll(s)];
            return {
              ahead: q('#map polyline.ahead').map((p) => p.dataset.drone),
              rings: q('#map g.predicted').map((g) => g.dataset.check),
              text: q('#forecast li[data-check="separation"]').map((li) => li.textContent),
              nodes: q('#graphs g.node.predicted').map((g) => g.dataset.node),
            };"""
        )
    )


def resume(driver: Any, drone: str) -> None:
    button = driver.find_element(
        By.CSS_SELECTOR, f'tr[data-drone="{drone}"] button[data-command="resume"]'
    )
    confirm(driver, button)


def test_the_page_shows_the_predicted_conflict_and_tracks_ahead(
    tmp_path: Path, browser: Any
) -> None:
    slow = str(REPO / "configs" / "crossing_slow.toml")
    run = start_live_run(tmp_path, MISSIONS / "crossing.go", "--fleet", slow, speedup=1)
    try:
        browser.get(run.wait_for(URL).group(1))
        wait_until(browser, lambda d: ("separation", "Drone1 Drone2") in predicted(d), 120)
        seen = wait_until(
            browser, lambda d: (shown := drawn(d))["rings"] and shown["nodes"] and shown
        )
        assert set(seen["ahead"]) == {"Drone1", "Drone2"} and "separation" in seen["rings"], seen
        # The two legs heading into the conflict are outlined on the dependency graphs.
        programs = compile_file(MISSIONS / "crossing.go").programs
        legs = {n.key for p in programs.values() for n in p.nodes if n.native
                and n.label in ("FlyByY(20)", "FlyByX(40)")}  # fmt: skip
        assert set(seen["nodes"]) == legs, seen
        text = seen["text"][0]
        assert "separation error in " in text and "Drone1.FlyByY(20)" in text, text
        browser.execute_script("window.scrollTo(0, 0)")
        assert browser.save_screenshot(str(LOOK_AHEAD))
        browser.execute_script(
            "document.querySelector('#graphs g.node.predicted').scrollIntoView({block: 'center'})"
        )
        assert browser.save_screenshot(str(ON_THE_GRAPHS))
        browser.execute_script("window.scrollTo(0, 0)")  # where the operator's buttons were
        # The look-ahead holds both; the operator lets Drone2 by, then Drone1.
        for drone in ("Drone1", "Drone2"):
            wait_until(browser, lambda d, n=drone: operator_state(d, n) == "held", 60)
        resume(browser, "Drone2")
        run.wait_for(re.compile(r"Drone2 ok +FlyByX\(40\)"), 120)
        resume(browser, "Drone1")
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS, 120)
        assert mission_state(browser) == "finished"
        code = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    summary = ended_ok(run, code, tmp_path)
    origins = [(c["command"], c["drone"], str(c["origin"])) for c in summary.operator_commands]
    assert [(c, d) for c, d, _ in origins] == [
        ("hold", "Drone1"),
        ("hold", "Drone2"),
        ("resume", "Drone2"),
        ("resume", "Drone1"),
    ]
    assert [o for _, _, o in origins][:2] == ["look-ahead", "look-ahead"]
    assert all(o.startswith("monitor page at 127.0.0.1") for _, _, o in origins[2:])
