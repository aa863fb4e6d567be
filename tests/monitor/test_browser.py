"""The monitor page in a real browser (Debian's chromium through chromedriver and selenium).

Experiment C flies with ``--monitor``; the page, opened during the run, must
end with every node of every graph ``done`` and the drones where the summary
says they ended.  A second run is aborted from the page: without the token
nothing happens, with it every drone lands.  The screenshot of the first run
is ``docs/monitor.png``.
"""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from eamos.ground.summary import RunSummary
from tests.monitor.live import URL, start_live_run
from tests.support.runs import REPO

pytestmark = [pytest.mark.e2e, pytest.mark.xdist_group("monitor-browser")]

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
if importlib.util.find_spec("selenium") is None:
    pytest.skip("selenium is not installed (pip install -e '.[test]')", allow_module_level=True)
if CHROMIUM is None or CHROMEDRIVER is None:
    pytest.skip(
        "chromium and chromedriver are needed (apt-get install chromium chromium-driver)",
        allow_module_level=True,
    )

from selenium import webdriver  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402

FINAL_WORDS = ("finished", "failed", "aborted", "timed out")
SCREENSHOT = REPO / "docs" / "monitor.png"
#: Generous: a loaded 2-core machine starts chromium and four processes at once.
WAIT_S = 240


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu"):
        options.add_argument(arg)
    options.add_argument("--window-size=1400,1900")
    driver = webdriver.Chrome(service=Service(executable_path=str(CHROMEDRIVER)), options=options)
    driver.set_page_load_timeout(WAIT_S)
    try:
        yield driver
    finally:
        driver.quit()


def mission_state(driver: Any) -> str:
    return str(driver.find_element(By.ID, "mission-state").get_attribute("data-state"))


def wait_until(driver: Any, what: Any, timeout_s: float = WAIT_S) -> Any:
    return WebDriverWait(driver, timeout_s, poll_frequency=0.2).until(what)


def node_states(driver: Any) -> dict[str, list[str]]:
    """Per graph (participant), the state of each of its nodes as the DOM shows it."""
    return driver.execute_script(
        """const out = {};
        for (const div of document.querySelectorAll('#graphs .mdg-box')) {
          out[div.dataset.participant] = [...div.querySelectorAll('g.node')].map(
            (g) => g.dataset.node + '=' + g.dataset.state);
        }
        return out;"""
    )


def positions(driver: Any) -> dict[str, tuple[float, ...]]:
    """Each drone's x, y, z in its own frame: what the page shows less its home on the map."""
    out = {}
    for row in driver.find_elements(By.CSS_SELECTOR, "#drones tr[data-drone]"):
        cell = row.find_element(By.CSS_SELECTOR, "td.pos")
        xyz = [float(v) for v in (cell.get_attribute(f"data-{a}") for a in "xyz") if v]
        home = [float(v) for v in str(row.get_attribute("data-home")).split(",")] + [0.0]
        out[str(row.get_attribute("data-drone"))] = tuple(
            v - h for v, h in zip(xyz, home, strict=False)
        )
    return out


def links(driver: Any) -> dict[str, tuple[int, ...]]:
    """Each row of the links table: external arcs, triggers sent, received."""
    return {
        str(row.get_attribute("data-link")): tuple(
            int(str(row.get_attribute(f"data-{c}"))) for c in ("arcs", "sent", "received")
        )
        for row in driver.find_elements(By.CSS_SELECTOR, "#links tr[data-link]")
    }


@dataclass
class SeenC:
    """What the page showed at the end of a live run of experiment C."""

    run_dir: Path
    summary: RunSummary
    state: str
    graphs: dict[str, list[str]]
    positions: dict[str, tuple[float, ...]]
    bars: int
    links: dict[str, tuple[int, ...]]


@pytest.fixture(scope="module")
def seen_c(tmp_path_factory: pytest.TempPathFactory, browser: Any) -> SeenC:
    """Experiment C flown with --monitor, the page open from the start; its last page."""
    tmp_path = tmp_path_factory.mktemp("live_c")
    run = start_live_run(tmp_path, "experiment_c", speedup=5)
    try:
        url = run.wait_for(URL).group(1)
        browser.get(url)
        wait_until(browser, lambda d: mission_state(d) in ("waiting for drones", "running"))
        graphs = wait_until(browser, lambda d: node_states(d) or None)
        assert set(graphs) == {"Drone1", "Drone2", "Drone3", "GCS"}
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS)
        assert run.finish() == 0, "\n".join(run.lines)
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    browser.execute_script("window.scrollTo(0, 0)")
    SCREENSHOT.parent.mkdir(exist_ok=True)
    assert browser.save_screenshot(str(SCREENSHOT))
    return SeenC(
        tmp_path / "run",
        RunSummary.read(tmp_path / "summary.json"),
        mission_state(browser),
        node_states(browser),
        positions(browser),
        len(browser.find_elements(By.CSS_SELECTOR, "#gantt g.bar")),
        links(browser),
    )


