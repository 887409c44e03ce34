"""Property-based fuzzing of what issue 24 made safe: run folders checked as a whole, rate
tables, model files and policy names, and the AADM protocol's lines.

Every reader returns a result that keeps its promises or raises one :class:`SkymuleError`
line; nothing a file names is imported or unpickled. Example counts are small and the
examples fixed (``derandomize``), as in ``test_fuzz_inputs``; ``deadline=None`` because a
loaded machine must not fail a test for being slow.
"""

from __future__ import annotations

import io
import json
import math
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from skymule.aadm.protocol import (
    parse_reply,
    parse_report,
    parse_telemetry,
    parse_tower_reply,
)
from skymule.errors import SkymuleError
from skymule.io.runs import read_run
from skymule.io.runschema import MBIT_TOLERANCE
from skymule.limits import MAX_EFFICIENCY_BPS_HZ
from skymule.policies import make_policy
from skymule.radio.rates import read_rate_csv
from skymule.scenario import PolicySpec, load_scenario

FUZZ = settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    derandomize=True,
    database=None,
)

numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 5.0, 10.0, 45.0, 50.0, 1e9, -5.0, 1e-12]),
)


def _one_line(exc: SkymuleError) -> None:
    assert str(exc) and "\n" not in str(exc)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-files")


# --- run folders as a whole ----------------------------------------------------------------

HEADER = "t_s,x_m,y_m,z_m,served,snr_db_A,snr_db_B,rate_mbps,downloaded_mbit,hovering,distance_m"


@st.composite
def run_folders(draw: st.DrawFn) -> tuple[list[list[Any]], dict[str, Any], list[str] | None]:
    """Slots, summary and scenario sensors of a run folder: valid files, numbers fuzzed."""
    n = draw(st.integers(1, 5))
    rows = []
    for t in range(n):
        served = draw(st.sampled_from(["A", "B", ""]))
        down = 0.0 if served == "" else draw(numbers.filter(math.isfinite).map(abs))
        rows.append([t, 0, 0, 30, served, 20, 18, 5, down, 0, t])
    down = {name: sum(r[8] for r in rows if r[4] == name) for name in ("A", "B")}
    buffers = {name: draw(st.sampled_from([down[name], down[name] + 40, 50.0])) for name in down}
    summary: dict[str, Any] = {
        "scenario": "s",
        "policy": "greedy",
        "slots": n,
        "total_downloaded_mbit": sum(down.values()),
        "total_buffer_mbit": sum(buffers.values()),
        "per_sensor_downloaded_mbit": down,
        "per_sensor_buffer_mbit": buffers,
    }
    key = draw(st.sampled_from(["none", "total", "total_buffer", "A", "B", "buffer", "slot"]))
    value = draw(numbers)
    if key == "total":
        summary["total_downloaded_mbit"] = value
    elif key == "total_buffer":
        summary["total_buffer_mbit"] = value
    elif key in ("A", "B"):
        summary["per_sensor_downloaded_mbit"] = {**down, key: value}
    elif key == "buffer":
        summary["per_sensor_buffer_mbit"] = {**buffers, "A": value}
    elif key == "slot":
        rows[draw(st.integers(0, n - 1))][8] = value
    sensors = draw(st.sampled_from([None, ["A", "B"], ["A"], ["B", "A"], ["A", "B", "C"]]))
    return rows, summary, sensors


def _scenario_json(names: list[str]) -> dict[str, Any]:
    return {
        "name": "s",
        "sensors": [
            {"name": n, "x_m": 10.0 * i, "y_m": 0.0, "buffer_mbit": 50} for i, n in enumerate(names)
        ],
        "trajectory": {"waypoints": [[0, 0, 30], [10, 0, 30]]},
    }


@FUZZ
@given(run_folders())
def test_a_run_folder_reads_only_when_its_files_agree(
    scratch: Path, folder: tuple[list[list[Any]], dict[str, Any], list[str] | None]
) -> None:
    rows, summary, sensors = folder
    run = scratch / "run"
    run.mkdir(exist_ok=True)
    (run / "slots.csv").write_text(
        "\n".join([HEADER, *(",".join(map(str, r)) for r in rows)]) + "\n"
    )
    (run / "summary.json").write_text(json.dumps(summary))
    (run / "scenario.json").unlink(missing_ok=True)
    if sensors is not None:
        (run / "scenario.json").write_text(json.dumps(_scenario_json(sensors)))
    try:
        read, slots = read_run(run)
    except SkymuleError as exc:
        _one_line(exc)
        event("refused")
        return
    event("read")
    # what reads is one run: totals, per-sensor sums, slot sums and buffers agree
    down = read["per_sensor_downloaded_mbit"]
    slack = 2 * MBIT_TOLERANCE + 1e-8 * max(1.0, abs(read["total_downloaded_mbit"]))
    assert abs(sum(down.values()) - read["total_downloaded_mbit"]) <= slack
    assert abs(slots["downloaded_mbit"].sum() - read["total_downloaded_mbit"]) <= slack
    for name, value in down.items():
        assert value <= read["per_sensor_buffer_mbit"][name] + slack
        assert abs(slots.loc[slots["served"] == name, "downloaded_mbit"].sum() - value) <= slack
    assert sensors is None or sorted(sensors) == sorted(down)


