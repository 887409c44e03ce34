"""skymule report on runs of several UAVs: the fleet report from the run folder's files.

A small two-UAV mission is flown through the CLI (``skymule run`` / ``skymule compare``), then
reported; the report must show what the run wrote (each UAV's summary, the Mbit each UAV took
from each sensor in slots.csv) and a damaged fleet folder must be one line and exit 2.
"""

from __future__ import annotations

import base64
import importlib.util
import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from conftest import run_cli
from skymule.report.fleet_html import FLEET_PANELS

SMALL_FLEET = """
name = "small-fleet"
seed = 3
[mission]
duration_s = 120
[site]
geofence = "lake-wheeler"
[[sensors]]
name = "LW1"
lat = 35.727451
lon = -78.695974
buffer_mbit = 300
[[sensors]]
name = "LW2"
lat = 35.72821
lon = -78.70093
buffer_mbit = 300
[[sensors]]
name = "LW3"
lat = 35.724933
lon = -78.691912
buffer_mbit = 300
[trajectory]
mode = "autonomous"
altitude_m = 30.0
max_speed_mps = 10.0
return_home = true
"""
UAVS = """
[[uavs]]
name = "north"
[[uavs]]
name = "south"
home = [-200.0, -100.0]
"""
SECTIONS = ("summary", "uavs", "scenario", *(p.key for p in FLEET_PANELS))


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fleet run, a fleet compare folder and a single-UAV run, all made by the CLI."""
    work = tmp_path_factory.mktemp("fleet-report")
    (work / "fleet.toml").write_text(SMALL_FLEET + UAVS)
    (work / "one.toml").write_text(SMALL_FLEET)
    for args in (
        ("run", "fleet.toml", "--policy", "coordinated", "--out", "run"),
        ("compare", "fleet.toml", "--policies", "greedy,coordinated", "--out", "cmp"),
        ("run", "one.toml", "--policy", "greedy", "--out", "single"),
    ):
        done = run_cli(*args, cwd=work)
        assert done.returncode == 0, done.stderr
    return work


@pytest.fixture
def fleet_run(made: Path, tmp_path: Path) -> Path:
    """A copy of the fleet run folder, moved away from its scenario file."""
    copy = tmp_path / "fleet"
    shutil.copytree(made / "run", copy)
    return copy


def embedded_pngs(page: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([^"]+)"', page)]


def table_rows(page: str, table_id: str) -> dict[str, list[str]]:
    """First cell -> the other cells of each body row of the table ``table_id``."""
    match = re.search(rf'<table id="{table_id}">.*?<tbody>(.*?)</tbody>', page, re.S)
    assert match is not None, table_id
    rows = re.findall(r"<tr>(.*?)</tr>", match.group(1))
    cells = [re.findall(r"<td>(.*?)</td>", row) for row in rows]
    return {row[0]: row[1:] for row in cells}


def test_fleet_run_report_shows_each_uav(fleet_run: Path) -> None:
    done = run_cli("report", fleet_run, cwd=fleet_run.parent)
    assert done.returncode == 0, done.stderr
    page = (fleet_run / "report.html").read_text()
    for section in SECTIONS:
        assert f'<section id="{section}">' in page, section
    assert not re.search(r'(src|href)="(https?:)?//', page) and "<link" not in page
    pngs = embedded_pngs(page)
    assert len(pngs) == len(FLEET_PANELS) and all(p.startswith(b"\x89PNG") for p in pngs)
    for panel in FLEET_PANELS:
        assert (fleet_run / "figures" / f"{panel.key}.png").read_bytes()[:4] == b"\x89PNG"
        pdf = (fleet_run / "figures" / f"{panel.key}.pdf").read_bytes()
        assert pdf[:5] == b"%PDF-" and b"/Subtype /Image" not in pdf, panel.key

    summary = json.loads((fleet_run / "summary.json").read_text())
    rows = table_rows(page, "uav-table-0")
    assert list(rows) == ["north", "south", "fleet"]
    for entry in summary["uavs"]:
        row = rows[entry["uav"]]
        assert row[0] == f"{entry['total_downloaded_mbit']:.1f}"  # downloaded [Mbit]
        assert row[1] == str(entry["lost_slots"])
        assert row[2] == f"{entry['hover_time_s']:.0f}"
        assert f"{entry['energy_kj']:.1f}" in row and str(entry["landed_within_5m"]) in row
    assert rows["fleet"][0] == f"{summary['total_downloaded_mbit']:.1f}"
    assert rows["fleet"][1] == str(summary["lost_slots"])

    # Mbit by UAV and sensor: slots.csv's downloads, adding up to the fleet's per sensor
    slots = pd.read_csv(fleet_run / "slots.csv", keep_default_na=False, dtype={"served": str})
    by_uav = slots[slots["served"] != ""].groupby(["uav", "served"])["downloaded_mbit"].sum()
    shown = table_rows(page, "uav-sensor-table-0")
    sensors = list(summary["per_sensor_buffer_mbit"])
    for uav in ("north", "south"):
        expected = [f"{by_uav.get((uav, s), 0.0):.1f}" for s in sensors]
        assert shown[uav] == expected, uav
    for index, sensor in enumerate(sensors):
        parts = sum(float(shown[uav][index]) for uav in ("north", "south"))
        assert parts == pytest.approx(summary["per_sensor_downloaded_mbit"][sensor], abs=0.11)
    assert all(sum(map(float, shown[uav])) > 0 for uav in ("north", "south"))  # both served


def test_no_pdf_writes_only_pngs(fleet_run: Path) -> None:
    (fleet_run / "figures").mkdir()
    (fleet_run / "figures" / "stale.pdf").write_bytes(b"%PDF-")
    done = run_cli("report", fleet_run, "--no-pdf")
    assert done.returncode == 0, done.stderr
    assert not list((fleet_run / "figures").glob("*.pdf"))
    assert sorted(p.stem for p in (fleet_run / "figures").glob("*.png")) == sorted(
        p.key for p in FLEET_PANELS
    )


def test_fleet_compare_folder_report_puts_policies_side_by_side(made: Path, tmp_path: Path) -> None:
    folder = tmp_path / "cmp"
    shutil.copytree(made / "cmp", folder)
    done = run_cli("report", folder, "--no-pdf")
    assert done.returncode == 0, done.stderr
    page = (folder / "report.html").read_text()
    for section in (*SECTIONS, "comparison"):
        assert f'<section id="{section}">' in page, section
    assert "<h3>coordinated</h3>" in page and "<h3>greedy</h3>" in page
    for index, policy in enumerate(("coordinated", "greedy")):  # folders in name order
        summary = json.loads((folder / policy / "summary.json").read_text())
        rows = table_rows(page, f"uav-table-{index}")
        for entry in summary["uavs"]:
            assert rows[entry["uav"]][0] == f"{entry['total_downloaded_mbit']:.1f}"
    assert len(embedded_pngs(page)) == len(FLEET_PANELS) + 1  # + the policy bars


def test_mixed_compare_folder_is_one_line(made: Path, tmp_path: Path) -> None:
    folder = tmp_path / "mixed"
    shutil.copytree(made / "cmp", folder)
    shutil.copytree(made / "single", folder / "single")
    done = run_cli("report", folder)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "mixes runs of several UAVs (coordinated, greedy) with single-UAV runs (single)" in (
        done.stderr
    )
    assert not (folder / "report.html").exists()


def _slots_edit(edit: Callable[[pd.DataFrame], pd.DataFrame]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        slots = pd.read_csv(run / "slots.csv", keep_default_na=False, dtype=str)
        edit(slots).to_csv(run / "slots.csv", index=False)

    return apply


def _summary_edit(edit: Callable[[dict[str, object]], None]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        summary = json.loads((run / "summary.json").read_text())
        edit(summary)
        (run / "summary.json").write_text(json.dumps(summary))

    return apply


def _set(row: int, column: str, value: str) -> Callable[[pd.DataFrame], pd.DataFrame]:
    def edit(slots: pd.DataFrame) -> pd.DataFrame:
        slots.loc[row, column] = value
        return slots

    return edit


def _one_more_north(slots: pd.DataFrame) -> pd.DataFrame:
    # south's last slot becomes a 121st north row, after north's last: times still increase
    slots.loc[len(slots) - 1, ["uav", "t_s"]] = ["north", "120"]
    return slots


def _more_download(slots: pd.DataFrame) -> pd.DataFrame:
    row = int((slots["downloaded_mbit"].astype(float) > 0).to_numpy().argmax())
    slots.loc[row, "downloaded_mbit"] = str(float(slots.loc[row, "downloaded_mbit"]) + 50.0)
    return slots


def _download_moved_to_another_uav(slots: pd.DataFrame) -> pd.DataFrame:
    """Same totals per sensor and for the fleet; one UAV's slot given to the other."""
    down = slots["downloaded_mbit"].astype(float)
    south = set(slots.loc[slots["uav"] == "south", "served"]) - {""}
    north = (slots["uav"] == "north") & (down > 0) & slots["served"].isin(south)
    row = int(north.to_numpy().argmax())
    other = (slots["uav"] == "south") & (slots["served"] == slots.loc[row, "served"])
    target = int(other.to_numpy().argmax())
    assert north[row] and other[target]
    slots.loc[target, "downloaded_mbit"] = str(down[target] + down[row])
    slots.loc[row, "downloaded_mbit"] = "0"
    return slots


