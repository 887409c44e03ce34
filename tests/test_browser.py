"""report.html in a real headless Chromium (Debian's package, driven by Playwright).

Skipped, with the reason, when /usr/bin/chromium or the playwright package is missing.
Keeps a screenshot of the first screen in ``test-artifacts/report-first-screen.png`` and one of
every figure as the page shows it, at its print size (3.5 in a panel, 96 CSS px an inch), in
``test-artifacts/figures/<key>.png``: the pictures to look at when a figure changes.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from skymule.report.build import build_report
from skymule.report.html import CSS_PX_PER_IN, PER_RUN_PANELS
from skymule.report.style import PANEL_WIDTH_IN
from skymule.scenario import scenario_from_dict
from skymule.tasks.compare import compare_policies, write_compare

CHROMIUM = Path("/usr/bin/chromium")
ARTIFACTS = Path(__file__).resolve().parent.parent / "test-artifacts"
LAUNCH_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
SCENARIO = {
    "name": "browser",
    "mission": {"duration_s": 60},
    "site": {"geofence": "lake-wheeler"},
    "sensors": [
        {"name": "LW1", "lat": 35.727451, "lon": -78.695974, "buffer_mbit": 100},
        {"name": "LW3", "lat": 35.724933, "lon": -78.691912, "buffer_mbit": 200},
    ],
    "trajectory": {"mode": "fixed", "waypoints": [[0, 0, 30], [6, -70, 30], [148, -160, 30]]},
}


def _browser_missing() -> str | None:
    if not CHROMIUM.is_file():
        return f"{CHROMIUM} not installed (apt-get install chromium)"
    if importlib.util.find_spec("playwright") is None:
        return "the playwright package is not installed (pip install '.[browser]')"
    return None


@pytest.fixture(scope="module")
def report_html(tmp_path_factory: pytest.TempPathFactory) -> Path:
    reason = _browser_missing()
    if reason is not None:
        pytest.skip(reason)
    folder = tmp_path_factory.mktemp("browser") / "cmp"
    scenario = scenario_from_dict(SCENARIO, "browser test", Path("."))
    # a whole compare folder (comparison.csv written last): report refuses a half one
    write_compare(compare_policies(scenario, ["greedy", "hgad"]), folder)
    return build_report(folder, pdf=False)


@pytest.mark.browser
def test_report_renders_in_chromium(report_html: Path, tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    errors: list[str] = []
    requests: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch_persistent_context(
            str(tmp_path / "profile"),
            executable_path=str(CHROMIUM),
            headless=True,
            args=LAUNCH_ARGS,
            viewport={"width": 1280, "height": 900},
        )
        try:
            page = browser.new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on(
                "request",
                lambda r: None if r.url.startswith(("file:", "data:")) else requests.append(r.url),
            )
            page.goto(report_html.as_uri())
            page.wait_for_load_state("load")
            ARTIFACTS.mkdir(exist_ok=True)
            page.screenshot(path=str(ARTIFACTS / "report-first-screen.png"))

            expected = ["summary", "score", "comparison", "interactive", "scenario"]
            expected += [p.key for p in PER_RUN_PANELS]
            for section in expected:
                assert page.locator(f"section#{section}").count() == 1, section
            # every figure is an image the browser decoded (non-zero natural size)
            figures = page.locator("figure.fig img")
            assert figures.count() == len(PER_RUN_PANELS) + 2
            sizes = figures.evaluate_all("imgs => imgs.map(i => [i.complete, i.naturalWidth])")
            assert all(done and width > 100 for done, width in sizes), sizes
            for key in ("trajectory", "download", "remaining", "snr", "snr-cdf", "score"):
                assert page.locator(f'figure[data-fig="{key}"] img').is_visible(), key
            # every figure shown at print size: 3.5 in a panel (two runs: two panels)
            (ARTIFACTS / "figures").mkdir(exist_ok=True)
            for key in ["score", "policies", *(p.key for p in PER_RUN_PANELS)]:
                image = page.locator(f'figure[data-fig="{key}"] img')
                panels = 1 if key in ("score", "policies") else 2
                width = image.evaluate("i => i.getBoundingClientRect().width")
                assert width == pytest.approx(panels * PANEL_WIDTH_IN * CSS_PX_PER_IN, abs=1), key
                image.screenshot(path=str(ARTIFACTS / "figures" / f"{key}.png"))

            # interactive view: hovering the path shows that slot's details
            svg = page.locator("svg.traj").first
            svg.scroll_into_view_if_needed()
            box = svg.bounding_box()
            assert box is not None and box["width"] > 100
            page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            tip = page.locator(".tip").first.inner_text()
            assert "t = " in tip and "serving" in tip and "left [Mbit]" in tip
            # wheel zoom changes the view box, double-click restores it
            before = svg.get_attribute("viewBox")
            page.mouse.wheel(0, -300)
            page.wait_for_timeout(50)
            zoomed = svg.evaluate("s => s.viewBox.baseVal.width")
            assert zoomed < float(str(before).split()[2])
            svg.dblclick()
            assert svg.evaluate("s => s.viewBox.baseVal.width") == pytest.approx(
                float(str(before).split()[2]), rel=1e-6
            )
        finally:
            browser.close()
    assert errors == [], errors
    assert requests == [], f"report made external requests: {requests}"


def test_skip_reason_names_the_missing_browser(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without Chromium the browser test skips saying so (CI logs show why)."""
    monkeypatch.setattr(sys.modules[__name__], "CHROMIUM", Path("/nonexistent/chromium"))
    reason = _browser_missing()
    assert reason is not None and "/nonexistent/chromium not installed" in reason