# --- rate tables ---------------------------------------------------------------------------

rate_cells = st.one_of(
    numbers.map(repr),
    st.sampled_from(["nan", "inf", "-inf", "", "x", "1e400", "-0", "3,4"]),
)


@FUZZ
@given(st.lists(st.tuples(rate_cells, rate_cells), max_size=6))
def test_rate_tables_read_finite_and_monotone_or_not_at_all(
    scratch: Path, rows: list[tuple[str, str]]
) -> None:
    path = scratch / "rates.csv"
    path.write_text("snr_db,efficiency\n" + "".join(f"{a},{b}\n" for a, b in rows))
    try:
        table = read_rate_csv(path)
    except SkymuleError as exc:
        _one_line(exc)
        event("refused")
        return
    event("read")
    thresholds = np.asarray(table.thresholds_db)
    efficiencies = np.asarray(table.efficiencies)
    assert np.isfinite(thresholds).all() and (np.diff(thresholds) > 0).all()
    assert np.isfinite(efficiencies).all() and (np.diff(efficiencies) >= 0).all()
    assert ((efficiencies >= 0) & (efficiencies <= MAX_EFFICIENCY_BPS_HZ)).all()
    snr = np.sort(np.r_[thresholds, thresholds - 1e-3, -1e3, 1e3, np.nan])
    rate = table.efficiency(snr)
    assert np.isfinite(rate).all() and (np.diff(rate[~np.isnan(snr)]) >= 0).all()


# --- model files and policy names ----------------------------------------------------------


@FUZZ
@given(
    st.lists(
        st.tuples(st.sampled_from(["data", "policy.pth", "x"]), st.binary(max_size=80)),
        max_size=3,
        unique_by=lambda entry: entry[0],
    ),
    st.booleans(),
)
def test_no_model_file_is_read_without_the_opt_in(
    scratch: Path, monkeypatch: pytest.MonkeyPatch, entries: list[tuple[str, bytes]], zipped: bool
) -> None:
    """Whatever a model file holds (a zip of anything, or any bytes), without --trust-model
    nothing of it is opened: no zip, no unpickling, one line."""
    path = scratch / "model.zip"
    if zipped:
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w") as archive:
            for name, data in entries:
                archive.writestr(name, data)
        path.write_bytes(buffer.getvalue())
    else:
        path.write_bytes(b"".join(data for _, data in entries))
    opened: list[str] = []
    with monkeypatch.context() as patch, pytest.raises(SkymuleError) as caught:
        patch.setattr(zipfile, "ZipFile", lambda *a, **k: opened.append("zip"))
        patch.setitem(sys.modules, "stable_baselines3", None)  # an import would fail loudly
        make_policy(PolicySpec(name=f"rl:{path}"))
    _one_line(caught.value)
    assert "--trust-model" in str(caught.value) and not opened


policy_names = st.one_of(
    st.text(max_size=20),
    st.builds(
        lambda a, b: f"{a}:{b}",
        st.from_regex(r"[a-z_][a-z0-9_.]{0,12}", fullmatch=True),
        st.from_regex(r"[A-Za-z_]\w{0,8}", fullmatch=True),
    ),
    st.sampled_from(["this:s", "antigravity:fly", "os:system", "rl:", "rl:x.zip", "greedy"]),
)


@FUZZ
@given(policy_names)
def test_checking_a_policy_name_imports_nothing(name: str) -> None:
    load_scenario("paper-sim-fixed")  # what loading a preset imports anyway
    before = set(sys.modules)
    try:
        load_scenario("paper-sim-fixed", [f"policy.name={json.dumps(name)}"])
    except SkymuleError as exc:
        _one_line(exc)
    assert set(sys.modules) == before


# --- AADM protocol -------------------------------------------------------------------------