DAMAGE: dict[str, tuple[Callable[[Path], None], str, str]] = {
    "uav column dropped": (
        _slots_edit(lambda s: s.drop(columns="uav")),
        "slots.csv",
        "missing column 'uav'; summary.json lists 2 UAVs",
    ),
    "unknown uav": (
        _slots_edit(_set(3, "uav", "west")),
        "slots.csv",
        "data row 4, column 'uav': 'west' is not allowed; allowed: one of summary.json's uavs "
        "(north, south)",
    ),
    "uav given as an index": (
        _slots_edit(_set(0, "uav", "0")),
        "slots.csv",
        "data row 1, column 'uav': '0' is not allowed",
    ),
    "empty uav cell": (
        _slots_edit(_set(5, "uav", "")),
        "slots.csv",
        "data row 6, column 'uav': an empty cell is not allowed",
    ),
    "a row moved to the other UAV": (
        _slots_edit(_one_more_north),
        "slots.csv",
        "UAV 'north' has 121 rows, expected summary.json's slots = 120 per UAV",
    ),
    "south on other slot times": (
        _slots_edit(_set(239, "t_s", "119.5")),
        "slots.csv",
        "data row 240, column 't_s': 119.5 is not allowed; allowed: 119.0 (the same slot's time "
        "as UAV 'north'",
    ),
    "download edited": (
        _slots_edit(_more_download),
        "slots.csv",
        "column downloaded_mbit adds up to 950 Mbit but summary.json says",
    ),
    "download moved to another uav": (
        _slots_edit(_download_moved_to_another_uav),
        "slots.csv",
        "UAV 'north' downloaded",
    ),
    "uavs list gone": (
        _summary_edit(lambda s: s.pop("uavs")),
        "summary.json",
        "no 'uavs' list (one summary per UAV) but slots.csv has a uav column",
    ),
    "a uav without its download": (
        _summary_edit(lambda s: s["uavs"][1].pop("total_downloaded_mbit")),  # type: ignore[index]
        "summary.json: uavs[1]",
        "total_downloaded_mbit",
    ),
    "n_uavs wrong": (
        _summary_edit(lambda s: s.update(n_uavs=3)),
        "summary.json",
        "n_uavs = 3 but 'uavs' lists 2 UAVs (north, south)",
    ),
    "uav names repeated": (
        _summary_edit(lambda s: s["uavs"][1].update(uav="north")),  # type: ignore[index]
        "summary.json",
        "uavs: names must be unique; repeated: north",
    ),
}


