"""``[trajectory] flight``: a recorded flight's positions over time, under any signal source."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from conftest import run_cli
from skymule.experiments.run import run_sweep
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.geo import LocalFrame
from skymule.io.traces import write_aadm_log, write_dt_export
from skymule.scenario import load_scenario, scenario_from_dict
from skymule.tasks.compare import compare_policies
from skymule.tasks.simulate import simulate
from skymule.world import build_mission

ROOT = Path(__file__).resolve().parents[1]
ORIGIN = (35.7274824, -78.6962749)

SCENARIO = """
name = "fly"
[site]
origin = {{ lat = 35.7274824, lon = -78.6962749 }}
[[sensors]]
name = "LW1"
x_m = 100.0
y_m = 50.0
buffer_mbit = 40
[[sensors]]
name = "LW2"
x_m = -150.0
y_m = -60.0
buffer_mbit = 60
[radio]
model = "fspl"
[trajectory]
mode = "fixed"
flight = "{flight}"
"""


def _flight(n: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Uneven sample times [s] and positions [m]: a 40-sample flight with a 3-s gap."""
    time_s = np.cumsum(np.r_[0.0, np.full(n - 1, 0.7)])
    time_s[20:] += 3.0
    angle = time_s / 10.0
    xyz = np.column_stack([120 * np.cos(angle), 80 * np.sin(angle), 30 + time_s / 4])
    return time_s, xyz


@pytest.fixture()
def dt_flight(tmp_path: Path) -> Path:
    time_s, xyz = _flight()
    snr = np.full((len(time_s), 2), 5.0)  # ignored: the scenario's source gives the SNR
    path = tmp_path / "flight.csv"
    write_dt_export(path, time_s, snr, ["LW1", "LW2"], xyz[:, 0], xyz[:, 1], xyz[:, 2])
    return path


def _scenario(tmp_path: Path, flight: Path, extra: str = "") -> Path:
    path = tmp_path / "fly.toml"
    path.write_text(SCENARIO.format(flight=flight.name) + extra)
    return path


def test_positions_are_resampled_to_the_slots_by_time(tmp_path: Path, dt_flight: Path) -> None:
    mission = build_mission(load_scenario(_scenario(tmp_path, dt_flight)))
    time_s, xyz = _flight()
    assert mission.track is not None and mission.source is not None
    slots = np.arange(int(time_s[-1]) + 1, dtype=float)  # slot k starts at k s
    assert mission.n_slots == len(slots) == mission.track.n_samples
    expected = np.column_stack([np.interp(slots, time_s, xyz[:, a]) for a in range(3)])
    np.testing.assert_allclose(mission.track.position_m, expected, atol=1e-9)
    # the SNR is the scenario's source at those positions, not the trace's column
    np.testing.assert_allclose(mission.track.snr_db, mission.source.snr_db(expected))
    assert not mission.track.hold_at_end  # the recorded flight ends where it ended
    half = build_mission(load_scenario(_scenario(tmp_path, dt_flight), ["mission.slot_s=0.5"]))
    assert half.n_slots == 61  # slots start at 0, 0.5, ..., 30.0 s (the flight ends at 30.3 s)


def test_any_trace_format_flies_the_same_path(tmp_path: Path, dt_flight: Path) -> None:
    """The same flight as an AADM merged log (lat/lon, timestamps) flies the same track."""
    time_s, xyz = _flight()
    lat, lon = LocalFrame(*ORIGIN).to_latlon(xyz[:, 0], xyz[:, 1])
    merged = tmp_path / "merged.csv"
    snr = np.zeros((len(time_s), 2))
    write_aadm_log(merged, time_s, snr, ["LW1", "LW2"], lat.round(8), lon.round(8), xyz[:, 2])
    from_dt = build_mission(load_scenario(_scenario(tmp_path, dt_flight)))
    from_log = build_mission(load_scenario(_scenario(tmp_path, merged)))
    assert from_dt.track is not None and from_log.track is not None
    np.testing.assert_allclose(from_log.track.position_m, from_dt.track.position_m, atol=0.01)