protocol_parts = st.sampled_from(
    ["snr:1:20.5,2:-99", "download:1:5.00", "vol:{'1': 500.0}", "1:x", "2:nan", "alt:30",
     "arm:1", "arm:2", "lat:inf", "00", "12.5", "rate>3.2 mbps", "bs>1", ""]
)  # fmt: skip
protocol_lines = st.one_of(
    st.text(max_size=40),
    st.lists(protocol_parts, max_size=4).map(",".join),
    st.lists(protocol_parts, max_size=4).map(";".join),
)


@FUZZ
@given(protocol_lines)
def test_protocol_lines_parse_or_are_one_line(line: str) -> None:
    for parse in (parse_reply, parse_report, parse_telemetry, parse_tower_reply):
        try:
            parse(line)
        except SkymuleError as exc:
            _one_line(exc)


# --- radio-map JSON (issue 32) --------------------------------------------------------------

map_numbers = st.one_of(
    numbers,
    st.sampled_from([1e308, -1e308, 2.5, 60.0, 1e-300, 1e12, 1e13]),
    st.integers(-(2**70), 2**70),
)


@st.composite
def radio_map_documents(draw: st.DrawFn) -> dict[str, Any]:
    """A one-sensor map document whose numbers and shapes are fuzzed, one field at a time
    or several (most draws keep most fields valid, to reach the value checks)."""
    n = draw(st.integers(0, 4))
    sensor: dict[str, Any] = {
        "name": "LW1",
        "position_m": [10.0, -20.0, 10.0],
        "intercept_db": 60.0,
        "exponent": 2.5,
        "sill_db2": 16.0,
        "range_m": 50.0,
        "nugget_db2": 0.5,
        "train_m": [[5.0 * i, 3.0 * i, 30.0] for i in range(n)],
        "weights": [0.1 * (i + 1) for i in range(n)],
    }
    for key in draw(st.lists(st.sampled_from(sorted(sensor)), max_size=3, unique=True)):
        if key in ("train_m", "weights", "position_m"):
            size = draw(st.integers(0, 5))
            shape = [[draw(map_numbers) for _ in range(3)]] * size if key == "train_m" else None
            sensor[key] = shape if shape is not None else [draw(map_numbers) for _ in range(size)]
        else:
            sensor[key] = draw(map_numbers)
    origin = {"lat": draw(st.sampled_from([35.7, 91.0, math.nan])), "lon": -78.7}
    return {"format": "skymule-radiomap", "version": 2, "method": "kriging",
            "origin": origin, "prior": None, "sensors": [sensor]}  # fmt: skip


@FUZZ
@given(radio_map_documents())
def test_a_radio_map_reads_to_finite_predictions_or_one_line(
    scratch: Path, document: dict[str, Any]
) -> None:
    from skymule.radio.radiomap import MAP_FORMAT, read_radiomap

    document["format"] = MAP_FORMAT
    path = scratch / "map.json"
    path.write_text(json.dumps(document))  # NaN/Infinity tokens, as Python writes them
    try:
        radio_map = read_radiomap(path)
    except SkymuleError as exc:
        _one_line(exc)
        event("refused")
        return
    event("read")
    grid = np.array([[x, y, 30.0] for x in (-500.0, 0.0, 7.0, 900.0) for y in (-300.0, 0.0)])
    assert np.isfinite(radio_map.source(["LW1"]).snr_db(grid)).all()


# --- learned weights (.npz) (issue 32) ------------------------------------------------------


@st.composite
def weight_files(draw: st.DrawFn) -> dict[str, np.ndarray]:
    """The model's arrays with names dropped or added, dtypes and shapes changed, values
    fuzzed (one or a few changes a draw)."""
    from skymule.policies.learned import FEATURE_NAMES, FORMAT, initial_net

    net = initial_net(np.random.default_rng(0))
    arrays: dict[str, np.ndarray] = {name: value[0] for name, value in vars(net).items()}
    arrays.update(format=np.array(FORMAT), features=np.array(FEATURE_NAMES))
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from([*sorted(arrays), "extra"]))
        change = draw(st.sampled_from(["drop", "dtype", "shape", "value", "add"]))
        value = arrays.get(name, np.zeros(2))
        if change == "drop":
            arrays.pop(name, None)
        elif change == "dtype":
            kind = draw(st.sampled_from(["i8", "f4", "U3", "b1", "c16"]))
            arrays[name] = np.zeros(value.shape, dtype=kind)
        elif change == "shape":
            arrays[name] = np.zeros(draw(st.lists(st.integers(0, 4), max_size=3)))
        elif change == "value" and value.dtype.kind == "f" and value.size:
            arrays[name] = value.copy()
            arrays[name].flat[0] = draw(numbers)
        else:
            arrays[name] = value
    return arrays


