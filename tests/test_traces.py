"""Tests for skymule.io.traces: AADM merged logs, digital-twin exports, volumes, writers."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from skymule.io.traces import (
    Trace,
    TraceError,
    normalise_column,
    positions_local,
    read_trace,
    read_volumes,
    write_aadm_log,
    write_dt_export,
)

FIXTURES = Path(__file__).parent / "fixtures"
AADM = FIXTURES / "aadm_merged_small.csv"
DT = FIXTURES / "dt_export_small.csv"
VOLUMES = FIXTURES / "aadm_volumes_small.txt"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _lines(path: Path) -> list[str]:
    return path.read_text(encoding="utf-8").splitlines()


def _replace_cell(src: Path, row: int, column: str, value: str) -> str:
    """Fixture text with the cell at file line ``row`` (header = 1) of ``column`` replaced."""
    lines = _lines(src)
    col = lines[0].split(",").index(column)
    cells = lines[row - 1].split(",")
    cells[col] = value
    lines[row - 1] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _error(path: Path) -> str:
    with pytest.raises(TraceError) as info:
        read_trace(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    return message


# ---------------------------------------------------------------- fixtures


def test_fixtures_are_regenerated_identically(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("make_fixtures", FIXTURES / "make_fixtures.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.write_csv(tmp_path / "a.csv", module.aadm_rows())
    module.write_csv(tmp_path / "d.csv", module.dt_rows())
    assert (tmp_path / "a.csv").read_bytes() == AADM.read_bytes()
    assert (tmp_path / "d.csv").read_bytes() == DT.read_bytes()


# ---------------------------------------------------------------- AADM


def test_aadm_loads_with_shapes_and_values() -> None:
    trace = read_trace(AADM)
    assert trace.format == "aadm"
    assert trace.path == str(AADM)
    assert trace.n_samples == 12
    assert trace.columns == ("LW1", "LW2", "LW3", "LW4")
    assert trace.snr_db.shape == (12, 4)
    assert trace.time_s.shape == trace.z_m.shape == (12,)
    assert trace.lat_deg is not None and trace.lon_deg is not None
    assert trace.x_m is None and trace.y_m is None
    np.testing.assert_allclose(trace.snr_db[0], [20.0, 21.0, 22.0, 23.0])
    np.testing.assert_allclose(trace.snr_db[-1], [14.5, 15.5, 16.5, 17.5])
    assert trace.lat_deg[0] == pytest.approx(35.7275)
    assert trace.lon_deg[-1] == pytest.approx(-78.6961900)
    assert trace.z_m[3] == pytest.approx(30.75)


def test_aadm_time_is_seconds_from_start_with_subsecond_precision() -> None:
    trace = read_trace(AADM)
    assert trace.time_s[0] == 0.0
    # 16:19:31.186 -> 16:19:32.193 -> 16:19:33.189 ... -> 16:19:42.186
    np.testing.assert_allclose(trace.time_s[:3], [0.0, 1.007, 2.003], atol=1e-9)
    assert trace.time_s[-1] == pytest.approx(11.0, abs=1e-9)
    assert np.all(np.diff(trace.time_s) > 0)


def test_aadm_deep_drop_is_kept_and_empty_cell_is_nan() -> None:
    trace = read_trace(AADM)
    lw3 = trace.snr_db[:, trace.column_index("snr_lw3")]
    assert lw3[5] == -50.0
    lw2 = trace.snr_db[:, trace.column_index("LW2")]
    assert np.isnan(lw2[8])
    np.testing.assert_array_equal(trace.missing_count(), [0, 1, 0, 0])


def test_aadm_any_sensor_names_and_extra_columns_ignored(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "odd.csv",
        "Battery,TIME,SNR_Front,snr_back,LONGITUDE,latitude,altitude,Yaw\n"
        "16.8,2025-05-24 16:19:31.186,10,-50,-78.6963,35.7275,0,1\n"
        "16.7,2025-05-24 16:19:31.686,,12.5,-78.6962,35.7276,5,2\n",
    )
    trace = read_trace(path)
    assert trace.format == "aadm"
    assert trace.columns == ("FRONT", "BACK")
    np.testing.assert_allclose(trace.time_s, [0.0, 0.5])
    assert np.isnan(trace.snr_db[1, 0])
    assert trace.snr_db[0, 1] == -50.0


def test_aadm_minus_99_is_a_value_not_missing(tmp_path: Path) -> None:
    path = _write(tmp_path, "a.csv", _replace_cell(AADM, 2, "snr_lw1", "-99"))
    assert read_trace(path).snr_db[0, 0] == -99.0


def test_aadm_numeric_time_is_seconds(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "a.csv",
        "time,snr_a,Longitude,Latitude,Altitude\n"
        "1716567571.25,1,-78.7,35.7,0\n1716567572.5,2,-78.7,35.7,0\n",
    )
    np.testing.assert_allclose(read_trace(path).time_s, [0.0, 1.25])


# ---------------------------------------------------------------- digital twin


def test_dt_loads_with_shapes_values_and_missing_markers() -> None:
    trace = read_trace(DT)
    assert trace.format == "dt"
    assert trace.columns == ("LW1", "LW2", "LW3", "LW4")
    assert trace.snr_db.shape == (12, 4)
    assert trace.lat_deg is None and trace.lon_deg is None
    assert trace.x_m is not None and trace.y_m is not None
    np.testing.assert_allclose(trace.time_s, 0.5 * np.arange(12))  # 3.5 s -> 0 s
    assert np.isnan(trace.snr_db[2, 1])
    assert np.isnan(trace.snr_db[7, 3])
    np.testing.assert_array_equal(trace.missing_count(), [0, 1, 0, 1])
    assert trace.snr_db[0, 0] == 15.0
    np.testing.assert_allclose(trace.x_m, 10.0 * np.arange(12))
    np.testing.assert_allclose(trace.y_m, -5.0 * np.arange(12))
    np.testing.assert_allclose(trace.z_m, 40.0)


def test_dt_below_minus_99_and_empty_cells_are_missing(tmp_path: Path) -> None:
    text = _replace_cell(DT, 2, "LW1", "-120.5")
    path = _write(tmp_path, "d.csv", text.replace("13.00,12.00,11.00,10.00", "13.00,,11.00,10.00"))
    trace = read_trace(path)
    assert np.isnan(trace.snr_db[0, 0])
    assert np.isnan(trace.snr_db[8, 1])
    assert trace.missing_count().sum() == 4


def test_dt_ignores_pandas_index_column(tmp_path: Path) -> None:
    path = _write(tmp_path, "d.csv", ",Time,LW1,X,Y,Height\n0,0,1,0,0,10\n1,1,2,0,0,10\n")
    assert read_trace(path).columns == ("LW1",)


# ---------------------------------------------------------------- Trace API


def test_column_index_accepts_spellings_and_names_available() -> None:
    trace = read_trace(DT)
    assert trace.column_index("LW3") == trace.column_index("lw3") == 2
    assert trace.column_index("snr_lw3") == 2
    with pytest.raises(TraceError, match=r"'LW9'.*available: LW1, LW2, LW3, LW4"):
        trace.column_index("LW9")


def test_normalise_column() -> None:
    assert normalise_column("snr_lw1") == "LW1"
    assert normalise_column(" Lw2 ") == "LW2"
    assert normalise_column("SNR_") == "SNR_"


def test_trace_arrays_are_read_only() -> None:
    trace = read_trace(DT)
    with pytest.raises(ValueError):
        trace.snr_db[0, 0] = 1.0


def test_trace_rejects_bad_shapes() -> None:
    with pytest.raises(ValueError, match="snr_db"):
        Trace("x", "dt", np.arange(3.0), np.zeros((3, 2)), ("A",), None, None,
              np.zeros(3), np.zeros(3), np.zeros(3))  # fmt: skip


def test_sensors_argument_selects_and_orders(tmp_path: Path) -> None:
    trace = read_trace(AADM, sensors=["lw4", "snr_LW1"])
    assert trace.columns == ("LW4", "LW1")
    np.testing.assert_allclose(trace.snr_db[0], [23.0, 20.0])
    lines = _lines(AADM)
    lines[0] = lines[0].replace("snr_lw2", "other")
    path = _write(tmp_path, "flight.csv", "\n".join(lines) + "\n")
    with pytest.raises(TraceError) as info:
        read_trace(path, sensors=["LW1", "LW2"])
    message = str(info.value)
    assert message.startswith(f"{path}: column 'snr_lw2' is missing (columns present: time,")


def test_positions_local() -> None:
    dt = read_trace(DT)
    pos = positions_local(dt)
    assert pos.shape == (12, 3)
    np.testing.assert_allclose(pos[:, 0], dt.x_m)
    aadm = read_trace(AADM)
    calls: list[tuple[np.ndarray, np.ndarray]] = []

    def to_local(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        calls.append((lat, lon))
        return (lon + 78.6963) * 1e5, (lat - 35.7275) * 1e5

    pos = positions_local(aadm, to_local)
    assert len(calls) == 1
    assert pos.shape == (12, 3)
    np.testing.assert_allclose(pos[:, 0], np.arange(12.0), atol=1e-6)
    np.testing.assert_allclose(pos[:, 1], 2 * np.arange(12.0), atol=1e-6)
    np.testing.assert_allclose(pos[:, 2], aadm.z_m)
    with pytest.raises(ValueError, match="to_local"):
        positions_local(aadm)


# ---------------------------------------------------------------- format detection


@pytest.mark.parametrize(
    ("header", "expected"),
    [
        ("time,snr_lw1,Longitude,Latitude,Altitude", "aadm"),
        ("TIME,SNR_A,LONGITUDE,LATITUDE,ALTITUDE,x,y", "aadm"),
        ("Time,LW1,X,Y,Height", "dt"),
        ("time,a,b,x,y,height", "dt"),
    ],
)
def test_format_detection(tmp_path: Path, header: str, expected: str) -> None:
    row = ",".join(["0"] * len(header.split(",")))
    path = _write(tmp_path, "f.csv", f"{header}\n{row}\n")
    assert read_trace(path).format == expected


def test_unrecognised_format(tmp_path: Path) -> None:
    path = _write(tmp_path, "flight.csv", "a,b,c\n1,2,3\n")
    message = _error(path)
    assert "unrecognised format: expected AADM merged-log columns" in message
    assert "(Time, <names>..., X, Y, Height)" in message


def test_semicolon_file_gets_a_hint(tmp_path: Path) -> None:
    path = _write(tmp_path, "flight.csv", "Time;LW1;X;Y;Height\n0;1;0;0;0\n")
    assert "comma-separated" in _error(path)


@pytest.mark.parametrize(
    ("header", "missing"),
    [
        ("time,snr_lw1,Longitude,Altitude", "Latitude"),
        ("snr_lw1,Longitude,Latitude,Altitude", "time"),
        ("Time,LW1,X,Y", "Height"),
        ("LW1,X,Y,Height", "Time"),
    ],
)
def test_missing_required_column(tmp_path: Path, header: str, missing: str) -> None:
    row = ",".join(["0"] * len(header.split(",")))
    path = _write(tmp_path, "flight.csv", f"{header}\n{row}\n")
    message = _error(path)
    assert f"column '{missing}' is missing (columns present: {header.replace(',', ', ')})" in (
        message
    )


def test_no_snr_columns(tmp_path: Path) -> None:
    path = _write(tmp_path, "f.csv", "time,Longitude,Latitude,Altitude\n0,0,0,0\n")
    assert "no SNR columns" in _error(path)
    path = _write(tmp_path, "g.csv", "Time,X,Y,Height\n0,0,0,0\n")
    assert "no SNR columns" in _error(path)


def test_duplicate_sensor_columns(tmp_path: Path) -> None:
    path = _write(tmp_path, "f.csv", "Time,LW1,snr_lw1,X,Y,Height\n0,1,2,0,0,0\n")
    assert "'LW1' and 'snr_lw1' both name sensor 'LW1'" in _error(path)
    path = _write(tmp_path, "g.csv", "Time,time,LW1,X,Y,Height\n0,0,1,0,0,0\n")
    assert "'Time' and 'time'" in _error(path)


# ---------------------------------------------------------------- bad files


def test_missing_file(tmp_path: Path) -> None:
    assert _error(tmp_path / "flight.csv").endswith("file not found")


def test_directory(tmp_path: Path) -> None:
    assert "is a directory" in _error(tmp_path)


@pytest.mark.parametrize("text", ["", "\n\n", "  \n"])
def test_empty_file(tmp_path: Path, text: str) -> None:
    assert "empty file" in _error(_write(tmp_path, "flight.csv", text))


@pytest.mark.parametrize("src", [AADM, DT])
def test_header_only(tmp_path: Path, src: Path) -> None:
    path = _write(tmp_path, "flight.csv", _lines(src)[0] + "\n")
    assert _error(path) == f"{path}: no data rows (the file has only a header)"


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "flight.csv"
    path.write_bytes(b"\xff\xfe\x00\x01garbage")
    assert "not a UTF-8 text file" in _error(path)


@pytest.mark.parametrize(
    ("src", "row", "column", "value", "fragment"),
    [
        (DT, 7, "LW1", "abc", "row 7, column 'LW1': 'abc' is not a number"),
        (AADM, 4, "snr_lw2", "n/a dB", "row 4, column 'snr_lw2': 'n/a dB' is not a number"),
        (AADM, 5, "Latitude", "35.7x", "row 5, column 'Latitude': '35.7x' is not a number"),
        (AADM, 6, "Longitude", "", "row 6, column 'Longitude': is empty; a value is required"),
        (AADM, 3, "Altitude", "high", "row 3, column 'Altitude': 'high' is not a number"),
        (DT, 9, "X", "1,5", "row 9 has 9 fields but the header has 8"),
        (DT, 4, "Height", "inf", "row 4, column 'Height': 'inf' is not a number"),
        (DT, 4, "LW2", "1e999", "row 4, column 'LW2': '1e999' is out of range"),
        (AADM, 8, "Latitude", "135.7", "row 8, column 'Latitude': '135.7' is out of range"),
        (DT, 5, "Time", "later", "row 5, column 'Time': 'later' is not a number (seconds)"),
        (AADM, 5, "time", "yesterday", "row 5, column 'time': 'yesterday' is not a timestamp"),
    ],
)
def test_bad_cell(
    tmp_path: Path, src: Path, row: int, column: str, value: str, fragment: str
) -> None:
    path = _write(tmp_path, "flight.csv", _replace_cell(src, row, column, value))
    message = _error(path)
    assert fragment in message
    assert "\n" not in message


def test_bad_cell_with_newline_stays_one_line(tmp_path: Path) -> None:
    path = _write(tmp_path, "flight.csv", _replace_cell(DT, 3, "LW1", '"1\n2"'))
    assert "'1\\n2' is not a number" in _error(path)


@pytest.mark.parametrize(
    ("src", "column", "value"),
    [(DT, "Time", "5.0"), (DT, "Time", "4.9"), (AADM, "time", "2025-05-24 16:19:33.189")],
)
def test_non_increasing_time(tmp_path: Path, src: Path, column: str, value: str) -> None:
    path = _write(tmp_path, "flight.csv", _replace_cell(src, 6, column, value))
    message = _error(path)
    assert f"row 6, column '{column}': '{value}' is not after the previous row's" in message
    assert "strictly increasing" in message


def test_truncated_last_row(tmp_path: Path) -> None:
    text = AADM.read_text(encoding="utf-8")[:-40]
    path = _write(tmp_path, "flight.csv", text)
    assert "row 13 has" in _error(path)


# ---------------------------------------------------------------- volumes


def test_read_volumes() -> None:
    np.testing.assert_array_equal(read_volumes(VOLUMES), [12.5, 40.0, 7.25, 100.0])


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("1\n2\nlots\n", "line 3: 'lots' is not a number"),
        ("1\n\n-2\n", "line 3: '-2' is not a valid volume"),
        ("\n\n", "no volumes"),
    ],
)
def test_read_volumes_errors(tmp_path: Path, text: str, fragment: str) -> None:
    path = _write(tmp_path, "volumes.txt", text)
    with pytest.raises(TraceError) as info:
        read_volumes(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    assert fragment in message
    assert "\n" not in message


def test_read_volumes_missing_file(tmp_path: Path) -> None:
    with pytest.raises(TraceError, match=r"volumes\.txt: file not found"):
        read_volumes(tmp_path / "volumes.txt")


# ---------------------------------------------------------------- writers


def test_aadm_round_trip(tmp_path: Path) -> None:
    original = read_trace(AADM)
    out = write_aadm_log(
        tmp_path / "copy.csv",
        original.time_s,
        original.snr_db,
        original.columns,
        original.lat_deg,
        original.lon_deg,
        original.z_m,
        extra={"Battery": np.linspace(16.8, 16.7, 12)},
    )
    again = read_trace(out)
    assert again.format == "aadm"
    assert again.columns == original.columns
    np.testing.assert_allclose(again.time_s, original.time_s, atol=1e-9)
    np.testing.assert_array_equal(again.snr_db, original.snr_db)  # NaN == NaN here
    np.testing.assert_array_equal(again.lat_deg, original.lat_deg)
    np.testing.assert_array_equal(again.lon_deg, original.lon_deg)
    np.testing.assert_array_equal(again.z_m, original.z_m)
    assert _lines(out)[1].startswith("2025-05-24 16:19:31.186,")


def test_dt_round_trip(tmp_path: Path) -> None:
    original = read_trace(DT)
    out = write_dt_export(
        tmp_path / "copy.csv",
        original.time_s,
        original.snr_db,
        original.columns,
        original.x_m,
        original.y_m,
        original.z_m,
    )
    assert _lines(out)[0] == "Time,LW1,LW2,LW3,LW4,X,Y,Height"
    assert "-99.0" in out.read_text(encoding="utf-8")
    again = read_trace(out)
    assert again.format == "dt"
    np.testing.assert_array_equal(again.time_s, original.time_s)
    np.testing.assert_array_equal(again.snr_db, original.snr_db)
    np.testing.assert_array_equal(again.x_m, original.x_m)
    np.testing.assert_array_equal(again.z_m, original.z_m)


def test_writers_reject_bad_input(tmp_path: Path) -> None:
    t = np.arange(3.0)
    z = np.zeros(3)
    with pytest.raises(ValueError, match="read back as missing"):
        write_dt_export(tmp_path / "a.csv", t, np.full((3, 1), -100.0), ["A"], z, z, z)
    with pytest.raises(ValueError, match="clash"):
        write_dt_export(tmp_path / "a.csv", t, np.zeros((3, 1)), ["X"], z, z, z)
    with pytest.raises(ValueError, match="strictly increasing"):
        write_dt_export(tmp_path / "a.csv", t[::-1], np.zeros((3, 1)), ["A"], z, z, z)
    with pytest.raises(ValueError, match="snr_db has shape"):
        write_aadm_log(tmp_path / "a.csv", t, np.zeros((3, 2)), ["A"], z, z, z)
    with pytest.raises(ValueError, match="1 ms"):
        write_aadm_log(tmp_path / "a.csv", np.array([0, 1e-4, 1]), np.zeros((3, 1)), ["A"], z, z, z)
