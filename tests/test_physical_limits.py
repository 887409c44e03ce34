"""Physical limits (issue 24): altitude, speed, coordinates, volumes and rate tables beyond
what any mission can be are refused in one line naming the limit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli
from skymule.errors import SkymuleError
from skymule.io.traces import read_trace, write_aadm_log, write_dt_export
from skymule.limits import MAX_ALTITUDE_M, MAX_SPEED_MPS, waypoint_problem
from skymule.radio.rates import read_rate_csv
from skymule.scenario import load_scenario


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ("trajectory.altitude_m=1e300", "trajectory.altitude_m = 1e+300: at most 20000 m"),
        ("trajectory.max_speed_mps=1e12", "max_speed_mps = 1000000000000.0: at most 340 m/s"),
        ("trajectory.speed_mps=1e12", "speed_mps = 1000000000000.0: at most 340 m/s"),
        ("trajectory.waypoints=[[0, 0, 30], [90, 0, -5]]", "waypoint 2: z_m = -5.0: allowed: 0"),
        ("trajectory.waypoints=[[1e300, 0, 30], [90, 0, 30]]", "waypoint 1: x_m = 1e+300"),
        ("trajectory.home=[0, -1e300]", "trajectory.home = [0, -1e+300]: -1e+300: at most 1e+07 m"),
        ("trajectory.visit_radius_m=1e300", "visit_radius_m = 1e+300: at most 1e+07 m"),
        ("sensors[0].buffer_mbit=1e300", "buffer_mbit = 1e+300"),
    ],
)
def test_scenario_values_beyond_physics_are_one_line(override: str, expected: str) -> None:
    with pytest.raises(SkymuleError) as caught:
        load_scenario("paper-sim-fixed", [override])
    assert expected in str(caught.value) and "\n" not in str(caught.value)


def test_the_limits_leave_room_for_large_uavs() -> None:
    scenario = load_scenario(
        "paper-sim-autonomous",
        ["trajectory.altitude_m=18000", "trajectory.max_speed_mps=175"],  # an RQ-4's envelope
    )
    assert scenario.trajectory.altitude_m == 18_000 < MAX_ALTITUDE_M
    assert scenario.trajectory.max_speed_mps < MAX_SPEED_MPS
    assert waypoint_problem(np.array([[0, 0, 0.0], [5e6, -5e6, MAX_ALTITUDE_M]])) is None


def test_a_waypoint_file_under_the_ground_is_refused(tmp_path: Path) -> None:
    (tmp_path / "path.csv").write_text("x_m,y_m,z_m\n0,0,30\n100,0,-2\n")
    done = run_cli(
        "run", "paper-sim-fixed", "--set", f'trajectory.waypoints="{tmp_path / "path.csv"}"'
    )
    assert done.returncode == 2
    [line] = done.stderr.strip().splitlines()
    assert "trajectory.waypoints (" in line and "waypoint 2: z_m = -2.0" in line


@pytest.mark.parametrize(
    ("rows", "expected"),
    [
        ("-5,0.1\n0,nan\n", "line 3: efficiency nan must be a finite number from 0 to 100"),
        ("-5,0.1\n0,1e9\n", "line 3: efficiency 1000000000.0 must be a finite number"),
        ("inf,0.1\n", "line 2: snr_db inf must be a finite number"),
        ("-5,0.5\n0,0.2\n", "line 3: efficiency 0.2 at snr_db 0 is lower than 0.5 at -5"),
        ("-5,0.5\n-5,0.7\n", "lines 2 and 3 both give snr_db -5"),
    ],
)
def test_rate_tables_are_finite_and_monotone(tmp_path: Path, rows: str, expected: str) -> None:
    path = tmp_path / "rates.csv"
    path.write_text("snr_db,efficiency\n" + rows)
    with pytest.raises(SkymuleError, match=expected):
        read_rate_csv(path)


def test_a_sorted_rate_table_still_reads(tmp_path: Path) -> None:
    path = tmp_path / "rates.csv"
    path.write_text("snr_db,efficiency\n10,2.0\n-5,0.1\n0,0.5\n")  # any order, monotone
    table = read_rate_csv(path)
    assert table.thresholds_db == (-5.0, 0.0, 10.0)
    assert table.efficiency(np.array([-10.0, 1.0, 30.0])).tolist() == [0.0, 0.5, 2.0]


def test_the_controller_refuses_volumes_analyze_refuses(tmp_path: Path) -> None:
    """The audit: `aadm controller --volumes` took 1e300 Mbit, which `analyze` refused."""
    volumes = tmp_path / "volumes.txt"
    volumes.write_text("10\n1e300\n90\n270\n")
    done = run_cli("aadm", "controller", "aadm-default", "--volumes", volumes)
    assert done.returncode == 2
    [line] = done.stderr.strip().splitlines()
    assert "line 2: '1e300' Mbit: at most 1e+12 Mbit" in line


def test_trace_positions_beyond_the_limits_are_refused(tmp_path: Path) -> None:
    time_s = np.arange(3.0)
    snr = np.zeros((3, 1))
    high = {
        "lat_deg": np.full(3, 35.72),
        "lon_deg": np.full(3, -78.69),
        "alt_m": np.array([30, 1e9, 30]),
    }
    write_aadm_log(tmp_path / "a.csv", time_s, snr, ["LW1"], **high)
    with pytest.raises(
        SkymuleError,
        match=r"row 3, column 'Altitude': '1000000000.0' is out of range \(allowed: -20000 to "
        r"20000 m\)",
    ):
        read_trace(tmp_path / "a.csv")
    far = {"x_m": np.array([0, 0, 3e7]), "y_m": np.zeros(3), "z_m": np.full(3, 30.0)}
    write_dt_export(tmp_path / "d.csv", time_s, snr, ["LW1"], **far)
    with pytest.raises(SkymuleError, match="row 4, column 'X'"):
        read_trace(tmp_path / "d.csv")
