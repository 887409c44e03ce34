"""AADM's own files: volumes, the controller's download log, agent<->comm files; analyze."""

from __future__ import annotations

from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from skymule.aadm import files
from skymule.errors import SkymuleError
from skymule.tasks.analyze import analyze_flight

FIXTURES = Path(__file__).parent / "fixtures"
LOG = FIXTURES / "aadm_merged_small.csv"
VOLUMES = FIXTURES / "aadm_volumes_small.txt"  # 12.5 / 40 / 7.25 / 100 Mbit


def test_volume_file_with_3_lines_for_4_towers_is_one_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "vol.txt"
    path.write_text("10\n30\n90\n")
    with pytest.raises(SkymuleError, match=r"vol.txt: 3 volume line\(s\) for 4 towers"):
        files.read_volume_file(path, 4)
    files.write_volume_file(path, np.array([10, 30, 90, 270.5]))
    assert list(files.read_volume_file(path, 4)) == [10, 30, 90, 270.5]


def test_download_log_round_trip_and_per_slot_increments(tmp_path: Path) -> None:
    path = tmp_path / "dl.csv"
    writer = files.DownloadLogWriter(path, 4)
    start = datetime(2025, 5, 24, 16, 19, 32, 181307)
    for k, totals in enumerate([[1, 0, 0, 0], [2.5, 0, 0, 0], [2.5, 3, 0, 0]]):
        writer.write(start + timedelta(seconds=k), np.array(totals, float))
    writer.close()
    assert path.read_text().splitlines()[:2] == [
        "time,dl_lw1,dl_lw2,dl_lw3,dl_lw4",
        "2025-05-24 16:19:32.181307,1.000000,0.000000,0.000000,0.000000",
    ]
    assert files.is_aadm_download_log(path)
    log = files.read_download_log(path)
    assert log.start == start and list(log.time_s) == [0.0, 1.0, 2.0]
    np.testing.assert_allclose(log.per_slot_mbit()[:, :2], [[1, 0], [1.5, 0], [0, 3]])


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("time,tower,mbit\n", "is not the controller's"),
        ("time,dl_lw1\n", "header and no rows"),
        ("time,dl_lw1\nyesterday,1\n", "row 2, column time: 'yesterday'"),
        ("time,dl_lw1\n2025-05-24 16:19:32.1,x\n", "row 2, column dl_lw1: 'x'"),
        ("time,dl_lw1\n2025-05-24 16:19:32.1,2\n2025-05-24 16:19:33.1,1\n", "went down"),
    ],
)
def test_bad_download_log_is_one_line(tmp_path: Path, text: str, problem: str) -> None:
    path = tmp_path / "dl.csv"
    path.write_text(text)
    with pytest.raises(SkymuleError, match=problem):
        files.read_download_log(path)


def test_comm_files_round_trip_atomically(tmp_path: Path) -> None:
    files.write_tower_file(tmp_path / files.SNR_FILE, np.array([-99, 12.5, 3, -99.0]))
    assert (tmp_path / "ss.txt").read_text() == "1: -99, 2: 12.5, 3: 3, 4: -99\n"
    assert list(files.read_tower_file(tmp_path / "ss.txt", 4)) == [-99, 12.5, 3, -99]
    files.write_done_file(tmp_path / "tn.txt", True)
    assert (tmp_path / "tn.txt").read_text().strip() == "-1" and files.read_done_file(
        tmp_path / "tn.txt"
    )
    files.write_choice_file(tmp_path / "bc.txt", 3)
    assert files.read_choice_file(tmp_path / "bc.txt", 4) == 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bc.txt", "ss.txt", "tn.txt"]
    # an unreadable value is NaN (the controller then counts 0 dB)
    assert np.isnan(files.parse_tower_values("1: nan, 2: 4", "ss.txt", 2)[0])


@pytest.mark.parametrize(
    ("text", "problem"),
    [("1: 3, 2: 4", r"expected ids 1..4"), ("1 -99", "is not 'tower_id: value'"), ("", "ids")],
)
def test_bad_comm_file(text: str, problem: str) -> None:
    with pytest.raises(SkymuleError, match=problem):
        files.parse_tower_values(text, "ss.txt", 4)


def test_unknown_tower_id_is_refused() -> None:
    with pytest.raises(SkymuleError, match=r"tower id '5' is not allowed; allowed: 1..4"):
        files.parse_tower_id("5", 4, "bc.txt")


