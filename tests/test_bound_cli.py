"""``skymule bound`` and the bound in ``skymule compare``, driven as a user drives them."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import CliResult, preset_mission, run_cli
from skymule.bounds.mission import mission_bound
from skymule.bounds.result import BoundError
from skymule.errors import SkymuleError
from skymule.io.traces import write_dt_export
from skymule.scenario import load_scenario
from skymule.world import build_mission

BOUND_KEYS = ("upper_bound_mbit", "no_hover_upper_bound_mbit", "method", "status", "solve_time_s")


def skymule(*args: str) -> CliResult:
    # wide enough for rich to print whole headers
    return run_cli(*args, env={"COLUMNS": "250"})


def one_line_error(done: CliResult, needle: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], done.stderr


def trace_scenario(tmp_path: Path, extra: str = "") -> Path:
    """A two-tower DT-export replay: LW1 loud early, LW2 loud late (SNR in dB)."""
    time_s = np.arange(40.0)
    snr = np.column_stack([30.0 - time_s, time_s - 10.0])
    write_dt_export(
        tmp_path / "flight.csv",
        time_s,
        snr,
        ["LW1", "LW2"],
        5.0 * time_s,
        0.0 * time_s,
        30 + 0 * time_s,
    )
    path = tmp_path / "replay.toml"
    path.write_text(
        'name = "replay"\n[[sensors]]\nname = "LW1"\nbuffer_mbit = 40\n'
        '[[sensors]]\nname = "LW2"\nbuffer_mbit = 60\n'
        f'[signal]\nsource = "trace"\ntrace = "flight.csv"\n{extra}'
    )
    return path


def test_bound_preset_writes_json(tmp_path: Path) -> None:
    done = skymule("bound", "paper-sim-fixed", "--out", str(tmp_path / "b"))
    assert done.returncode == 0, done.stderr
    assert "upper_bound_mbit" in done.stdout
    record = json.loads((tmp_path / "b" / "bound.json").read_text())
    assert all(key in record for key in BOUND_KEYS)
    # the buffers hold 3000 Mbit; hovering reaches all of it, the paper's no-hover LP less
    assert record["upper_bound_mbit"] == pytest.approx(3000.0, rel=1e-9)
    assert 2500.0 < record["no_hover_upper_bound_mbit"] < record["upper_bound_mbit"]
    assert record["mode"] == "fixed" and "HiGHS" in record["method"]
    assert "Optimal" in record["status"] and record["solve_time_s"] < 5.0


def test_bound_trace_source(tmp_path: Path) -> None:
    path = trace_scenario(tmp_path)
    done = skymule("bound", str(path), "--out", str(tmp_path / "b"))
    assert done.returncode == 0, done.stderr
    record = json.loads((tmp_path / "b" / "bound.json").read_text())
    mission = build_mission(load_scenario(str(path)))
    assert mission.track is not None and not mission.track.hold_at_end
    expected = mission_bound(mission)
    assert record["upper_bound_mbit"] == pytest.approx(expected.upper_bound_bit / 1e6)
    assert record["no_hover_upper_bound_mbit"] <= record["upper_bound_mbit"] + 1e-9
    assert record["upper_bound_mbit"] <= 100.0 + 1e-9


def test_bound_refuses_fading_on_fixed_paths(tmp_path: Path) -> None:
    path = trace_scenario(tmp_path, '[radio]\nfading = "rayleigh"\n')
    one_line_error(skymule("bound", str(path)), "radio.fading = 'rayleigh'")


def test_bound_bad_scenario_is_one_line() -> None:
    one_line_error(skymule("bound", "no-such-preset"), "paper-sim-fixed")


def test_autonomous_bound_missing_is_one_line(monkeypatch: pytest.MonkeyPatch) -> None:
    mission = preset_mission("paper-sim-autonomous")
    monkeypatch.setitem(sys.modules, "skymule.bounds.autonomous", None)
    with pytest.raises(BoundError, match="autonomous bound is not available") as caught:
        mission_bound(mission)
    assert isinstance(caught.value, SkymuleError) and "\n" not in str(caught.value)


def test_compare_has_bound_row_and_gap(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    done = skymule(
        "compare", "paper-sim-fixed", "--policies", "greedy,hgad,optimal-fixed", "--out", str(out)
    )
    assert done.returncode == 0, done.stderr
    assert "bound" in done.stdout and "gap Mbit" in done.stdout
    table = pd.read_csv(out / "comparison.csv").set_index("policy")
    assert table.index.tolist() == ["greedy", "hgad", "optimal-fixed"]
    bound = json.loads((out / "bound.json").read_text())["upper_bound_mbit"]
    gap = bound - table["total_downloaded_mbit"]
    assert np.allclose(table["gap_to_bound_mbit"], gap)
    assert np.allclose(table["gap_to_bound_frac"], gap / bound)
    assert (table["gap_to_bound_mbit"] >= -1e-6).all()
    assert table.loc["optimal-fixed", "gap_to_bound_mbit"] < table.loc["hgad", "gap_to_bound_mbit"]


def test_compare_without_a_bound_still_runs(tmp_path: Path) -> None:
    path = trace_scenario(tmp_path, '[radio]\nfading = "rician"\n')
    done = skymule("compare", str(path), "--policies", "greedy,optimal-fixed")
    assert done.returncode == 0, done.stderr
    assert "no upper bound" in done.stdout and "radio.fading" in done.stdout


def test_the_grid_bound_warns_when_the_snr_breaks_its_condition(tmp_path: Path) -> None:
    """Strong shadowing varies by more than 1 dB within 3.5 m: the grid bound says so on
    stderr and in bound.json (it is still computed); free space keeps it quiet."""
    shadowed = ("--set", "radio.shadowing_std_db=8", "--set", "radio.shadowing_decorrelation_m=20")
    done = skymule("bound", "paper-sim-autonomous", *shadowed, "--out", str(tmp_path / "b"))
    assert done.returncode == 0, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("skymule: warning: the grid bound's condition fails here")
    assert "within 3.5 m" in line
    record = json.loads((tmp_path / "b" / "bound.json").read_text())
    assert record["warnings"] == [line.removeprefix("skymule: warning: ")]
    assert "warnings" not in done.stdout  # in the table's place: stderr
    clean = skymule("bound", "paper-sim-autonomous", "--json")
    assert clean.stderr == "" and json.loads(clean.stdout)["warnings"] == []
    compared = skymule("compare", "paper-sim-autonomous", *shadowed, "--policies", "greedy")
    assert "skymule: warning: upper bound: the grid bound's condition fails" in compared.stderr


def test_steepest_step_ignores_points_off_the_grid_and_dead_links() -> None:
    from skymule.bounds.autonomous import steepest_step_db

    snr = np.array([[10.0, 12.5, np.nan], [11.0, -np.inf, 40.0]])[:, :, None]
    assert steepest_step_db(snr) == 2.5  # 10 -> 12.5 across, 10 -> 11 down; 40 has no neighbour
    assert steepest_step_db(np.full((2, 2, 1), np.nan)) == 0.0


def test_the_python_bound_reads_in_mbit_like_every_summary() -> None:
    from skymule.tasks.compare import compare_policies, scenario_bound

    scenario = load_scenario("paper-sim-fixed")
    upper = scenario_bound(scenario)
    assert upper.upper_bound_mbit == pytest.approx(3000.0) and upper.total_buffer_mbit == 3000.0
    assert upper.upper_bound_mbit == upper.to_json_dict()["upper_bound_mbit"]
    assert 2500.0 < (upper.no_hover_upper_bound_mbit or 0.0) < 3000.0
    (row,) = compare_policies(scenario, ["hgad"]).rows()
    assert row["upper_bound_mbit"] - row["total_downloaded_mbit"] == row["gap_to_bound_mbit"]