def test_flight_under_a_radio_map_and_through_compare_and_sweep(
    tmp_path: Path, dt_flight: Path
) -> None:
    """A flight flown under a map fitted to another recorded flight, compared and swept."""
    signal = '[signal]\nsource = "radiomap"\ntraces = ["other.csv"]\n'
    other = tmp_path / "other.csv"
    grid = np.stack(np.meshgrid(np.linspace(-200, 200, 9), np.linspace(-150, 150, 7)), -1)
    xy = grid.reshape(-1, 2)
    d = np.linalg.norm(xy[:, None, :] - np.array([[100.0, 50.0], [-150.0, -60.0]]), axis=-1)
    snr = 60.0 - 20 * np.log10(np.hypot(d, 20.0)) + np.sin(xy[:, :1] / 40.0)
    n = len(xy)
    write_dt_export(other, np.arange(n), snr, ["LW1", "LW2"], xy[:, 0], xy[:, 1], np.full(n, 30))
    scenario = load_scenario(_scenario(tmp_path, dt_flight, signal))
    comparison = compare_policies(scenario, ["greedy", "hgad"])
    totals = {run.policy: run.result.summary["total_downloaded_mbit"] for run in comparison.runs}
    assert totals["greedy"] > 0 and totals["hgad"] > 0
    mission = build_mission(scenario)
    assert mission.track is not None and mission.source is not None
    np.testing.assert_allclose(
        mission.track.snr_db, mission.source.snr_db(mission.track.position_m)
    )
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'base = "fly.toml"\nmode = "product"\n[axes]\npolicy.name = ["greedy", "hgad"]\n'
        '"sensors[*].buffer_mbit" = [30, 60]\n'
    )
    spec = load_sweep(sweep)
    outcome = run_sweep(spec, tmp_path / "out", executor="inprocess", progress=False)
    assert len(outcome.results) == 4
    missions = {m.mission_id: m for m in iter_missions(spec)}
    for row in outcome.results.to_dict("records"):
        mission = missions[row["mission_id"]]
        single = simulate(scenario_from_dict(mission.scenario, "t", tmp_path)).summary
        assert row["total_downloaded_mbit"] == single["total_downloaded_mbit"] > 0
        assert row["slots"] == single["slots"] == 31  # slots start at 0..30 s


def test_cli_compare_and_report_of_a_recorded_flight(tmp_path: Path) -> None:
    """The example scenario: the sample flight's path under the sample DT's map."""
    out = tmp_path / "cmp"
    done = run_cli("compare", ROOT / "examples" / "fly-recorded.toml", "--out", out, check=True)
    assert "hgad" in done.stdout
    summary = json.loads((out / "greedy" / "summary.json").read_text())
    assert summary["total_downloaded_mbit"] > 0
    slots = pd.read_csv(out / "greedy" / "slots.csv")
    assert len(slots) == 360  # the 360-s sample flight, one slot a second
    run_cli("report", out, "--no-pdf", check=True)
    assert (out / "report.html").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ("waypoints = [[0, 0, 30], [10, 0, 30]]\n", "give either waypoints or flight"),
        ('\n[signal]\nsource = "trace"\ntrace = "flight.csv"\n', "use source = 'radiomap'"),
        ("", "trajectory.flight: "),
    ],
)
def test_flight_mistakes_are_one_line(
    tmp_path: Path, dt_flight: Path, extra: str, needle: str
) -> None:
    path = _scenario(tmp_path, dt_flight, extra)
    if not extra:
        dt_flight.unlink()  # the recorded flight is missing
    done = run_cli("run", path, "--out", tmp_path / "run")
    assert done.returncode == 2, done.stderr
    assert needle in done.stderr and len(done.stderr.strip().splitlines()) == 1