@FUZZ
@given(weight_files())
def test_weights_load_checked_or_are_one_line(scratch: Path, arrays: dict[str, np.ndarray]) -> None:
    from skymule.policies.learned import WEIGHT_NAMES, expected_shapes, load_net

    path = scratch / "weights.npz"
    named: dict[str, Any] = dict(arrays)
    with path.open("wb") as handle:
        np.savez(handle, **named)
    try:
        net = load_net(path)
    except SkymuleError as exc:
        _one_line(exc)
        assert "weights.npz" in str(exc)
        event("refused")
        return
    event("read")
    shapes = expected_shapes(net.encoder_b.shape[1], net.hidden_b.shape[1])
    for name in WEIGHT_NAMES:
        value = getattr(net, name)
        assert value.dtype == np.float64 and np.isfinite(value).all()
        assert value.shape == (1, *shapes[name])
        assert arrays[name].dtype.kind == "f"  # integers, booleans, text: refused


# --- recorded flights: time and SNR ranges (issue 32) ---------------------------------------

time_cells = st.one_of(
    numbers.map(repr),
    st.sampled_from(["1e300", "1e8", "9999999", "-1", "0", "nan", "", "2025-05-24 16:19:00"]),
)
snr_cells = st.one_of(
    numbers.map(repr),
    st.sampled_from(["1e308", "-1e308", "300", "300.5", "-300", "-99", "-100", "", "nan"]),
)


def _trace_text(times: list[str], snr: list[str], aadm: bool) -> str:
    if aadm:
        rows = [f"{t},{s},35.7275,-78.6963,30" for t, s in zip(times, snr, strict=True)]
        return "time,snr_lw1,Latitude,Longitude,Altitude\n" + "\n".join(rows) + "\n"
    rows = [f"{t},{s},{i},0,30" for i, (t, s) in enumerate(zip(times, snr, strict=True))]
    return "Time,LW1,X,Y,Height\n" + "\n".join(rows) + "\n"


@FUZZ
@given(st.lists(st.tuples(time_cells, snr_cells), min_size=1, max_size=5), st.booleans())
def test_recorded_flights_read_within_limits_or_are_one_line(
    scratch: Path, cells: list[tuple[str, str]], aadm: bool
) -> None:
    """Times and SNR samples fuzzed: what reads has strictly increasing times within the
    longest mission and SNR within +-300 dB (or missing); the rest is one line."""
    from skymule.io.traces import read_trace
    from skymule.limits import MAX_DURATION_S, MAX_SNR_DB

    times, snr = [c[0] for c in cells], [c[1] for c in cells]
    path = scratch / "flight.csv"
    path.write_text(_trace_text(times, snr, aadm))
    try:
        trace = read_trace(path)
    except SkymuleError as exc:
        _one_line(exc)
        event("refused")
        return
    event("read")
    assert trace.time_s[0] == 0 and (np.diff(trace.time_s) > 0).all()
    assert trace.time_s[-1] <= MAX_DURATION_S
    values = trace.snr_db[np.isfinite(trace.snr_db)]
    assert (np.abs(values) <= MAX_SNR_DB).all() and not np.isinf(trace.snr_db).any()


@FUZZ
@given(st.lists(st.tuples(st.integers(0, 23), snr_cells), max_size=3))
def test_trace_snr_reaches_a_fit_finite_or_is_one_line(
    scratch: Path, changes: list[tuple[int, str]]
) -> None:
    """A few SNR samples of a digital-twin export fuzzed: fitting a map to it gives finite
    predictions or one line (nnls took inf variances from a 1e308 dB sample)."""
    from skymule.geo import LocalFrame
    from skymule.radio.radiomap import fit_radiomap

    snr = [f"{60 - 20 * math.log10(5 + 6 * i) + (i % 3):.2f}" for i in range(24)]
    for index, cell in changes:
        snr[index] = cell
    path = scratch / "dt.csv"
    rows = [f"{i},{s},{5 * i},{3 * i},30" for i, s in enumerate(snr)]
    path.write_text("Time,LW1,X,Y,Height\n" + "\n".join(rows) + "\n")
    try:
        tower = np.array([[0.0, 0.0, 10.0]])
        fitted = fit_radiomap([path], ["LW1"], tower, LocalFrame(35.7, -78.7))
    except SkymuleError as exc:
        _one_line(exc)
        event(f"refused: {str(exc).split(': ')[-1][:40]}")
        return
    event("fitted")
    assert np.isfinite(fitted.sensors[0].snr_db(np.array([[20.0, 10.0, 30.0]]))).all()
