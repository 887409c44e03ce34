"""skymule analyze: a recorded AADM flight replayed under policies, plus its own download log."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from conftest import CliResult, run_cli
from skymule.errors import SkymuleError
from skymule.report.inputs import load_input
from skymule.tasks.analyze import analyze_flight, parse_buffers

FIXTURES = Path(__file__).parent / "fixtures"
LOG = FIXTURES / "aadm_merged_small.csv"
VOLUMES = FIXTURES / "aadm_volumes_small.txt"
DOWNLOADS = (
    "time,tower,mbit\n"
    "2025-05-24 16:19:31.500,LW1,2.0\n"
    "2025-05-24 16:19:32.500,snr_lw1,2.5\n"
    "2025-05-24 16:19:35.500,LW2,1.5\n"
)


def skymule(*args: str, cwd: Path) -> CliResult:
    return run_cli(*args, cwd=cwd)


def test_cli_analyze_writes_compare_folder_and_report(tmp_path: Path) -> None:
    (tmp_path / "downloads.csv").write_text(DOWNLOADS)
    done = skymule(
        "analyze",
        str(LOG),
        "--volumes",
        str(VOLUMES),
        "--download-log",
        "downloads.csv",
        "--out",
        "an",
        "--no-pdf",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    folder = tmp_path / "an"
    report = load_input(folder)
    assert report.kind == "compare"
    assert [r.label for r in report.runs] == ["flight", "greedy", "hgad"]
    table = pd.read_csv(folder / "comparison.csv")
    assert list(table["policy"]) == ["greedy", "hgad", "flight"]
    # buffers from the volume file, in column order
    assert report.runs[1].summary["per_sensor_buffer_mbit"] == {
        "LW1": 12.5,
        "LW2": 40.0,
        "LW3": 7.25,
        "LW4": 100.0,
    }
    # the flight run is what the download log says, slot by slot
    flight = report.runs[0].slots
    assert list(flight["served"][:6]) == ["LW1", "LW1", "", "", "LW2", ""]
    assert list(flight["downloaded_mbit"][:6]) == [2.0, 2.5, 0.0, 0.0, 1.5, 0.0]
    assert flight["remaining_mbit_LW1"].iloc[-1] == pytest.approx(12.5 - 4.5)
    # the replay used the recorded positions: same path for the flight and greedy
    greedy = report.runs[1].slots
    pd.testing.assert_series_equal(flight["x_m"], greedy["x_m"])
    page = (folder / "report.html").read_text()
    assert '<section id="comparison">' in page and ">flight<" in page
    assert not list((folder / "figures").glob("*.pdf"))  # --no-pdf
    # Lake Wheeler towers were recognised: drawn on the map with the geofence
    assert page.count('class="tower"') == 3 * 4 and 'class="fence"' in page


def test_log_with_missing_columns_is_one_line_error(tmp_path: Path) -> None:
    table = pd.read_csv(LOG).drop(columns=["Latitude"])
    table.to_csv(tmp_path / "broken.csv", index=False)
    done = skymule("analyze", "broken.csv", cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "broken.csv" in done.stderr and "Latitude" in done.stderr


def test_volume_count_must_match_log(tmp_path: Path) -> None:
    (tmp_path / "v.txt").write_text("10\n20\n")
    with pytest.raises(SkymuleError, match=r"v.txt: 2 volumes for 4 SNR columns"):
        analyze_flight(LOG, tmp_path / "out", policies=["greedy"], volumes=tmp_path / "v.txt")


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("time,tower\n1,LW1\n", "missing column(s) mbit"),
        ("time,tower,mbit\n1,LW9,2\n", "'LW9' is not a log sensor"),
        ("time,tower,mbit\n1,LW1,2\n1.5,LW2,1\n", "two towers in the slot at 1 s"),
        ("time,tower,mbit\n99,LW1,2\n", "outside the flight"),
        ("time,tower,mbit\n1,LW1,-2\n", "column mbit"),
    ],
)
def test_bad_download_log(tmp_path: Path, text: str, problem: str) -> None:
    (tmp_path / "d.csv").write_text(text)
    with pytest.raises(SkymuleError) as caught:
        analyze_flight(LOG, tmp_path / "out", policies=["greedy"], download_log=tmp_path / "d.csv")
    assert problem in str(caught.value) and "\n" not in str(caught.value)


def test_parse_buffers() -> None:
    assert parse_buffers("500", 3) == [500.0] * 3
    assert parse_buffers("1,2,3", 3) == [1.0, 2.0, 3.0]
    for bad in ("1,2", "x", "-1", ""):
        with pytest.raises(SkymuleError, match="--buffers"):
            parse_buffers(bad, 3)


def test_digital_twin_export_is_replayed_too(tmp_path: Path) -> None:
    (tmp_path / "downloads.csv").write_text("time,tower,mbit\n0.2,LW1,1.0\n2.4,LW3,0.5\n")
    done = skymule(
        "analyze",
        str(FIXTURES / "dt_export_small.csv"),
        "--buffers",
        "50",
        "--download-log",
        "downloads.csv",
        "--out",
        "dt",
        "--no-pdf",
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    report = load_input(tmp_path / "dt")
    assert [r.label for r in report.runs] == ["flight", "greedy", "hgad"]
    flight = report.runs[0].slots
    assert list(flight["served"][:3]) == ["LW1", "", "LW3"]
    assert report.runs[1].summary["per_sensor_buffer_mbit"]["LW4"] == 50.0


def test_an_impossible_controller_log_is_refused_tower_by_tower(tmp_path: Path) -> None:
    # LW1 holds 500 Mbit: a log crediting it 99,999 Mbit is not of this flight (it used to
    # score "complete at t1 = 1 s": 599)
    samples = Path(__file__).parents[1] / "examples" / "samples"
    rows = (samples / "flight_downloads.csv").read_text().splitlines()
    for at in range(3, len(rows)):  # a running total: from row 4 on
        cells = rows[at].split(",")
        rows[at] = ",".join([cells[0], "99999", *cells[2:]])
    (tmp_path / "dl.csv").write_text("\n".join(rows) + "\n")
    done = skymule(
        "analyze",
        str(samples / "flight_merged.csv"),
        *("--volumes", str(samples / "volumes.txt"), "--download-log", "dl.csv"),
        *("--out", "an", "--no-pdf"),
        cwd=tmp_path,
    )
    assert done.returncode == 2, done.stdout
    assert done.stderr.strip() == (
        "skymule: error: dl.csv: row 4, column dl_lw1: 99999 Mbit downloaded, more than the "
        "tower's volume of 500 Mbit; a tower can give at most its volume"
    )
    assert not (tmp_path / "an" / "summary.json").exists()
