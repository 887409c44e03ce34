"""Damaged run folders handed to plot/report/export: one line naming the file, exit 2.

Each case damages one file of a real run folder the way a user (or a crash) does, and checks
the readers refuse it with a line naming the file, the row/column and what is allowed, rather
than drawing a figure from part of the mission or raising a traceback.
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.io.runs import read_run
from skymule.report.inputs import load_run


@pytest.fixture(scope="module")
def pristine(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("runs") / "run"
    done = run_cli("run", "paper-sim-fixed", "--policy", "greedy", "--out", str(out))
    assert done.returncode == 0, done.stderr
    return out


@pytest.fixture
def run_dir(pristine: Path, tmp_path: Path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(pristine, copy)
    return copy


def _edit_lines(path: Path, edit: Callable[[list[str]], list[str]]) -> None:
    path.write_text("\n".join(edit(path.read_text().splitlines())) + "\n")


def _set_cell(row: int, column: str, value: str) -> Callable[[list[str]], list[str]]:
    def edit(lines: list[str]) -> list[str]:
        header = lines[0].split(",")
        cells = lines[row].split(",")
        cells[header.index(column)] = value
        return [*lines[:row], ",".join(cells), *lines[row + 1 :]]

    return edit


def _edit_json(path: Path, **changes: object) -> None:
    data = json.loads(path.read_text())
    for dotted, value in changes.items():
        node = data
        *parents, last = dotted.split("__")
        for key in parents:
            node = node[int(key)] if isinstance(node, list) else node[key]
        node[last] = value
    path.write_text(json.dumps(data))


def _error(run_dir: Path) -> str:
    with pytest.raises(SkymuleError) as caught:
        read_run(run_dir)
    message = str(caught.value)
    assert "\n" not in message
    return message


def test_pristine_folder_reads(run_dir: Path) -> None:
    summary, slots = read_run(run_dir)
    assert len(slots) == summary["slots"] == 500
    assert load_run(run_dir).scenario["name"] == "paper-sim-fixed"


def test_text_in_a_numeric_column_names_row_and_column(run_dir: Path) -> None:
    _edit_lines(run_dir / "slots.csv", _set_cell(37, "rate_mbps", "abc"))
    message = _error(run_dir)
    assert "slots.csv: data row 37, column 'rate_mbps': 'abc'" in message
    assert "allowed: a finite number" in message


def test_empty_cell_in_a_required_column(run_dir: Path) -> None:
    _edit_lines(run_dir / "slots.csv", _set_cell(5, "downloaded_mbit", ""))
    assert "data row 5, column 'downloaded_mbit': an empty cell" in _error(run_dir)


def test_unknown_served_sensor_and_bad_hovering(run_dir: Path) -> None:
    _edit_lines(run_dir / "slots.csv", _set_cell(3, "served", "LW9"))
    assert "column 'served': 'LW9' is not allowed; allowed: empty or one of LW1" in (
        _error(run_dir)
    )
    _edit_lines(run_dir / "slots.csv", _set_cell(3, "served", "LW1"))
    _edit_lines(run_dir / "slots.csv", _set_cell(8, "hovering", "2"))
    assert "data row 8, column 'hovering': 2" in _error(run_dir)


def test_header_only_slots(run_dir: Path) -> None:
    _edit_lines(run_dir / "slots.csv", lambda lines: lines[:1])
    assert "slots.csv: header only, no slot rows (summary.json says slots = 500)" in (
        _error(run_dir)
    )


def test_truncated_slots_is_never_plotted_from_part_of_the_mission(run_dir: Path) -> None:
    text = (run_dir / "slots.csv").read_text()
    cut = text.index("\n", len(text) // 2) + 30  # mid-row, as a killed writer leaves it
    (run_dir / "slots.csv").write_text(text[:cut])
    message = _error(run_dir)
    assert "slots.csv:" in message and "slot rows but summary.json says slots = 500" in message
    done = run_cli("plot", str(run_dir))
    assert done.returncode == 2 and not (run_dir / "download.png").exists()


def test_decreasing_time_is_refused(run_dir: Path) -> None:
    _edit_lines(run_dir / "slots.csv", _set_cell(10, "t_s", "3"))
    assert "data row 10, column 't_s': 3" in _error(run_dir)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"per_sensor_downloaded_mbit": "lots"}, "per_sensor_downloaded_mbit"),
        ({"total_downloaded_mbit": "12"}, "total_downloaded_mbit = '12': must be a number"),
        ({"slots": True}, "slots = True: must be a whole number"),
        ({"per_sensor_buffer_mbit__LW1": -5}, "per_sensor_buffer_mbit.LW1 = -5"),
        ({"aadm_complete": "yes"}, "aadm_complete = 'yes': must be true or false"),
    ],
)
def test_wrong_types_in_summary(run_dir: Path, change: dict[str, object], expected: str) -> None:
    _edit_json(run_dir / "summary.json", **change)
    message = _error(run_dir)
    assert "summary.json:" in message and expected in message


def test_summary_that_is_not_json_or_not_utf8(run_dir: Path) -> None:
    (run_dir / "summary.json").write_text("{not json")
    assert "summary.json: not valid JSON" in _error(run_dir)
    (run_dir / "summary.json").write_bytes(b'{"scenario": "\xff"}')
    assert "summary.json: not a UTF-8 text file" in _error(run_dir)


def test_wrong_types_in_scenario_json(run_dir: Path) -> None:
    _edit_json(run_dir / "scenario.json", sensors__0__buffer_mbit="500")
    message = _error(run_dir)
    assert "scenario.json: sensors[0].buffer_mbit = '500': must be a number" in message


def test_sensors_of_slots_and_summary_must_agree(run_dir: Path) -> None:
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("per_sensor_downloaded_mbit", "per_sensor_buffer_mbit"):
        summary[key] = {"X" + k: v for k, v in summary[key].items()}
    (run_dir / "summary.json").write_text(json.dumps(summary))
    assert "do not match summary.json's sensors XLW1" in _error(run_dir)


@pytest.mark.parametrize(
    "command",
    [("plot",), ("report", "--no-pdf"), ("export", "--geojson")],
)
def test_cli_readers_exit_2_with_one_line(run_dir: Path, command: tuple[str, ...]) -> None:
    _edit_json(run_dir / "scenario.json", sensors__1__x_m="far")
    _edit_lines(run_dir / "slots.csv", _set_cell(12, "x_m", "abc"))
    done = run_cli(command[0], str(run_dir), *command[1:])
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr
    assert "slots.csv: data row 12, column 'x_m': 'abc'" in lines[0]


def test_slots_that_are_not_text(run_dir: Path) -> None:
    (run_dir / "slots.csv").write_bytes(b"t_s,x_m\n\xff\xfe,1\n")
    assert "slots.csv: not a UTF-8 text file" in _error(run_dir)
    (run_dir / "slots.csv").write_bytes(b"")
    assert "slots.csv: empty file" in _error(run_dir)


def test_statistics_that_do_not_apply_may_be_nan(run_dir: Path) -> None:
    _edit_json(run_dir / "summary.json", distance_to_home_m=float("nan"), energy_kj=float("nan"))
    summary, _ = read_run(run_dir)
    assert math.isnan(summary["distance_to_home_m"])
    _edit_json(run_dir / "summary.json", energy_kj=-1.0)
    assert "energy_kj = -1.0: must be >= 0" in _error(run_dir)


def test_served_column_all_empty_or_numeric_names(run_dir: Path) -> None:
    """A run that served nothing (every cell empty), and sensors named by numbers."""
    slots = (run_dir / "slots.csv").read_text().splitlines()
    header = slots[0].split(",")
    column = header.index("served")
    rows = []
    for line in slots[1:]:
        cells = line.split(",")
        cells[column] = "" if len(rows) % 2 else "1"
        rows.append(",".join(cells))
    (run_dir / "slots.csv").write_text("\n".join([slots[0].replace("LW1", "1"), *rows]) + "\n")
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("per_sensor_downloaded_mbit", "per_sensor_buffer_mbit"):
        summary[key] = {("1" if k == "LW1" else k): v for k, v in summary[key].items()}
    (run_dir / "summary.json").write_text(json.dumps(summary))
    _, table = read_run(run_dir)
    assert table["served"].tolist()[:4] == ["1", "", "1", ""]
    _edit_lines(
        run_dir / "slots.csv",
        lambda lines: (
            [lines[0]]
            + [
                ",".join("" if i == column else c for i, c in enumerate(line.split(",")))
                for line in lines[1:]
            ]
        ),
    )
    _, table = read_run(run_dir)
    assert set(table["served"]) == {""}
