"""Property-based fuzzing of every file reader at the edge (issue 15, "reliability of the tool").

Whatever a user hands in (random TOML-ish tables, raw bytes, random CSV text, damaged run
files), each reader returns a result or raises one clear :class:`SkymuleError` (one line):
never another exception, which the CLI would show as a traceback. Inputs start from valid
files and mutate them, so the fuzzing reaches deep into the validation, not only the parser.
Example counts are modest to keep the suite quick; ``deadline=None`` because a loaded CI
machine must not fail a test for being slow.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.experiments.sweep import iter_missions, load_sweep, parse_sweep, validate_mission
from skymule.faults import draw_faults, fault_rng
from skymule.io.runs import read_run
from skymule.io.traces import read_trace, read_volumes
from skymule.scenario import Scenario, load_scenario, scenario_from_dict

DEEP = int(os.environ.get("SKYMULE_FUZZ_EXAMPLES", "0"))
"""Set SKYMULE_FUZZ_EXAMPLES=5000 to fuzz deeper (random examples instead of the fixed set)."""

FUZZ = settings(
    max_examples=DEEP or 60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    derandomize=not DEEP,  # the same examples on every run: a red build is reproducible
    database=None,
)

# --- values a TOML file can hold --------------------------------------------------------------

scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, 1, -1, 1e305, -1e305, 1e-300, 0.5, 200, 1e12, 1e13]),
    st.text(max_size=12),
    st.sampled_from(["200", "true", "fspl", "greedy", "hgad", "trace", "model", "autonomous"]),
)
toml_values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=10,
)

BASE_SCENARIO: dict[str, Any] = {
    "name": "fuzz",
    "seed": 3,
    "mission": {"duration_s": 60, "slot_s": 1.0},
    "sensors": [
        {"name": "A", "x_m": 10.0, "y_m": 0.0, "buffer_mbit": 50},
        {"name": "B", "lat": 35.7285, "lon": -78.6955, "buffer_mbit": 80},
    ],
    "radio": {"model": "fspl"},
    "trajectory": {"mode": "fixed", "waypoints": [[0, 0, 30], [100, 0, 30]]},
    "policy": {"name": "hgad"},
    "faults": [
        {"kind": "outage", "params": {"sensors": ["A"], "start_s": 5, "duration_s": 10}},
        {"kind": "gilbert-elliott", "params": {"p_good_to_bad": 0.1, "p_bad_to_good": 0.3}},
    ],
}

FIELD_PATHS: list[tuple[str | int, ...]] = [
    ("name",),
    ("seed",),
    ("mission",),
    ("mission", "duration_s"),
    ("mission", "slot_s"),
    ("sensors",),
    ("sensors", 0, "buffer_mbit"),
    ("sensors", 0, "x_m"),
    ("sensors", 1, "lat"),
    ("sensors", 1, "name"),
    ("radio", "model"),
    ("radio", "shadowing_std_db"),
    ("radio", "fading"),
    ("signal", "source"),
    ("trajectory", "waypoints"),
    ("trajectory", "mode"),
    ("trajectory", "home"),
    ("policy", "hover_threshold"),
    ("faults",),
    ("faults", 0, "kind"),
    ("faults", 0, "params"),
    ("faults", 1, "params", "p_good_to_bad"),
    ("faults", 0, "params", "sensors"),
    ("unknown_field",),
]


def _with(data: Any, path: tuple[str | int, ...], value: Any) -> Any:
    """A copy of ``data`` with ``path`` set to ``value`` (creating tables on the way)."""
    if not path:
        return value
    head, rest = path[0], path[1:]
    if isinstance(data, list) and isinstance(head, int) and head < len(data):
        copy = list(data)
        copy[head] = _with(copy[head], rest, value)
        return copy
    copy_dict = dict(data) if isinstance(data, dict) else {}
    copy_dict[str(head)] = _with(copy_dict.get(str(head), {}), rest, value)
    return copy_dict


def _one_line_error(exc: SkymuleError) -> None:
    message = str(exc)
    assert message and "\n" not in message, message
    event("refused")  # `pytest --hypothesis-show-statistics`: how many examples were valid


mutations = st.lists(st.tuples(st.sampled_from(FIELD_PATHS), toml_values), max_size=3)


@FUZZ
@given(mutations)
def test_scenario_loader_on_mutated_tables(changes: list[tuple[Any, Any]]) -> None:
    data: Any = BASE_SCENARIO
    for path, value in changes:
        data = _with(data, path, value)
    try:
        scenario = scenario_from_dict(data, "fuzz.toml", Path("."))
    except SkymuleError as exc:
        _one_line_error(exc)
        return
    assert isinstance(scenario, Scenario)
    for sensor in scenario.sensors:  # what passed validation is a sane number
        assert math.isfinite(sensor.buffer_mbit) and 0 <= sensor.buffer_mbit <= 1e12
    names = [s.name for s in scenario.sensors]
    draws = draw_faults(scenario.faults or [], 30, names, scenario.mission.slot_s, fault_rng(0))
    assert draws.link_up.shape == (30, len(names))


@FUZZ
@given(st.dictionaries(st.text(max_size=10), toml_values, max_size=6))
def test_scenario_loader_on_random_tables(data: dict[str, Any]) -> None:
    try:
        scenario_from_dict(data, "fuzz.toml", Path("."))
    except SkymuleError as exc:
        _one_line_error(exc)


VALID_TOML = (
    b'name = "x"\nseed = 1\n[mission]\nduration_s = 100\n[[sensors]]\nname = "A"\n'
    b"x_m = 0\ny_m = 0\nbuffer_mbit = 10\n"
)


def _mutated_bytes(data: st.DataObject, valid: bytes) -> bytes:
    choice = data.draw(st.integers(0, 2))
    if choice == 0:
        return data.draw(st.binary(max_size=200))
    if choice == 1:  # valid text with random bytes spliced in
        cut = data.draw(st.integers(0, len(valid)))
        return valid[:cut] + data.draw(st.binary(max_size=8)) + valid[cut:]
    cut = data.draw(st.integers(0, len(valid)))
    return valid[:cut]  # truncated


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


@FUZZ
@given(st.data())
def test_scenario_loader_on_raw_bytes(scratch: Path, data: st.DataObject) -> None:
    path = scratch / "scenario.toml"
    path.write_bytes(_mutated_bytes(data, VALID_TOML))
    try:
        load_scenario(path)
    except SkymuleError as exc:
        _one_line_error(exc)


# --- traces ----------------------------------------------------------------------------------

AADM_HEADER = ["time", "snr_lw1", "snr_lw2", "Longitude", "Latitude", "Altitude"]
DT_HEADER = ["Time", "LW1", "LW2", "LW3", "LW4", "X", "Y", "Height"]
cells = st.one_of(
    st.sampled_from(
        [
            "",
            "-99",
            "nan",
            "inf",
            "-inf",
            "1e309",
            "abc",
            "12.5",
            "2025-05-24 16:19:31.186",
            "2025-05-24 16:19:32.186+02:00",
            "2025-05-24T16:19:33Z",
            "NaT",
            "-78.69",
            "35.72",
            "30",
            "0",
            '"quoted, cell"',
        ]
    ),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**20), 10**20).map(str),
    st.text(alphabet=st.characters(blacklist_categories=["Cs"]), max_size=6),
)


@st.composite
def csv_texts(draw: st.DrawFn) -> str:
    header = draw(st.sampled_from([AADM_HEADER, DT_HEADER, ["a", "b"]]))
    if draw(st.booleans()):
        header = draw(st.permutations(header))
    rows = draw(
        st.lists(
            st.lists(cells, min_size=len(header) - 1, max_size=len(header) + 1),
            max_size=8,
        )
    )
    separator = draw(st.sampled_from([",", ",", ";", "\t"]))
    lines = [separator.join(header), *(separator.join(row) for row in rows)]
    return draw(st.sampled_from(["\n", "\r\n"])).join(lines)


def _sequential_aadm(data: st.DataObject) -> str:
    """A valid AADM log with one random cell replaced: deep checks, not only the header."""
    rows = [",".join(AADM_HEADER)]
    for i in range(6):
        rows.append(f"2025-05-24 16:19:{31 + i:02d}.186,{10 + i},{20 - i},-78.69,35.72,30")
    r = data.draw(st.integers(1, len(rows) - 1))
    c = data.draw(st.integers(0, len(AADM_HEADER) - 1))
    row = rows[r].split(",")
    row[c] = data.draw(cells)
    rows[r] = ",".join(row)
    return "\n".join(rows) + "\n"


@FUZZ
@given(st.data())
def test_trace_reader_on_random_csv(scratch: Path, data: st.DataObject) -> None:
    path = scratch / "trace.csv"
    kind = data.draw(st.integers(0, 2))
    if kind == 0:
        path.write_text(data.draw(csv_texts()), encoding="utf-8")
    elif kind == 1:
        path.write_text(_sequential_aadm(data), encoding="utf-8")
    else:
        path.write_bytes(data.draw(st.binary(max_size=120)))
    try:
        trace = read_trace(path)
    except SkymuleError as exc:
        _one_line_error(exc)
        return
    assert np.all(np.diff(trace.time_s) > 0) and trace.time_s[0] == 0.0


@FUZZ
@given(st.lists(cells, max_size=6))
def test_volume_reader_on_random_lines(scratch: Path, lines: list[str]) -> None:
    path = scratch / "volumes.txt"
    path.write_text("\n".join(lines), encoding="utf-8")
    try:
        volumes = read_volumes(path)
    except SkymuleError as exc:
        _one_line_error(exc)
        return
    assert np.all(np.isfinite(volumes))


# --- sweeps ----------------------------------------------------------------------------------

small_ints = st.integers(-5, 40)
axis_specs = st.one_of(
    st.lists(st.one_of(small_ints, st.floats(-1e3, 1e3), st.text(max_size=5)), max_size=3),
    st.builds(lambda b: {"range": b}, st.lists(small_ints, min_size=0, max_size=4)),
    st.builds(
        lambda name, params: {"dist": name, **params},
        st.sampled_from(["uniform", "normal", "lognormal", "integers", "choice", "beta"]),
        st.dictionaries(
            st.sampled_from(["low", "high", "mean", "std", "sigma", "values", "x"]),
            st.one_of(small_ints, st.floats(allow_nan=True), st.booleans(), st.text(max_size=3)),
            max_size=3,
        ),
    ),
    toml_values,
)
axis_keys = st.sampled_from(
    [
        "seed",
        "policy.name",
        "sensors[*].buffer_mbit",
        "sensors[0].x_m",
        "sensors[9].x_m",
        "mission.duration_s",
        "radio.shadowing_std_db",
        "bad key",
        "sensors[*]",
        "nope.field",
    ]
)


@st.composite
def sweep_tables(draw: st.DrawFn) -> dict[str, Any]:
    table: dict[str, Any] = {
        "base": draw(st.sampled_from(["paper-sim-fixed", "missing-preset", "", "."])),
        "seed": draw(st.one_of(small_ints, st.booleans(), st.floats(allow_nan=True))),
        "mode": draw(
            st.one_of(
                st.just("product"),
                st.builds(lambda n: {"sample": n}, st.one_of(small_ints, st.text(max_size=3))),
                toml_values,
            )
        ),
        "axes": draw(st.dictionaries(axis_keys, axis_specs, max_size=3)),
    }
    drop = draw(st.lists(st.sampled_from(list(table)), max_size=2))
    extra = draw(st.dictionaries(st.sampled_from(["extra", "base"]), toml_values, max_size=1))
    return {**{k: v for k, v in table.items() if k not in drop}, **extra}


@FUZZ
@given(sweep_tables())
def test_sweep_parser_on_random_tables(scratch: Path, table: dict[str, Any]) -> None:
    try:
        spec = parse_sweep(table, "fuzz-sweep.toml", scratch)
        assert len(spec) >= 1
        for mission in itertools.islice(iter_missions(spec), 3):
            assert isinstance(validate_mission(spec, mission), Scenario)
    except SkymuleError as exc:
        _one_line_error(exc)


VALID_SWEEP = b'base = "paper-sim-fixed"\nseed = 1\n[axes]\nseed = [1, 2]\n'


@FUZZ
@given(st.data())
def test_sweep_loader_on_raw_bytes(scratch: Path, data: st.DataObject) -> None:
    path = scratch / "sweep.toml"
    path.write_bytes(_mutated_bytes(data, VALID_SWEEP))
    try:
        load_sweep(path)
    except SkymuleError as exc:
        _one_line_error(exc)


# --- run folders -----------------------------------------------------------------------------

SLOTS_HEADER = (
    "t_s,x_m,y_m,z_m,lat,lon,served,snr_db_A,remaining_mbit_A,rate_mbps,downloaded_mbit,"
    "hovering,distance_m"
)
SLOT_ROWS = [
    "0,0,0,30,35.7,-78.6,A,20,45,5,5,0,0",
    "1,1,0,30,35.7,-78.6,A,21,40,5,5,1,1",
    "2,2,0,30,35.7,-78.6,,-inf,40,0,0,0,2",
]
SUMMARY = {
    "scenario": "s",
    "policy": "greedy",
    "slots": 3,
    "slot_s": 1.0,
    "total_downloaded_mbit": 10.0,
    "per_sensor_downloaded_mbit": {"A": 10.0},
    "per_sensor_buffer_mbit": {"A": 50.0},
}
SUMMARY_KEYS = [*SUMMARY, "completion", "handovers", "visit_order", "landed_at_home"]


@FUZZ
@given(st.data())
def test_run_folder_reader_on_damaged_files(scratch: Path, data: st.DataObject) -> None:
    run = scratch / "run"
    run.mkdir(exist_ok=True)
    (run / "scenario.json").unlink(missing_ok=True)
    rows = list(SLOT_ROWS)
    summary: Any = dict(SUMMARY)
    target = data.draw(st.sampled_from(["cell", "rows", "summary", "summary-bytes", "scenario"]))
    if target == "cell":
        r = data.draw(st.integers(0, len(rows) - 1))
        row = rows[r].split(",")
        row[data.draw(st.integers(0, len(row) - 1))] = data.draw(cells)
        rows[r] = ",".join(row)
    elif target == "rows":
        rows = rows[: data.draw(st.integers(0, len(rows)))]
    elif target == "summary":
        summary = _with(
            summary, (data.draw(st.sampled_from(SUMMARY_KEYS)),), data.draw(toml_values)
        )
    elif target == "scenario":
        scenario = _with(
            BASE_SCENARIO, data.draw(st.sampled_from(FIELD_PATHS)), data.draw(toml_values)
        )
        (run / "scenario.json").write_text(json.dumps(scenario))
    (run / "slots.csv").write_text("\n".join([SLOTS_HEADER, *rows]) + "\n")
    if target == "summary-bytes":
        (run / "summary.json").write_bytes(data.draw(st.binary(max_size=60)))
    else:
        (run / "summary.json").write_text(json.dumps(summary))
    try:
        summary_read, slots = read_run(run)
    except SkymuleError as exc:
        _one_line_error(exc)
        return
    assert len(slots) == summary_read["slots"]  # never part of the mission


def test_the_fuzzed_bases_are_valid() -> None:
    """The mutations start from valid inputs (else the fuzzing only exercises the first check)."""
    assert scenario_from_dict(BASE_SCENARIO, "fuzz.toml", Path(".")).faults is not None
    assert tomllib.loads(VALID_TOML.decode())["name"] == "x"
    assert len(parse_sweep(tomllib.loads(VALID_SWEEP.decode()), "s", Path("."))) == 2


# --- the whole command: any scenario file ends in results or one line, exit 2 ---------------

coordinates = st.one_of(
    st.sampled_from([0.0, 1e-9, 0.5, 10.0, 150.0, -300.0, 2000.0, 1e5]),
    st.floats(-1500, 1500),
)


@st.composite
def mission_tables(draw: st.DrawFn) -> dict[str, Any]:
    """Scenarios that pass most checks, so the mission is built and flown."""
    sensors = [
        {
            "name": f"S{i}",
            "x_m": draw(coordinates),
            "y_m": draw(coordinates),
            "height_m": draw(st.sampled_from([0.0, 10.0, 60.0])),
            "buffer_mbit": draw(st.sampled_from([0.0, 1e-6, 5.0, 300.0, 1e12])),
        }
        for i in range(draw(st.integers(1, 4)))
    ]
    mode = draw(st.sampled_from(["fixed", "autonomous"]))
    trajectory: dict[str, Any] = {"mode": mode}
    if mode == "fixed":
        trajectory["waypoints"] = [
            [draw(coordinates), draw(coordinates), draw(st.sampled_from([5.0, 30.0, 120.0]))]
            for _ in range(draw(st.integers(1, 3)))
        ]
        trajectory["speed_mps"] = draw(st.sampled_from([1.0, 10.0, 40.0]))
    else:
        trajectory["max_speed_mps"] = draw(st.sampled_from([1.0, 10.0, 40.0]))
        trajectory["home"] = [draw(coordinates), draw(coordinates)]
    policies = ["greedy", "hgad", "optimal-fixed", "planner"]
    return {
        "name": "fuzz",
        "seed": draw(st.integers(0, 3)),
        "mission": {
            "duration_s": draw(st.sampled_from([1, 3, 40, 600])),
            "slot_s": draw(st.sampled_from([0.5, 1.0, 3.0])),
        },
        "sensors": sensors,
        "radio": {
            "model": draw(st.sampled_from(["fspl", "two-ray", "al-hourani", "3gpp-rma-av"])),
            "shadowing_std_db": draw(st.sampled_from([0.0, 6.0])),
            "fading": draw(st.sampled_from(["none", "rayleigh"])),
            "rate_table": draw(st.sampled_from(["aadm-lte-cqi", "shannon"])),
        },
        "trajectory": trajectory,
        "policy": {
            "name": draw(st.sampled_from(policies)),
            "hover_threshold": draw(st.sampled_from([0.05, 1.0])),
        },
    }


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    return repr(float(value)) if isinstance(value, float) else str(value)


@settings(FUZZ, max_examples=DEEP or 12)
@given(mission_tables())
def test_run_command_on_random_missions(scratch: Path, table: dict[str, Any]) -> None:
    path = scratch / "mission.toml"
    path.write_text("\n".join(f"{key} = {_toml(value)}" for key, value in table.items()))
    done = run_cli("run", str(path), "--out", str(scratch / "out"))
    if done.returncode == 2:
        assert done.stderr.count("\n") == 1, done.stderr
        event("refused")
        return
    assert done.returncode == 0, done.stderr
    summary, slots = read_run(scratch / "out")  # what the run wrote reads back valid
    assert len(slots) == summary["slots"]
    total_buffer = sum(summary["per_sensor_buffer_mbit"].values())
    assert summary["total_downloaded_mbit"] <= total_buffer * (1 + 1e-9)
