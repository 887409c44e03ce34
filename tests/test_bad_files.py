"""Files that gave a traceback or a silent wrong answer (issue 32): each is now one line naming
the file and the value, with exit status 2, and nothing is allocated or read first."""

from __future__ import annotations

import json
import math
import shutil
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.experiments.store import claim
from skymule.geo import LocalFrame, load_geofence
from skymule.io.qgc_plan import read_qgc_plan
from skymule.io.runs import read_run
from skymule.io.traces import TraceError, read_trace, write_dt_export
from skymule.radio.radiomap import read_radiomap
from skymule.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "examples" / "samples"
DEEP = "[" * 50_000 + "]" * 50_000  # 0.1 MB of nesting: a RecursionError in json.loads


def _one_line(done: Any, *needles: str) -> None:
    """Exit status 2 and one stderr line holding every needle."""
    assert done.returncode == 2, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
    for needle in needles:
        assert needle in done.stderr, done.stderr


# --- deeply nested JSON (and TOML) in every reader -------------------------------------------


def _deep(tmp_path: Path, name: str, text: str = DEEP) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("limit", [1000, 20_000])
def test_deep_json_is_one_line_in_every_reader(tmp_path: Path, limit: int) -> None:
    """Refused from a bracket count before parsing, whatever the recursion limit (with a
    raised one, json's C parser would recurse 50,000 C frames deep)."""
    readers = [
        (read_radiomap, "map.json"),
        (lambda p: load_geofence(str(p), LocalFrame(35.7, -78.7)), "fence.geojson"),
        (read_qgc_plan, "mission.plan"),
    ]
    saved = sys.getrecursionlimit()
    sys.setrecursionlimit(limit)
    try:
        for read, name in readers:
            with pytest.raises(SkymuleError) as caught:
                read(_deep(tmp_path, name))
            message = str(caught.value)
            assert name in message and "nested more than 100 levels" in message
            assert "\n" not in message
    finally:
        sys.setrecursionlimit(saved)


