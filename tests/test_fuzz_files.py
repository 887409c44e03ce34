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
