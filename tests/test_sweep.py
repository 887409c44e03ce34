"""Sweeps: files, reproducible missions, executors, resumable store, CLI errors."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from conftest import SMALL_SWEEP, run_cli, write
from engine_cases import TWIN_RTOL
from skymule.experiments import store
from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.scenario import scenario_from_dict
from skymule.tasks.simulate import simulate

SKYMULE = str(Path(sys.executable).with_name("skymule"))

SMALL = SMALL_SWEEP


def test_rows_equal_single_mission_runs(tmp_path):
    spec = load_sweep(write(tmp_path, SMALL.format(n=3)))
    outcome = run_sweep(spec, tmp_path / "out", executor="inprocess", progress=False)
    assert len(outcome.results) == len(spec) == 12
    missions = {m.mission_id: m for m in iter_missions(spec)}
    for row in outcome.results.iloc[[0, 5, 11]].to_dict("records"):
        mission = missions[row["mission_id"]]
        summary = simulate(scenario_from_dict(mission.scenario, "t", Path("."))).summary
        assert row["policy"] == summary["policy"] == mission.params["policy.name"]
        for key in ("handovers", "hover_time_s", "slots"):
            assert row[key] == summary[key], key
        for key in ("total_downloaded_mbit", "distance_m"):  # compiled sums: another order
            assert row[key] == pytest.approx(summary[key], rel=TWIN_RTOL, abs=0.0), key
    # paired: both policies fly the same buffers
    results = outcome.results
    greedy = results[results["policy"] == "greedy"].reset_index(drop=True)
    hgad = results[results["policy"] == "hgad"].reset_index(drop=True)
    pd.testing.assert_series_equal(greedy["total_buffer_mbit"], hgad["total_buffer_mbit"])
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    # one row per policy and duration (the list axis; seeds are replicates)
    assert summary["policy"].tolist() == ["greedy", "greedy", "hgad", "hgad"]
    assert summary["mission.duration_s"].tolist() == [120, 200, 120, 200]
    assert summary["missions"].tolist() == [3, 3, 3, 3]


def test_missions_are_reproducible_and_keep_ids_when_axes_grow(tmp_path):
    small = load_sweep(write(tmp_path, SMALL.format(n=3), "a.toml"))
    large = load_sweep(write(tmp_path, SMALL.format(n=5), "b.toml"))
    first = [(m.mission_id, m.params) for m in iter_missions(small)]
    assert first == [(m.mission_id, m.params) for m in iter_missions(small)]
    assert {i for i, _ in first} <= {m.mission_id for m in iter_missions(large)}
    assert len({i for i, _ in first}) == len(first)
    buffers = {m.params["sensors[0].buffer_mbit"] for m in iter_missions(small)}
    assert len(buffers) == 6  # one draw per (seed, duration), shared by both policies
    assert all(50 <= b <= 600 for b in buffers)


def test_sample_mode_and_positions(tmp_path):
    text = """
base = "paper-sim-fixed"
mode = { sample = 4 }
[axes]
"policy.name" = ["greedy", "hgad"]
"sensors[0].x_m" = { dist = "normal", mean = 0, std = 50 }
"sensors[0].y_m" = { dist = "uniform", low = -100, high = 100 }
"""
    spec = load_sweep(write(tmp_path, text))
    missions = list(iter_missions(spec))
    assert len(missions) == len(spec) == 8
    sensor = missions[0].scenario["sensors"][0]
    assert "lat" not in sensor and sensor["x_m"] == missions[0].params["sensors[0].x_m"]
    assert missions[0].params["sensors[0].x_m"] == missions[1].params["sensors[0].x_m"]
    assert missions[0].params["sensors[0].x_m"] != missions[2].params["sensors[0].x_m"]
    assert missions[1].scenario["sensors"][1].get("lat") is not None


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_executors_give_identical_tables(tmp_path):
    spec = load_sweep(write(tmp_path, SMALL.format(n=4)))
    tables = {}
    for executor in ("inprocess", "process", "dask-local"):
        outcome = run_sweep(
            spec,
            tmp_path / executor,
            executor=executor,
            workers=2 if executor == "process" else 1,
            chunk_size=5,
            progress=False,
        )
        tables[executor] = outcome.results
    assert len(tables["inprocess"]) == 16
    pd.testing.assert_frame_equal(tables["inprocess"], tables["process"])
    pd.testing.assert_frame_equal(tables["inprocess"], tables["dask-local"])


def test_kill_and_resume_runs_every_mission_exactly_once(tmp_path):
    path = write(tmp_path, SMALL.format(n=150))  # 600 missions, 30 chunks
    out = tmp_path / "out"
    command = [SKYMULE, "sweep", str(path), "--out", str(out), "--executor", "inprocess"]
    command += ["--chunk-size", "20", "--quiet"]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    while len(store.part_paths(out)) < 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    done_before = store.done_ids(out)
    assert 0 < len(done_before) < 600, "the sweep was not killed mid-way"
    assert not (out / "results.parquet").exists()
    rerun = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert rerun.returncode == 0, rerun.stderr
    assert f"ran {600 - len(done_before)} of 600" in " ".join(rerun.stdout.split())
    results = pd.read_parquet(out / "results.parquet")
    expected = [m.mission_id for m in iter_missions(load_sweep(path))]
    assert results["mission_id"].tolist() == expected
    assert results["mission_index"].tolist() == list(range(600))


BAD = {
    "unknown field": ('"policy.nme" = [1, 2]', "axes.policy.nme", "unknown field"),
    "empty axis": ("seed = []", "axes.seed is empty", ""),
    "empty range": ("seed = { range = [5, 5] }", "axes.seed.range", "empty"),
    "bad uniform": (
        '"sensors[*].buffer_mbit" = { dist = "uniform", low = 9, high = 1 }',
        "low = 9 must be below high = 1",
        "",
    ),
    "negative std": (
        '"sensors[0].x_m" = { dist = "normal", mean = 0, std = -1 }',
        "std = -1 must be >= 0",
        "",
    ),
    "unknown dist": ('seed = { dist = "poisson", lam = 3 }', "dist = 'poisson'", "allowed"),
    "unknown policy": ('policy.name = ["greedy", "best"]', "'best'", "allowed: greedy"),
    "invalid value": ('"mission.duration_s" = [-5]', "mission.duration_s = -5", ""),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sweep_files_get_one_line_and_exit_2(tmp_path, case):
    axis, *fragments = BAD[case]
    path = write(tmp_path, f'base = "paper-sim-fixed"\n[axes]\nseed = [1, 2]\n{axis}\n')
    if case in ("empty axis", "empty range", "unknown dist"):
        path.write_text(f'base = "paper-sim-fixed"\n[axes]\n{axis}\n')
    result = run_cli("sweep", path, "--out", tmp_path / "out", "--executor", "inprocess")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert str(path) in lines[0]
    for fragment in fragments:
        assert fragment in lines[0]
    assert not (tmp_path / "out" / "results").exists()
