"""The page of ``spco serve`` in a real browser: Debian's headless chromium, driven by Selenium through
Debian's chromedriver (no browser downloads; ``.ci/run`` installs both). Skipped with the reason where
they are missing, except under CI (``CI=true``), where that is a failure."""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import pytest
from serve_helpers import Server, build_home, copy_home

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver") or shutil.which("/usr/lib/chromium/chromedriver")


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"{reason} (CI must run the browser test: .ci/run installs chromium and chromium-driver)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory):
    """A headless chromium driven by Selenium through the distribution's chromedriver."""
    if CHROMIUM is None or CHROMEDRIVER is None:
        _unavailable("no chromium and chromedriver on this machine (Debian: apt-get install chromium "
                     "chromium-driver)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        _unavailable("selenium is not installed (pip install -e '.[test]')")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1400,900",
                 f"--user-data-dir={tmp_path_factory.mktemp('chromium')}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(60)
    yield driver
    driver.quit()


def _shows_the_map(browser: Any, robot: Any, wait: Any, home: Path) -> list[Any]:
    """The map: learnt regions as ellipses, each place labelled where ``where`` goes for it (``home``: the
    served file, asked in this process so that the page's log shows only the clicks), axes, and the
    samples as dots; the event stream open. Returns the regions' ellipses."""
    from selenium.webdriver.common.by import By

    from spco import knowledge as kn

    known = robot.regions()["names"]
    wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "#layer-regions ellipse.region"))
    ellipses = browser.find_elements(By.CSS_SELECTOR, "#layer-regions ellipse.region")
    labels = [e.text for e in browser.find_elements(By.CSS_SELECTOR, "#layer-labels text.region-label")]
    regions = robot.regions()["regions"]
    drawn = [g for g in regions if g["weight"] >= 0.01 or g["taught"] > 0]  # negligible ones hidden
    assert len(ellipses) == len(drawn) and len(drawn) < len(regions) + 1
    assert labels and any(name in " ".join(labels) for name in known)
    # a place is labelled where `where` goes for it: the label and the answer to "where is …" are one
    labelled: dict[str, int] = {}
    for label in browser.find_elements(By.CSS_SELECTOR, "#layer-labels text.region-label"):
        for name in label.get_attribute("data-places").split("|"):
            assert name not in labelled, labels  # one label per place
            labelled[name] = int(label.get_attribute("data-region"))
    learnt = {p["name"]: p["region"] for p in robot.regions()["places"] if p["learnt"]}
    assert labelled == learnt
    served = kn.load_home_model(home)
    for name, region in labelled.items():
        assert kn.where(served, name).region == region
    axis_labels = [e.text for e in browser.find_elements(By.CSS_SELECTOR, "#layer-axes text.axis-label")]
    assert "x (m)" in axis_labels and "y (m)" in axis_labels
    assert any(t.endswith(" m") for t in axis_labels)  # the scale bar
    assert len(browser.find_elements(By.CSS_SELECTOR, "#layer-samples circle.sample")) == \
        robot.health()["samples"]
    assert browser.find_element(By.ID, "connection").text == "live"  # the event stream is open
    return ellipses


def _answers_what_and_where(browser: Any, wait: Any, ellipses: list[Any], name: str) -> list[str]:
    """Click the biggest region: the names there, with p; type ``name``: its poses drawn. Returns the
    names shown at the click."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    biggest = max(ellipses, key=lambda e: e.size["width"] * e.size["height"])
    ActionChains(browser).move_to_element(biggest).click().perform()
    wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "#what-names li"))
    names = [li.text for li in browser.find_elements(By.CSS_SELECTOR, "#what-names li")]
    assert names and all(" — p 0." in n or " — p 1." in n for n in names)
    browser.find_element(By.ID, "where-input").send_keys(name)
    browser.find_element(By.ID, "where-button").click()
    wait.until(lambda d: len(d.find_elements(By.CSS_SELECTOR, "#layer-poses g.pose")) == 10)
    assert name in browser.find_element(By.ID, "where-result").text
    return names


def _teaches_and_undoes(browser: Any, robot: Any, wait: Any, before: list[str], shots: Path) -> None:
    """Type a sentence at the clicked point: taught, and every panel shows it (the names at the point
    included); undo it: the names at the point are again exactly ``before``."""
    from selenium.webdriver.common.by import By

    browser.find_element(By.ID, "teach-sentence").send_keys("this is the pantry")
    browser.find_element(By.ID, "teach-button").click()
    wait.until(lambda d: "Taught (seq 1" in d.find_element(By.ID, "teach-result").text)
    assert robot.health()["teachings"] == 1
    wait.until(lambda d: "1 teachings served" in d.find_element(By.ID, "stats").text)
    wait.until(lambda d: "pantry" in d.find_element(By.ID, "what-names").text)
    assert browser.save_screenshot(str(shots / "page-after-teaching.png"))
    browser.find_element(By.ID, "undo-button").click()
    wait.until(lambda d: "Undone (teaching 1)" in d.find_element(By.ID, "teach-result").text)
    wait.until(lambda d: [li.text for li in d.find_elements(By.CSS_SELECTOR, "#what-names li")] == before)
    wait.until(lambda d: "0 teachings served" in d.find_element(By.ID, "stats").text)
    assert browser.save_screenshot(str(shots / "page-after-undo.png"))


def test_the_page_shows_the_regions_answers_and_teaches_live(browser, tmp_path: Path) -> None:
    from selenium.common.exceptions import StaleElementReferenceException
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    from spco.service.client import Client

    (tmp_path / "built").mkdir()
    home = copy_home(build_home(tmp_path / "built"), tmp_path / "served")
    server = Server(home)
    try:
        robot = Client(server.url)
        known = robot.regions()["names"]
        # (a list the page redraws between finding an element and reading it: read it again)
        wait = WebDriverWait(browser, 30, ignored_exceptions=(StaleElementReferenceException,))
        browser.get(server.url + "/")
        ellipses = _shows_the_map(browser, robot, wait, home)
        before = _answers_what_and_where(browser, wait, ellipses, known[0])
        shots = Path(os.environ.get("SPCO_PAGE_SCREENSHOTS", str(tmp_path)))
        shots.mkdir(parents=True, exist_ok=True)
        assert browser.save_screenshot(str(shots / "page-before-teaching.png"))
        _teaches_and_undoes(browser, robot, wait, before, shots)
        robot.teach(x=0.0, y=0.0, theta=0.0, sentence="this is the pantry")  # taught again, by the robot
        wait.until(lambda d: "1 teachings served" in d.find_element(By.ID, "stats").text)
        # another client teaches: the page learns it from the event stream
        robot.teach(id=int(robot.regions()["samples"][0]["id"]), sentence="this is the scullery")
        wait.until(lambda d: "2 teachings served" in d.find_element(By.ID, "stats").text)
        log = browser.find_element(By.ID, "log").text
        assert "this is the scullery" in log and "this is the pantry" in log
        shot = tmp_path / "page.png"
        assert browser.save_screenshot(str(shot)) and shot.stat().st_size > 10_000
    finally:
        assert server.stop() == 0, server.output