@pytest.mark.parametrize("case", list(DAMAGE))
def test_damaged_fleet_folder_is_one_line_exit_2(fleet_run: Path, case: str) -> None:
    damage, file_name, message = DAMAGE[case]
    damage(fleet_run)
    done = run_cli("report", fleet_run, "--no-pdf")
    assert done.returncode == 2, done.stdout
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert f"{fleet_run / file_name}" in done.stderr and message in done.stderr, done.stderr
    assert not (fleet_run / "report.html").exists()


@pytest.mark.browser
def test_fleet_report_renders_in_chromium(fleet_run: Path, tmp_path: Path) -> None:
    """The page in a real headless Chromium: every figure decoded, nothing fetched, no error."""
    from test_browser import CHROMIUM, LAUNCH_ARGS

    if not CHROMIUM.is_file() or importlib.util.find_spec("playwright") is None:
        pytest.skip(f"needs {CHROMIUM} and the playwright package (pip install '.[browser]')")
    from playwright.sync_api import sync_playwright

    assert run_cli("report", fleet_run, "--no-pdf").returncode == 0
    errors: list[str] = []
    requests: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch_persistent_context(
            str(tmp_path / "profile"),
            executable_path=str(CHROMIUM),
            headless=True,
            args=LAUNCH_ARGS,
        )
        try:
            page = browser.new_page()
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.on(
                "request",
                lambda r: None if r.url.startswith(("file:", "data:")) else requests.append(r.url),
            )
            page.goto((fleet_run / "report.html").as_uri())
            page.wait_for_load_state("load")
            figures = page.locator("figure.fig img")
            assert figures.count() == len(FLEET_PANELS)
            sizes = figures.evaluate_all("imgs => imgs.map(i => [i.complete, i.naturalWidth])")
            assert all(done and width > 100 for done, width in sizes), sizes
            assert page.locator("#uav-table-0 tbody tr").count() == 3  # two UAVs + the fleet
        finally:
            browser.close()
    assert errors == [] and requests == [], (errors, requests)
