"""Several UAVs: the fleet slot contract by hand, one UAV equals today's engine, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from conftest import run_cli
from skymule.bounds.fleet import fleet_bound, fleet_time_sharing_lp
from skymule.errors import ScenarioError, SkymuleError
from skymule.flight.paths import Track
from skymule.policies.base import Action, MissionContext, Observation
from skymule.policies.fleet import partition
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import Scenario, UavSpec, load_scenario
from skymule.sim.fleet import Fleet, build_fleet
from skymule.sim.run import mission_context
from skymule.tasks.fleet import make_fleet_policy, run_fleet, simulate_fleet
from skymule.tasks.simulate import simulate
from skymule.world import mission_from_track

MBIT = 1e6


def test_fleet_served_conflict_tie_and_no_choice() -> None:
    # columns are three independent missions; rows are UAVs 0..2
    choice = np.array([[1, 0, NO_SENSOR], [1, 0, 2], [2, 0, 2]])
    rate = np.array([[5.0, 3.0, 9.0], [7.0, 3.0, 4.0], [1.0, 3.0, 4.0]])
    served = contract.fleet_served(choice, rate)
    # mission 0: UAVs 0 and 1 both want sensor 1, UAV 1's rate is higher; UAV 2 alone on 2
    assert served[:, 0].tolist() == [NO_SENSOR, 1, 2]
    # mission 1: a three-way tie on sensor 0 goes to the lowest UAV index
    assert served[:, 1].tolist() == [0, NO_SENSOR, NO_SENSOR]
    # mission 2: UAV 0 chose nothing; UAVs 1 and 2 tie on sensor 2 -> UAV 1
    assert served[:, 2].tolist() == [NO_SENSOR, 2, NO_SENSOR]


def test_serve_slot_shares_one_buffer_by_hand() -> None:
    """Two fleet missions of two UAVs each (columns 0-1 and 2-3), buffers (N, G) shared per
    mission: conflicts first, then faults, then min(R dt, Q) taken from the shared buffer."""
    remaining = np.array([[2.0, 6.0], [10.0, 6.0], [4.0, 6.0]])  # 3 sensors x 2 missions
    # deliver rates (N, B): column b is UAV b's rate to each sensor
    rate = np.array([[5.0, 1.0, 2.0, 2.0], [1.0, 3.0, 1.0, 1.0], [1.0, 1.0, 9.0, 1.0]])
    ok = np.ones((3, 4), bool)
    ok[2, 2] = False  # UAV 0 of mission 1 finds sensor 2 blocked this slot
    sensor = np.array([0, 1, 2, 2])
    served, bits, lost = contract.serve_slot(
        sensor, rate, ok, remaining, np.array([0, 0, 1, 1]), 2, np.ones(4)
    )
    # mission 0: no conflict; UAV 0 empties sensor 0 (min(5, 2)), UAV 1 gets min(3, 10)
    # mission 1: both chose sensor 2; UAV 0's rate (9) wins, but a fault blocks it: nobody
    assert served.tolist() == [0, 1, -1, -1]
    assert bits.tolist() == [2.0, 3.0, 0.0, 0.0]
    assert lost is not None and lost.tolist() == [False, False, False, True]
    assert remaining.tolist() == [[0.0, 6.0], [7.0, 6.0], [4.0, 6.0]]


class Script:
    """Serves the listed sensor in each slot (None: nothing)."""

    def __init__(self, name: str, plan: list[int | None]) -> None:
        self.name, self.plan = name, plan
        self.seen: list[np.ndarray] = []

    def reset(self, context: MissionContext) -> None:
        pass

    def act(self, observation: Observation) -> Action:
        self.seen.append(observation.remaining_bit.copy())
        return Action(serve=self.plan[observation.slot])


def _two_uav_fleet(snr_a: list[float], snr_b: list[float], buffers: list[float]) -> Fleet:
    # bandwidth 1 MHz: the AADM table's rate in Mbit/s is its spectral efficiency:
    # 23 dB -> 5.55, 15 dB -> 3.32
    missions = tuple(
        mission_from_track(
            Track(np.zeros((1, 3)), np.array([snr], float), hold_at_end=True),
            buffers,
            n_slots=3,
            bandwidth_hz=1e6,
        )
        for snr in (snr_a, snr_b)
    )
    specs = (missions[0].scenario.policy,) * 2
    return Fleet(missions[0].scenario, ("A", "B"), missions, specs)


def test_two_uav_contract_by_hand() -> None:
    fleet = _two_uav_fleet([15, 23], [23, 23], [2.0, 100.0])
    a = Script("a", [0, 1, 0])
    b = Script("b", [0, 1, 1])
    log = run_fleet(fleet, [a, b])
    got_a, got_b = (np.round(x.downloaded_bit / MBIT, 6).tolist() for x in log.missions())
    # slot 0: both want S1; B's rate (5.55) beats A's (3.32): B empties its 2 Mbit, A gets 0
    # slot 1: both want S2 at 5.55: a tie, A (index 0) wins
    # slot 2: A asks for the emptied S1 (served, 0 bits, not lost), B takes S2 alone
    assert got_a == [0.0, 5.55, 0.0]
    assert got_b == [2.0, 0.0, 5.55]
    assert log.lost.T.tolist() == [[True, False], [False, True], [False, False]]
    assert log.mission(0).served.tolist() == [NO_SENSOR, 1, 0]
    assert log.mission(1).served.tolist() == [0, NO_SENSOR, 1]
    # shared buffers: both UAVs observe (and log) the same buffers
    assert a.seen[1].tolist() == b.seen[1].tolist() == [0.0, 100 * MBIT]
    final = [0.0, (100 - 2 * 5.55) * MBIT]
    assert np.allclose(log.mission(0).remaining_bit[-1], final)
    assert np.allclose(log.mission(1).remaining_bit[-1], final)


def test_policy_choosing_a_missing_sensor_is_one_clear_error() -> None:
    fleet = _two_uav_fleet([15, 23], [23, 23], [2.0, 100.0])
    with pytest.raises(SkymuleError, match=r"'b \(B\)' chose sensor 7; allowed: 0..1"):
        run_fleet(fleet, [Script("a", [0, 0, 0]), Script("b", [7, 0, 0])])


def _one_uav(scenario: Scenario) -> Scenario:
    waypoints = scenario.trajectory.waypoints if scenario.trajectory.mode == "fixed" else None
    return scenario.model_copy(update={"uavs": [UavSpec(name="solo", waypoints=waypoints)]})


def _same_log(single: object, fleet_log: object) -> None:
    for field in ("served", "downloaded_bit", "remaining_bit", "position_m", "hovering"):
        assert np.array_equal(getattr(single, field), getattr(fleet_log, field)), field


@pytest.mark.parametrize(
    ("preset", "policy"),
    [
        ("paper-sim-fixed", "greedy"),
        ("paper-sim-fixed", "hgad"),
        ("aadm-default", "hgad"),
        ("paper-sim-autonomous", "greedy"),
        ("paper-sim-autonomous", "hgad"),
    ],
)
def test_one_uav_fleet_equals_todays_engine(preset: str, policy: str) -> None:
    scenario = load_scenario(preset)
    single = simulate(scenario, policy)
    for variant in (scenario, _one_uav(scenario)):
        result = simulate_fleet(variant, policy)
        _same_log(single.log, result.log.mission(0))
        assert result.summary["total_downloaded_mbit"] == single.summary["total_downloaded_mbit"]
        assert result.summary["uavs"][0]["energy_kj"] == single.summary["energy_kj"]


def _two_uav_scenario(**home: list[float]) -> Scenario:
    base = load_scenario("paper-sim-autonomous")
    uavs = [UavSpec(name="A"), UavSpec(name="B", home=home.get("b", [-200.0, -100.0]))]
    mission = base.mission.model_copy(update={"duration_s": 300.0})
    return base.model_copy(update={"uavs": uavs, "mission": mission})


def test_coordinated_beats_independent_hgad_and_both_respect_the_k_uav_bound() -> None:
    scenario = _two_uav_scenario()
    fleet = build_fleet(scenario)
    hgad = simulate_fleet(scenario, "hgad", fleet=fleet).summary
    coordinated = simulate_fleet(scenario, "coordinated", fleet=fleet).summary
    assert coordinated["total_downloaded_mbit"] > hgad["total_downloaded_mbit"]
    assert all(uav["landed_within_5m"] for uav in coordinated["uavs"])
    owner = partition([mission_context(m) for m in fleet.missions])
    assert set(owner.tolist()) == {0, 1}  # both UAVs get sensors
    assert make_fleet_policy(fleet, "coordinated").name == "coordinated"
    upper = fleet_bound(fleet).upper_bound_bit
    assert max(hgad["total_downloaded_mbit"], coordinated["total_downloaded_mbit"]) * MBIT <= (
        upper + 1.0
    )


def test_fleet_lp_by_hand() -> None:
    # one sensor, two UAVs, 3 slots of 1 s at 5 bit/s: the sensor serves one UAV at a time
    rate = np.full((2, 3, 1), 5.0)
    assert fleet_time_sharing_lp(rate, np.array([100.0]), 1.0)[0] == pytest.approx(15.0)
    # two sensors: both UAVs can serve at once (each its own sensor)
    rate2 = np.full((2, 3, 2), 5.0)
    assert fleet_time_sharing_lp(rate2, np.array([100.0, 100.0]), 1.0)[0] == pytest.approx(30.0)
    # shared buffers cap the total
    assert fleet_time_sharing_lp(rate2, np.array([4.0, 7.0]), 1.0)[0] == pytest.approx(11.0)


def test_fixed_fleet_runs_each_path(tmp_path: Path) -> None:
    base = load_scenario("paper-sim-fixed")
    path = base.trajectory.waypoints
    assert isinstance(path, list)
    uavs = [UavSpec(name="A", waypoints=path), UavSpec(name="B", waypoints=path[::-1])]
    result = simulate_fleet(base.model_copy(update={"uavs": uavs}), "hgad")
    # the K-UAV bound on fixed paths holds
    assert (
        result.summary["total_downloaded_mbit"] * MBIT <= fleet_bound(result.fleet).upper_bound_bit
    )
    start_b = result.log.mission(1).position_m[0]
    assert np.allclose(start_b, path[-1])
    result.write(tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    parts = sum(u["total_downloaded_mbit"] for u in summary["uavs"])
    assert summary["total_downloaded_mbit"] == pytest.approx(parts)
    # each UAV's per-sensor download is its own share (the logs hold the shared buffers)
    for uav in summary["uavs"]:
        own = uav["per_sensor_downloaded_mbit"]
        assert sum(own.values()) == pytest.approx(uav["total_downloaded_mbit"])
    for sensor, fleet_mbit in summary["per_sensor_downloaded_mbit"].items():
        shares = [uav["per_sensor_downloaded_mbit"][sensor] for uav in summary["uavs"]]
        assert sum(shares) == pytest.approx(fleet_mbit)
    assert all(u["total_downloaded_mbit"] > 0 for u in summary["uavs"])
    # the run folder reads back and draws one trajectory figure for the fleet
    from skymule.io.runs import read_run
    from skymule.report.plot import plot_run

    read_summary, slots = read_run(tmp_path)
    assert sorted(set(slots["uav"])) == ["A", "B"]
    (figure,) = plot_run(tmp_path, read_summary, slots)
    assert figure.name == "trajectory.png" and figure.stat().st_size > 0


def _write(tmp_path: Path, extra: str) -> Path:
    text = (
        Path(load_scenario.__code__.co_filename)
        .parent.joinpath("scenarios", "paper-sim-autonomous.toml")
        .read_text()
    )
    path = tmp_path / "fleet.toml"
    path.write_text(text + extra)
    return path


def test_cli_run_and_compare_on_a_fleet(tmp_path: Path) -> None:
    # the command of docs/fleet.md, on its example
    scenario = Path(__file__).resolve().parents[1] / "examples" / "fleet-lake-wheeler.toml"
    out = tmp_path / "c"
    result = run_cli("compare", scenario, "--policies", "hgad,coordinated", "--out", out)
    assert result.returncode == 0, result.stderr
    table = (tmp_path / "c" / "comparison.csv").read_text().splitlines()
    assert table[0].startswith("scenario,policy,n_uavs")
    assert "gap_to_bound_mbit" in table[0]
    slots = (tmp_path / "c" / "hgad" / "slots.csv").read_text().splitlines()
    assert slots[0].startswith("uav,") and ",chosen,lost," in slots[0]
    assert len(slots) == 1 + 2 * 500
    # --json prints the comparison as JSON (no table): the CSV's totals, the bound, each gap
    printed = run_cli("compare", scenario, "--policies", "hgad,coordinated", "--json")
    assert printed.returncode == 0, printed.stderr
    record = json.loads(printed.stdout)
    assert [r["policy"] for r in record["runs"]] == ["hgad", "coordinated"]
    bound = record["bound"]["upper_bound_mbit"]
    for row in record["runs"]:
        assert row["gap_to_bound_mbit"] == pytest.approx(bound - row["total_downloaded_mbit"])


def test_cli_fleet_run_prints_json_or_a_table_that_keeps_every_value(tmp_path: Path) -> None:
    scenario = Path(__file__).resolve().parents[1] / "examples" / "fleet-lake-wheeler.toml"
    printed = run_cli("run", scenario, "--json")
    assert printed.returncode == 0, printed.stderr
    summary = json.loads(printed.stdout)
    assert summary["n_uavs"] == len(summary["uavs"]) == 2
    table = run_cli("run", scenario)  # piped: plain text, full names, every digit
    assert "total_downloaded_mbit" not in table.stdout  # the short header
    assert "Mbit" in table.stdout and "…" not in table.stdout
    assert f"{summary['total_downloaded_mbit']:.1f}" in table.stdout


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            '\n[[uavs]]\nname = "A"\n\n[[uavs]]\nname = "A"\n',
            "uavs: names must be unique; repeated: A",
        ),
        (
            '\n[[uavs]]\nname = "A"\n\n[[uavs]]\nname = "B"\nhome = [5000, 0]\n',
            "uavs[1] (B): trajectory.home = (5000.0, 0.0) m lies outside the geofence",
        ),
    ],
)
def test_bad_fleet_input_is_one_line_exit_2(tmp_path: Path, extra: str, message: str) -> None:
    result = run_cli("run", _write(tmp_path, extra))
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr


def test_fixed_fleet_needs_waypoints_per_uav() -> None:
    base = load_scenario("paper-sim-fixed")
    scenario = base.model_copy(update={"uavs": [UavSpec(name="A")]})
    with pytest.raises(ScenarioError, match=r"uavs\[0\] \(A\): waypoints is required"):
        build_fleet(scenario)


def test_bench_fleet_tiny_mode_runs_and_respects_the_bound(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_fleet.py"
    monkeypatch.syspath_prepend(str(path.parent))  # its helpers, as `python benchmarks/..`
    spec = importlib.util.spec_from_file_location("bench_fleet", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    table = bench.main(["--tiny", "--missions", "2"])
    assert table.shape == (2, 2 + len(bench.POLICIES))
    assert np.all(table[:, 1:-1] <= table[:, [-1]] + 1e-6)  # every policy under the bound
    assert "coordinated - independent hgad" in capsys.readouterr().out


def test_single_uav_entry_points_refuse_a_fleet_scenario() -> None:
    scenario = _two_uav_scenario()
    with pytest.raises(ScenarioError, match=r"has \[\[uavs\]\] \(several UAVs\)"):
        simulate(scenario, "hgad")
