"""The self-contained HTML report (pinlin.html_report, `pinlin report`), in a real browser.

The browser test runs Debian's headless Chromium through chromedriver and Selenium (``.ci/run``
installs them where missing); it is skipped, with the reason, only where one of them is not
installed. The page is opened from a file URL with every background connection of Chromium
off, and the page's own Content-Security-Policy forbids it any network access.
"""

from __future__ import annotations

import json
import re
import shutil
import tempfile
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

import pinlin
from pinlin.cli import main
from pinlin.html_report import report_html, write_html_report
from pinlin.stick_figure import Skeleton

CHROMIUM = ("/usr/bin/chromium", "chromium")
CHROMEDRIVER = ("/usr/bin/chromedriver", "chromedriver")


class _Page(HTMLParser):
    """Tags with their attributes, the body rows of #mode-table and the data block."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.rows = 0
        self._table = self._body = self._data = False
        self.data = ""

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if tag == "table":
            self._table = attrs.get("id") == "mode-table"
        self._body = self._body or (self._table and tag == "tbody")
        if self._body and tag == "tr":
            self.rows += 1
        self._data = tag == "script" and attrs.get("id") == "pinlin-data"

    def handle_endtag(self, tag):
        if tag == "tbody":
            self._body = False
        if tag == "script":
            self._data = False

    def handle_data(self, data):
        if self._data:
            self.data += data


@pytest.fixture(scope="module")
def five_bar(tmp_path_factory):
    """(scene, modes, path of its report)."""
    scene = pinlin.Scene.resolve("five_bar")
    model = pinlin.linearize(scene)
    modes = pinlin.modal(model)
    path = tmp_path_factory.mktemp("report") / "five_bar.html"
    write_html_report(scene, path, model=model, modes=modes)
    return scene, modes, path


def test_report_is_self_contained(five_bar):
    scene, modes, path = five_bar
    text = path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(text)
    for tag, attrs in page.tags:
        for key in ("src", "href"):
            if key in attrs:
                assert attrs[key].startswith("data:"), (tag, key, attrs[key][:60])
        assert not (tag == "script" and "src" in attrs)
    assert "http://" not in text and "https://" not in text
    assert "default-src 'none'" in text  # the page may not reach any network
    assert page.rows == len(modes.modes())
    data = json.loads(page.data)
    assert [m["number"] for m in data["modes"]] == list(range(1, len(modes.modes()) + 1))
    # The drawn rest figure is the stick figure at q0 (to the stored digits).
    rest = Skeleton(scene.system).figure(modes.model.operating_point.q)
    np.testing.assert_allclose(np.reshape(data["rest"], (-1, 3)), rest.points, atol=1e-4)
    for mode in data["modes"]:
        assert len(mode["frames"]) == len(mode["amplitudes"]) >= 1
        assert all(len(level) == 24 for level in mode["frames"])


def test_report_html_lists_every_mode_of_a_robot():
    scene = pinlin.Scene.resolve("ur5_arm")
    modes = pinlin.modal(pinlin.linearize(scene))
    page = _Page()
    page.feed(report_html(scene, modes=modes, max_modes=2, include_response=False))
    assert page.rows == len(modes.modes()) == 6
    assert len(json.loads(page.data)["modes"]) == 2


def test_cli_report(tmp_path, capsys):
    out = tmp_path / "r.html"
    assert main(["report", "double_pendulum", "-o", str(out)]) == 0
    assert "written to" in capsys.readouterr().out
    assert out.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")


@pytest.mark.parametrize("args, message", [
    (["-o", "{tmp}/r.txt"], "r.txt: expected an .html file for the report, got '.txt'"),
    (["-o", "{tmp}/no/such/r.html"], "does not exist"),
    (["-o", "{tmp}/r.html", "--max-modes", "0"], "expected 1 to 500 modes to draw, got 0"),
    (["-o", ""], "needs a file name"),
])
def test_cli_report_bad_options_one_line_exit_2(tmp_path, capsys, args, message):
    argv = ["report", "double_pendulum", *(a.replace("{tmp}", str(tmp_path)) for a in args)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------------------------
def _which(candidates: tuple[str, ...]) -> str | None:
    for c in candidates:
        found = shutil.which(c)
        if found:
            return found
    return None


@pytest.fixture(scope="module")
def browser():
    """Headless Chromium driven by chromedriver, console logging on; skipped (with why) where
    Selenium, Chromium or chromedriver is not installed."""
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("selenium is not installed (pip install '.[test]')")
    binary, driver_path = _which(CHROMIUM), _which(CHROMEDRIVER)
    if binary is None or driver_path is None:
        pytest.skip("Debian's chromium and chromium-driver are not installed (.ci/run installs "
                    "them with apt-get where it can)")
    profile = tempfile.mkdtemp(prefix="pinlin-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic",
                "--no-first-run", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--window-size=1280,1400",
                f"--user-data-dir={profile}"):
        options.add_argument(arg)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(options=options, service=Service(driver_path))
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def _canvas_png(driver) -> bytes:
    from selenium.webdriver.common.by import By

    canvas = driver.find_element(By.ID, "figure")
    driver.execute_script("arguments[0].scrollIntoView({block: 'center'});", canvas)
    return canvas.screenshot_as_png


def test_report_in_a_headless_browser(browser, five_bar):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import Select

    scene, modes, path = five_bar
    browser.get(Path(path).resolve().as_uri())
    assert browser.title == "pinlin report: five_bar"
    errors = [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    assert not errors, errors  # a script error would leave the canvas blank
    rows = browser.find_elements(By.CSS_SELECTOR, "#mode-table tbody tr")
    assert len(rows) == len(modes.modes()) == 2
    select = Select(browser.find_element(By.ID, "mode"))
    assert len(select.options) == 2
    browser.find_element(By.ID, "play").click()  # pause: the drawing then stands still
    first = _canvas_png(browser)
    assert _canvas_png(browser) == first  # paused: nothing changes by itself
    select.select_by_index(1)
    second = _canvas_png(browser)
    assert second != first  # another mode, another drawing
    selected = browser.find_elements(By.CSS_SELECTOR, "#mode-table tbody tr.selected")
    assert [r.get_attribute("data-mode") for r in selected] == ["2"]
    # Another amplitude changes the drawing too.
    browser.execute_script("var s = document.getElementById('amplitude'); s.value = s.max; "
                           "s.dispatchEvent(new Event('input'));")
    assert _canvas_png(browser) != second
    errors = [e for e in browser.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
    assert not errors, errors
    shot = browser.get_screenshot_as_png()
    assert shot.startswith(b"\x89PNG")
    assert re.search(r"five_bar", browser.page_source)


def test_scene_name_cannot_break_out_of_the_data_script():
    """A scene named '<!--<script>' (or '</script>') must not change how the page parses:
    the data script holds no '<' at all and its JSON reads the name back exactly."""
    import dataclasses

    name = "<!--<script></script>"
    scene = dataclasses.replace(pinlin.Scene.resolve("pendulum"), name=name)
    html = report_html(scene, include_response=False)
    start = html.index('<script type="application/json" id="pinlin-data">')
    body = html[start:].split(">", 1)[1]
    payload = body[:body.index("</script>")]
    assert "<" not in payload
    assert json.loads(payload)["name"] == name


def test_a_model_of_another_scene_is_refused():
    """The double pendulum's model given for the pendulum's report failed on an argument 'q'
    the caller never passed."""
    from pinlin.html_report import report_html

    other = pinlin.linearize("double_pendulum")
    with pytest.raises(pinlin.ArgumentError, match="argument 'model': expected a linear model "
                                                   "of scene 'pendulum'"):
        report_html("pendulum", model=other)
