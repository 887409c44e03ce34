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
    """Sensors named by numbers, and a run that served nothing (every cell empty)."""
    lines = (run_dir / "slots.csv").read_text().splitlines()
    header = lines[0].split(",")
    served, down = header.index("served"), header.index("downloaded_mbit")
    renamed = [",".join("1" if (i == served and c == "LW1") else c
                        for i, c in enumerate(line.split(","))) for line in lines[1:]]  # fmt: skip
    (run_dir / "slots.csv").write_text("\n".join([lines[0].replace("LW1", "1"), *renamed]) + "\n")
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("per_sensor_downloaded_mbit", "per_sensor_buffer_mbit"):
        summary[key] = {("1" if k == "LW1" else k): v for k, v in summary[key].items()}
    (run_dir / "summary.json").write_text(json.dumps(summary))
    _edit_json(run_dir / "scenario.json", sensors__0__name="1")
    _, table = read_run(run_dir)
    assert "1" in set(table["served"]) and "LW1" not in set(table["served"])
    nothing = [",".join("" if i == served else "0" if i == down else c
                        for i, c in enumerate(line.split(","))) for line in renamed]  # fmt: skip
    (run_dir / "slots.csv").write_text("\n".join([lines[0].replace("LW1", "1"), *nothing]) + "\n")
    zero = {k: 0.0 for k in summary["per_sensor_downloaded_mbit"]}
    _edit_json(run_dir / "summary.json", per_sensor_downloaded_mbit=zero, total_downloaded_mbit=0)
    _, table = read_run(run_dir)
    assert set(table["served"]) == {""}


# --- the folder as a whole (issue 24): each file valid, together inconsistent --------------


def test_a_total_beyond_the_buffers_is_refused(run_dir: Path) -> None:
    """The audit's summary.json claiming 1e9 Mbit against 3,000 Mbit of buffers."""
    _edit_json(run_dir / "summary.json", total_downloaded_mbit=1e9)
    assert "summary.json: total_downloaded_mbit = 1e+09 but per_sensor_downloaded_mbit adds" in (
        _error(run_dir)
    )
    summary = json.loads((run_dir / "summary.json").read_text())
    per = {k: 1e9 / 4 for k in summary["per_sensor_downloaded_mbit"]}
    _edit_json(run_dir / "summary.json", per_sensor_downloaded_mbit=per)
    assert "summary.json: sensor 'LW1' gave 2.5e+08 Mbit, more than its buffer of" in (
        _error(run_dir)
    )


def test_downloads_multiplied_in_the_slot_table_are_refused(run_dir: Path) -> None:
    """The audit's slots.csv with every download times 10."""
    lines = (run_dir / "slots.csv").read_text().splitlines()
    column = lines[0].split(",").index("downloaded_mbit")

    def times_ten(line: str) -> str:
        cells = line.split(",")
        cells[column] = repr(float(cells[column]) * 10)
        return ",".join(cells)

    (run_dir / "slots.csv").write_text("\n".join([lines[0], *map(times_ten, lines[1:])]) + "\n")
    message = _error(run_dir)
    assert "slots.csv: column downloaded_mbit adds up to" in message
    assert "but summary.json says total_downloaded_mbit" in message


def test_one_slot_moved_to_another_sensor_is_refused(run_dir: Path) -> None:
    lines = (run_dir / "slots.csv").read_text().splitlines()
    header = lines[0].split(",")
    row = next(
        i for i, line in enumerate(lines[1:], 1) if line.split(",")[header.index("served")] == "LW1"
    )
    _edit_lines(run_dir / "slots.csv", _set_cell(row, "served", "LW2"))
    assert "slots.csv: the slots serving 'LW1' download" in _error(run_dir)


def test_a_scenario_listing_other_sensors_is_refused(run_dir: Path) -> None:
    """The audit's scenario.json listing 2 of the 4 sensors."""
    scenario = json.loads((run_dir / "scenario.json").read_text())
    scenario["sensors"] = scenario["sensors"][:2]
    (run_dir / "scenario.json").write_text(json.dumps(scenario))
    assert "scenario.json: sensors LW1, LW2 do not match the run's sensors LW1, LW2, LW3, LW4" in (
        _error(run_dir)
    )


@pytest.mark.parametrize("command", [("plot",), ("report", "--no-pdf"), ("export", "--kml")])
def test_every_reader_refuses_an_inconsistent_folder(
    run_dir: Path, command: tuple[str, ...]
) -> None:
    _edit_json(run_dir / "summary.json", total_downloaded_mbit=1e9)
    done = run_cli(command[0], str(run_dir), *command[1:])
    assert done.returncode == 2, done.stderr
    [line] = done.stderr.strip().splitlines()
    assert "total_downloaded_mbit = 1e+09" in line
    assert not any(run_dir.glob("*.png")) and not (run_dir / "flight.kml").exists()