def assert_the_end_of_c(seen: SeenC) -> None:
    assert seen.state == "finished"
    for graph, nodes in seen.graphs.items():
        assert nodes, f"{graph}: no nodes in its picture"
        not_done = [n for n in nodes if not n.endswith("=done")]
        assert not not_done, f"{graph}: {not_done}"
    for name, result in seen.summary.drones.items():
        assert result.report is not None and result.report.final is not None
        final = result.report.final
        assert seen.positions[name] == pytest.approx((final.x, final.y, final.z), abs=1e-6)
    reports = [r.report for r in seen.summary.drones.values() if r.report is not None]
    assert seen.bars == sum(len(r.actions) for r in reports)
    # The links table: each external arc carried one trigger, as every report counts.
    assert seen.links and all(a == s == r for a, s, r in seen.links.values()), seen.links
    for name, result in seen.summary.drones.items():
        assert result.report is not None
        sent = sum(v[1] for k, v in seen.links.items() if k.split(">")[0] == name)
        received = sum(v[2] for k, v in seen.links.items() if k.split(">")[1] == name)
        assert (sent, received) == (result.report.triggers_sent, result.report.triggers_received)


def test_the_page_follows_experiment_c_to_the_end(seen_c: SeenC) -> None:
    assert_the_end_of_c(seen_c)


def test_the_replay_ends_on_the_same_page_and_its_slider_goes_back(
    seen_c: SeenC, browser: Any
) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "eamos.cli", "monitor", str(seen_c.run_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert proc.stdout is not None
        found = re.search(r"(http://127\.0\.0\.1:\d+/\S*)", proc.stdout.readline())
        assert found
        browser.get(found.group(1))
        wait_until(browser, lambda d: mission_state(d) == "finished")
        wait_until(browser, lambda d: node_states(d) or None)
        replayed = SeenC(
            seen_c.run_dir,
            seen_c.summary,
            mission_state(browser),
            node_states(browser),
            positions(browser),
            len(browser.find_elements(By.CSS_SELECTOR, "#gantt g.bar")),
            links(browser),
        )
        assert_the_end_of_c(replayed)
        assert replayed.graphs == seen_c.graphs and replayed.positions == seen_c.positions
        assert replayed.links == seen_c.links
        # Back to the start: nothing ran yet.
        browser.execute_script(
            "const s = document.getElementById('slider'); s.value = 0;"
            "s.dispatchEvent(new Event('input'));"
        )
        wait_until(browser, lambda d: mission_state(d) == "waiting for drones")
        wait_until(
            browser,
            lambda d: all(n.endswith("=waiting") for ns in node_states(d).values() for n in ns),
        )
        assert not browser.find_element(By.ID, "abort").is_enabled()
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def test_abort_needs_the_token_and_lands_every_drone(tmp_path: Path, browser: Any) -> None:
    run = start_live_run(tmp_path, "experiment_c", speedup=2, timeout_s=200)
    try:
        url = run.wait_for(URL).group(1)
        # Without the token the button stays disabled and the server refuses the request.
        browser.get(url.split("?")[0])
        wait_until(browser, lambda d: mission_state(d) == "running")
        assert not browser.find_element(By.ID, "abort").is_enabled()
        status = browser.execute_script(
            "return await fetch('/api/abort', {method: 'POST', body: '{}',"
            " headers: {'Content-Type': 'application/json'}}).then(r => r.status)"
        )
        assert status == 403
        assert mission_state(browser) == "running"
        # With the token: Abort, confirm, and every drone lands.
        browser.get(url)
        wait_until(browser, lambda d: max(z for *_, z in positions(d).values() or [(0,)]) > 1.0)
        assert mission_state(browser) == "running"
        button = wait_until(browser, lambda d: d.find_element(By.ID, "abort"))
        wait_until(browser, lambda d: button.is_enabled())
        browser.execute_script("window.scrollTo(0, 0)")
        browser.save_screenshot(str(SCREENSHOT.with_name("monitor-running.png")))
        button.click()
        assert browser.find_element(By.ID, "confirm").is_displayed()
        browser.find_element(By.ID, "abort-yes").click()
        wait_until(browser, lambda d: mission_state(d) in FINAL_WORDS)
        assert mission_state(browser) == "aborted"
        code = run.finish()
    finally:
        if run.proc.poll() is None:
            run.proc.kill()
    assert code == 1, "\n".join(run.lines)
    summary = RunSummary.read(tmp_path / "summary.json")
    assert summary.outcome == "aborted by the operator"
    for name, result in summary.drones.items():
        assert result.report is not None and result.report.final is not None, name
        assert result.report.final.z < 0.2, f"{name} did not land: {result.report.final}"
    lines = "\n".join(run.lines)
    assert "abort refused (not the run's token)" in lines
    assert "abort requested from the monitor page at 127.0.0.1" in lines