def test_deep_json_in_a_run_folder_is_one_line(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run_cli("run", "paper-sim-fixed", "--set", "mission.duration_s=20", "--out", run, check=True)
    (run / "summary.json").write_text(DEEP)
    with pytest.raises(SkymuleError, match="nested more than 100 levels"):
        read_run(run)
    # report reads it twice: fleet_inputs' summary probe, then read_run
    _one_line(run_cli("report", run, "--no-pdf"), "summary.json", "nested more than 100 levels")


def test_deep_sweep_json_is_one_line(tmp_path: Path) -> None:
    _deep(tmp_path, "sweep.json")
    with pytest.raises(SkymuleError, match=r"sweep\.json is damaged"):
        claim(tmp_path, "0" * 64, "sweep.toml")


def test_deep_toml_is_one_line(tmp_path: Path) -> None:
    """Refused whatever the recursion limit (mypy, run in-process by another test, raises it
    to 16384: tomllib then parses 5000 levels, and the depth check refuses them)."""
    scenario = _deep(tmp_path, "deep.toml", "a = " + "[" * 5000 + "]" * 5000 + "\n")
    _one_line(run_cli("run", scenario), "deep.toml", "nested more than 100 levels")
    sweep = _deep(tmp_path, "sweep.toml", "a = " + "[" * 5000 + "]" * 5000 + "\n")
    _one_line(
        run_cli("sweep", sweep, "--out", tmp_path / "o"),
        "sweep.toml",
        "nested more than 100 levels",
    )


# --- radio maps: shapes and values -----------------------------------------------------------


@pytest.fixture(scope="module")
def fitted_map(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A kriging map of the sample digital-twin flight, as its JSON document."""
    out = tmp_path_factory.mktemp("map") / "map.json"
    run_cli("fit-radiomap", SAMPLES / "dt_flight.csv", "--out", out, check=True)
    document: dict[str, Any] = json.loads(out.read_text())
    return document


def _map_file(tmp_path: Path, document: dict[str, Any], **changes: Any) -> Path:
    changed = json.loads(json.dumps(document))
    changed["sensors"][0].update(changes)
    path = tmp_path / "bad-map.json"
    path.write_text(json.dumps(changed))  # NaN and inf written as NaN and Infinity
    return path


@pytest.mark.parametrize(
    ("changes", "needle"),
    [
        ({"exponent": math.nan}, "sensors[0] (LW1).exponent = nan"),
        ({"position_m": [math.inf, 0.0, 10.0]}, "sensors[0] (LW1).position_m = inf"),
        ({"intercept_db": 1e308}, "sensors[0] (LW1).intercept_db = 1e+308"),
        ({"sill_db2": -1.0}, "sill_db2 = -1.0"),
        ({"range_m": 0.0}, "range_m = 0.0"),
        ({"weights": [1.0]}, "weights has 1 values for"),
    ],
)
def test_radio_map_values_are_checked_on_read(
    tmp_path: Path, fitted_map: dict[str, Any], changes: dict[str, Any], needle: str
) -> None:
    path = _map_file(tmp_path, fitted_map, **changes)
    with pytest.raises(SkymuleError) as caught:
        read_radiomap(path)
    assert needle in str(caught.value) and "bad-map.json" in str(caught.value)
    # the commands that used such a map: score-radiomap (was a ValueError for short
    # weights) and run (downloaded 0 Mbit from that tower, exit 0)
    _one_line(run_cli("score-radiomap", path, SAMPLES / "dt_flight.csv"), needle)


def test_a_bad_map_is_refused_by_run_and_sim2real(
    tmp_path: Path, fitted_map: dict[str, Any]
) -> None:
    path = _map_file(tmp_path, fitted_map, exponent=math.nan)
    source = ["--set", 'signal.source="radiomap"', "--set", f"signal.map={json.dumps(str(path))}"]
    _one_line(run_cli("run", "paper-sim-fixed", *source), "exponent = nan")
    real = SAMPLES / "flight_merged.csv"
    _one_line(run_cli("sim2real", "paper-sim-fixed", real, "--twin", path), "exponent = nan")


def test_the_fitted_map_itself_reads(fitted_map: dict[str, Any], tmp_path: Path) -> None:
    path = tmp_path / "ok.json"
    path.write_text(json.dumps(fitted_map))
    assert read_radiomap(path).names  # the bounds refuse nothing a fit writes


def test_score_radiomap_json_is_strict_json(tmp_path: Path) -> None:
    """A sensor without one scored sample has no RMSE: null, never the bare NaN that is not
    JSON (was printed by score-radiomap --json)."""
    flight = tmp_path / "flight.csv"
    lines = (SAMPLES / "dt_flight.csv").read_text().splitlines()
    header = lines[0].split(",")
    column = next(i for i, h in enumerate(header) if h.upper() == "LW2")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[column] = "-99"  # the digital twin's missing-sample marker
    flight.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    done = run_cli("score-radiomap", "paper-sim-fixed", flight, "--json", check=True)

    def refuse(token: str) -> None:
        raise AssertionError(f"not JSON: {token}")

    scores = json.loads(done.stdout, parse_constant=refuse)
    assert scores["rmse_db"]["LW2"] is None and scores["rmse_db"]["LW1"] is not None


# --- traces: SNR and time ranges -------------------------------------------------------------


def _dt_trace(tmp_path: Path, snr: list[float], times: list[float] | None = None) -> Path:
    n = len(snr)
    path = tmp_path / "trace.csv"
    t = np.arange(n, dtype=float) if times is None else np.asarray(times)
    xs = np.linspace(0.0, 50.0, n)
    names = ["LW1", "LW2", "LW3", "LW4"]
    write_dt_export(path, t, np.column_stack([snr] * 4), names, xs, xs, np.full(n, 30.0))
    return path


def test_a_trace_snr_of_1e308_db_is_refused_at_load(tmp_path: Path) -> None:
    snr = [20.0] * 30
    snr[7] = 1e308
    path = _dt_trace(tmp_path, snr)
    with pytest.raises(TraceError, match=r"row 9, column 'LW1': '1e\+308' dB is out of range"):
        read_trace(path)
    # fit-radiomap gave an nnls ValueError; sim2real a null RMSE with exit status 0
    _one_line(run_cli("fit-radiomap", path, "--out", tmp_path / "m.json"), "1e+308")
    _one_line(run_cli("score-radiomap", "paper-sim-fixed", path), "1e+308")
    done = run_cli("sim2real", "paper-sim-fixed", path, "--twin", "paper-sim-fixed")
    _one_line(done, "1e+308")


def test_trace_snr_limits_keep_real_values(tmp_path: Path) -> None:
    path = _dt_trace(tmp_path, [-98.0, -50.0, 0.0, 85.0, 299.0])
    assert read_trace(path).snr_db[:, 0].tolist() == [-98.0, -50.0, 0.0, 85.0, 299.0]
    merged = tmp_path / "merged.csv"
    text = (SAMPLES / "flight_merged.csv").read_text().splitlines()
    cells = text[5].split(",")
    snr_col = text[0].lower().split(",").index("snr_lw1")
    cells[snr_col] = "-400"
    merged.write_text("\n".join([*text[:5], ",".join(cells), *text[6:]]) + "\n")
    with pytest.raises(TraceError, match="'-400' dB is out of range"):
        read_trace(merged)


def test_a_trace_time_of_1e300_is_refused_at_load(tmp_path: Path) -> None:
    path = _dt_trace(tmp_path, [20.0, 21.0, 22.0], times=[0.0, 1.0, 1e8])
    with pytest.raises(TraceError, match=r"'100000000.0' is 1e\+08 s after the first row"):
        read_trace(path)  # a 1e8-s flight: refused as read, before any slot exists
    path = _dt_trace(tmp_path, [20.0, 21.0, 22.0], times=[0.0, 1.0, 1e300])
    with pytest.raises(TraceError, match=r"row 4, column 'Time': '1e\+300' is 1e\+300 s"):
        read_trace(path)
    scenario = tmp_path / "replay.toml"
    scenario.write_text(
        'name = "replay"\n[[sensors]]\nname = "LW1"\nbuffer_mbit = 10\n'
        f'[signal]\nsource = "trace"\ntrace = "{path}"\n'
    )
    _one_line(run_cli("run", scenario), "1e+300")  # was "Maximum allowed size exceeded"


def _fly(tmp_path: Path, flight: Path, *sets: str) -> Path:
    scenario = tmp_path / "fly.toml"
    text = (ROOT / "examples" / "fly-recorded.toml").read_text()
    text = text.replace('"samples/dt_flight.csv"', json.dumps(str(SAMPLES / "dt_flight.csv")))
    scenario.write_text(text.replace('"samples/flight_merged.csv"', json.dumps(str(flight))))
    return scenario


def test_a_long_recorded_flight_is_refused_before_its_slots_are_built(tmp_path: Path) -> None:
    """2e5 s at slot_s = 0.01 s is 2e7 slots (160 MB of slot times): refused from the count,
    with under 20 MB allocated (the slot times were built before the check)."""
    lines = (SAMPLES / "flight_merged.csv").read_text().splitlines()
    last = lines[-1].split(",")
    last[0] = "2025-05-26 23:59:00"  # about 2e5 s after the first row
    flight = tmp_path / "long.csv"
    flight.write_text("\n".join([*lines[:-1], ",".join(last)]) + "\n")
    scenario = _fly(tmp_path, flight)
    from skymule.world import build_mission

    spec = load_scenario(scenario, ["mission.slot_s=0.01"])
    tracemalloc.start()
    try:
        with pytest.raises(SkymuleError, match=r"slots of 0\.01 s; at most 10,000,000"):
            build_mission(spec)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6, peak


def test_a_recorded_flight_outside_the_geofence_is_refused(tmp_path: Path) -> None:
    """The sample flight moved 5 km east is refused like a waypoint there (it was flown)."""
    lines = (SAMPLES / "flight_merged.csv").read_text().splitlines()
    header = lines[0].split(",")
    lon = header.index("Longitude")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        row[lon] = f"{float(row[lon]) + 0.0553:.7f}"  # ~5 km at 35.7 N
    flight = tmp_path / "outside.csv"
    flight.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    done = run_cli("run", _fly(tmp_path, flight))
    _one_line(done, "trajectory.flight[0]", "outside the geofence")
    inside = run_cli("run", _fly(tmp_path, SAMPLES / "flight_merged.csv"), "--json", check=True)
    assert json.loads(inside.stdout)["total_downloaded_mbit"] > 0


# --- flags and scenario keys -----------------------------------------------------------------


def test_fit_radiomap_neural_with_a_negative_seed_is_one_line(tmp_path: Path) -> None:
    done = run_cli(
        "fit-radiomap", SAMPLES / "dt_flight.csv", "--out", tmp_path / "m.json",
        "--method", "neural", "--seed", "-1",
    )  # fmt: skip
    _one_line(done, "--seed -1", "0 or above")
    assert not (tmp_path / "m.json").exists()
    done = run_cli("sim2real", "paper-sim-fixed", SAMPLES / "flight_merged.csv",
                   "--twin", "paper-sim-fixed", "--seed", "-5")  # fmt: skip
    _one_line(done, "--seed -5", "0 or above")


def test_bandwidth_has_a_physical_upper_bound() -> None:
    with pytest.raises(SkymuleError, match=r"radio.bandwidth_hz = 1e\+308"):
        load_scenario("paper-sim-fixed", ["radio.bandwidth_hz=1e308"])
    _one_line(run_cli("run", "paper-sim-fixed", "--set", "radio.bandwidth_hz=1e308"), "1e+308")
    assert load_scenario("paper-sim-fixed", ["radio.bandwidth_hz=4e8"]).radio.bandwidth_hz == 4e8


def test_copying_the_sample_flight_keeps_it_flyable(tmp_path: Path) -> None:
    """The fixes above refuse nothing of the shipped example (fly-recorded)."""
    flight = tmp_path / "copy.csv"
    shutil.copy(SAMPLES / "flight_merged.csv", flight)
    assert read_trace(flight).n_samples == 360