def _aadm_log(path: Path, start: str, rows: list[list[float]]) -> None:
    first = datetime.strptime(start, files.TIME_FORMAT)
    writer = files.DownloadLogWriter(path, 4)
    for k, totals in enumerate(rows):
        writer.write(first + timedelta(seconds=k), np.asarray(totals, float))
    writer.close()


def test_analyze_scores_an_aadm_download_log_as_the_controller(tmp_path: Path) -> None:
    # volumes 12.5/40/7.25/100 (159.75 Mbit); the log starts one second into the flight
    path = tmp_path / "dl.csv"
    _aadm_log(
        path,
        "2025-05-24 16:19:32.500000",
        [[2, 0, 0, 0], [4.5, 0, 0, 0], [4.5, 0, 0, 0], [4.5, 1.5, 0, 0]],
    )
    rows = analyze_flight(
        LOG, tmp_path / "an", policies=["greedy"], volumes=VOLUMES, download_log=path
    )
    flight = next(r for r in rows if r["policy"] == "flight")
    assert flight["total_downloaded_mbit"] == pytest.approx(6.0)
    assert flight["aadm_complete"] is False
    assert flight["aadm_t1_s"] == 4.0  # four polls logged, the window still open
    assert flight["aadm_score"] == pytest.approx(100 * 6.0 / 159.75)
    slots = pd.read_csv(tmp_path / "an" / "flight" / "slots.csv", keep_default_na=False)
    assert list(slots["served"][:6]) == ["", "LW1", "LW1", "", "LW2", ""]
    # the replay is scored by the same rule, from the first sample above 24 m (slot 0 here)
    greedy = next(r for r in rows if r["policy"] == "greedy")
    assert greedy["aadm_score"] == pytest.approx(
        greedy["aadm_s1"] + 100 * greedy["total_downloaded_mbit"] / 159.75
    )


def test_cli_analyze_with_a_wrong_tower_count_is_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "dl.csv"
    path.write_text("time,dl_lw1,dl_lw2\n2025-05-24 16:19:32.500000,1,0\n")
    done = run_cli(
        "analyze", str(LOG), "--download-log", str(path), "--out", "an", "--no-pdf", cwd=tmp_path
    )
    assert done.returncode == 2
    assert "2 tower columns for the 4 SNR columns" in done.stderr
    assert "Traceback" not in done.stderr


def test_comm_writes_the_files_byte_for_byte_as_the_comm_script(tmp_path: Path) -> None:
    from skymule.aadm.comm import reset_files, write_reply_files

    reset_files(tmp_path, 4)
    assert (tmp_path / "ss.txt").read_text() == "1: -99, 2: -99, 3: -99, 4: -99"
    assert (tmp_path / "dv.txt").read_text() == "1: 0.0, 2: 0.0, 3: 0.0, 4: 0.0"
    assert (tmp_path / "tn.txt").read_text() == "0" and (tmp_path / "bc.txt").read_text() == ""
    snr = "1:38.992650,2:16.200000,3:15.200000,4:-99.000000"
    write_reply_files(
        tmp_path, f"vol:{{'1': 500.0, '2': 800.0, '3': 700.0, '4': 1000.0}};snr:{snr}"
    )
    assert (tmp_path / "ss.txt").read_text() == snr
    assert (tmp_path / "dv.txt").read_text() == "1:500.0, 2:800.0, 3:700.0, 4:1000.0"
    write_reply_files(tmp_path, f"download:1:7.77,2:0.00,3:0.00,4:0.00;snr:{snr}")
    assert (tmp_path / "dd.txt").read_text() == "1:7.77, 2:0.00, 3:0.00, 4:0.00"
    write_reply_files(tmp_path, "download:None;snr:1:1.000000,2:2.000000,3:3.000000,4:4.000000")
    assert (tmp_path / "ss.txt").read_text() == snr  # the script stops at the part it fails on
    write_reply_files(tmp_path, f"download_complete:1;snr:{snr}")
    assert (tmp_path / "tn.txt").read_text() == "-1"
    # what it wrote reads back as the agent reads it
    assert files.read_tower_file(tmp_path / "ss.txt", 4).tolist() == [38.99265, 16.2, 15.2, -99.0]
    assert files.read_done_file(tmp_path / "tn.txt")
