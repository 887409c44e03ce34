"""Faults applied by the engines (docs/faults.md, "How the engines apply them"), hand-worked."""

from __future__ import annotations

from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from shapely.geometry import Point

from skymule.errors import SkymuleError
from skymule.faults import no_faults
from skymule.fleet_runner import make_fleet_policy, run_fleet
from skymule.io.runs import slots_frame
from skymule.metrics import summarize
from skymule.policies import make_policy
from skymule.scenario import PolicySpec, Scenario, load_scenario, scenario_from_dict
from skymule.sim import compiled
from skymule.sim.autonomous import AutonomousFlight
from skymule.sim.batch import (
    BatchResult,
    batchable,
    run_batch,
    run_fixed_batch,
    stack_missions,
    summarize_fixed_batch,
)
from skymule.sim.context import mission_context
from skymule.sim.contract import NO_SENSOR
from skymule.sim.engine import FixedFlight
from skymule.sim.fleet import build_fleet
from skymule.flights import MissionLog
from skymule.sim.run import run_mission
from skymule.world import Mission, build_mission

PRESETS = ("paper-sim-fixed", "paper-sim-autonomous")


def _with_faults(preset: str, faults: list[dict[str, Any]], **update: Any) -> Scenario:
    base = load_scenario(preset)
    data = base.to_toml_dict()
    data["faults"] = faults
    data.update(update)
    return scenario_from_dict(data, preset, Path(base.base_dir))


def _run(mission: Mission, policy: str | None = None) -> MissionLog:
    spec = mission.scenario.policy if policy is None else PolicySpec(name=policy)
    return run_mission(mission, make_policy(spec))


def _same_log(a: MissionLog, b: MissionLog) -> None:
    for name in ("served", "downloaded_bit", "remaining_bit", "position_m", "hovering"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


@pytest.mark.parametrize("preset", PRESETS)
def test_fault_free_mission_takes_the_fault_free_path(preset: str) -> None:
    mission = build_mission(load_scenario(preset))
    assert mission.faults is None
    log = _run(mission)
    assert log.affected is None and log.chosen is None
    # the fault path with nothing faulty gives today's numbers value for value
    clean = replace(mission, faults=no_faults(mission.n_slots, mission.n_sensors))
    faulty_path = _run(clean)
    _same_log(log, faulty_path)
    assert summarize(log, preset) == summarize(faulty_path, preset)
    assert not faulty_path.affected.any()  # type: ignore[union-attr]
    assert np.array_equal(faulty_path.chosen, log.served)  # type: ignore[arg-type]


def test_fault_free_reference_equals_the_batched_engine_on_the_fixed_preset() -> None:
    mission = build_mission(load_scenario("paper-sim-fixed"))
    for name in ("greedy", "hgad"):
        spec = PolicySpec(name=name)
        _same_log(_run(mission, name), run_fixed_batch([mission], [spec], engine="numpy")[0])


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("policy", ["greedy", "hgad"])
def test_an_outage_window_serves_nothing_from_that_tower(preset: str, policy: str) -> None:
    outage = {"kind": "outage", "params": {"sensors": ["LW2"], "start_s": 100, "duration_s": 60}}
    mission = build_mission(_with_faults(preset, [outage]))
    log = _run(mission, policy)
    window = slice(100, 160)
    assert not (log.served[window] == 1).any()
    # LW2's buffer does not move while it is down: nothing is taken from it
    assert np.all(log.remaining_bit[window, 1] == log.remaining_bit[99, 1])
    # a slot in which the policy chose LW2 downloaded nothing and is logged as serving nothing
    chose_dead = log.chosen[window] == 1  # type: ignore[index]
    assert np.all(log.downloaded_bit[window][chose_dead] == 0.0)
    assert log.affected is not None and log.affected[window].all()
    assert not log.affected[:100].any() and not log.affected[160:].any()
    # outside the window the tower serves as usual
    assert (log.served == 1).any()


def _true_yield_holds(log: MissionLog) -> None:
    """Every slot delivered min(true rate * dt, remaining) of the sensor it served."""
    before = np.vstack([log.buffers_bit, log.remaining_bit[:-1]])
    for t in np.flatnonzero(log.served != NO_SENSOR):
        i = log.served[t]
        expected = min(log.rate_bps[t, i] * log.slot_s, before[t, i])
        assert log.downloaded_bit[t] == pytest.approx(expected, rel=1e-12, abs=1e-9)
    assert np.all(log.downloaded_bit[log.served == NO_SENSOR] == 0.0)


@pytest.mark.parametrize("preset", PRESETS)
def test_snr_error_changes_choices_but_not_the_accounting(preset: str) -> None:
    noise = {"kind": "snr-error", "params": {"std_db": 6.0}}
    clean = _run(build_mission(load_scenario(preset)), "greedy")
    noisy = _run(build_mission(_with_faults(preset, [noise])), "greedy")
    assert not np.array_equal(noisy.served, clean.served)  # choices change
    _true_yield_holds(noisy)  # yields follow the true rate
    if preset == "paper-sim-fixed":  # the path is fixed: the true SNR logged is the same
        assert np.array_equal(noisy.snr_db, clean.snr_db)
        assert np.array_equal(noisy.rate_bps, clean.rate_bps)


def test_missed_polls_serve_nothing_and_the_position_error_is_only_seen() -> None:
    faults = [
        {"kind": "missed-polls", "params": {"probability": 0.3}},
        {"kind": "gps-error", "params": {"std_m": 20.0}},
    ]
    mission = build_mission(_with_faults("paper-sim-fixed", faults))
    assert mission.faults is not None
    log = _run(mission, "hgad")
    missed = mission.faults.poll_missed
    assert missed.any()
    assert np.all(log.served[missed] == NO_SENSOR) and np.all(log.downloaded_bit[missed] == 0)
    _true_yield_holds(log)
    clean = build_mission(load_scenario("paper-sim-fixed"))
    assert mission.track is not None and clean.track is not None
    assert np.array_equal(mission.track.position_m, clean.track.position_m)  # log: true path


def test_gps_error_moves_what_the_policy_sees_not_the_uav() -> None:
    gps = {"kind": "gps-error", "params": {"bias_m": [30.0, -40.0]}}
    mission = build_mission(_with_faults("paper-sim-fixed", [gps]))
    flight = FixedFlight(mission)
    seen = flight.observe().position_m
    assert mission.track is not None
    assert np.allclose(seen - mission.track.position_m[0], [30.0, -40.0, 0.0])


def test_headwind_slows_an_autonomous_uav_and_a_fixed_one_falls_behind() -> None:
    wind = [{"kind": "wind", "params": {"speed_mps": 5.0, "from_deg": 0.0}}]
    for preset in PRESETS:
        calm = _run(build_mission(load_scenario(preset)), "greedy")
        windy = _run(build_mission(_with_faults(preset, wind)), "greedy")
        steps = np.diff(np.vstack([windy.position_m, windy.end_position_m[None]])[:, :2], axis=0)
        limit = build_mission(load_scenario(preset)).max_step_m
        assert np.all(np.hypot(*steps.T) <= limit + 1e-9)
        # against the wind (flying north) no step is longer than a 5 m/s headwind allows
        north = steps[:, 1] > 1e-9
        if north.any() and preset == "paper-sim-autonomous":
            heading_north = np.abs(steps[north, 0]) < 1e-6
            assert np.all(steps[north][heading_north, 1] <= (limit - 5.0) + 1e-6)
        assert not np.array_equal(windy.position_m, calm.position_m)


def test_battery_limit_sends_the_uav_home_before_it_is_spent() -> None:
    battery = [{"kind": "battery", "params": {"capacity_wh": 15.0, "reserve_fraction": 0.2}}]
    mission = build_mission(_with_faults("paper-sim-autonomous", battery))
    assert mission.faults is not None and mission.faults.battery is not None
    flight = AutonomousFlight(mission)
    policy = make_policy(mission.scenario.policy)
    policy.reset(mission_context(mission))
    while not flight.done:
        flight.apply(policy.act(flight.observe()))
    log = flight.log("hgad")
    assert mission.home_m is not None
    clean = _run(build_mission(load_scenario("paper-sim-autonomous")))
    # a 15 Wh pack (12 Wh usable) cannot fly the whole mission: it comes home early
    battery_ = mission.faults.battery
    one_slot = float(battery_.slot_energy_j(mission.max_speed_mps, mission.slot_s))
    assert flight.landed and flight.used_j <= battery_.usable_j + one_slot
    assert np.hypot(*(log.end_position_m[:2] - mission.home_m)) < 1.0
    assert log.downloaded_bit.sum() < clean.downloaded_bit.sum()


MIXED_FAULTS = [
    {"kind": "outage", "params": {"sensors": ["LW1"], "start_s": 40, "duration_s": 80}},
    {"kind": "gilbert-elliott", "params": {"p_good_to_bad": 0.05, "p_bad_to_good": 0.3}},
    {"kind": "snr-error", "params": {"bias_db": -1.0, "std_db": 4.0, "correlation_s": 3.0}},
    {"kind": "missed-polls", "params": {"probability": 0.05}},
]


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_the_batched_engine_applies_faults_as_the_reference_engine(engine: str) -> None:
    if engine == "compiled" and not compiled.available():
        pytest.skip("numba not installed")
    faulty = [
        build_mission(_with_faults("paper-sim-fixed", MIXED_FAULTS, seed=seed))
        for seed in (1, 2, 3)
    ]
    clean = build_mission(load_scenario("paper-sim-fixed"))  # mixed with a fault-free one
    missions = [*faulty, clean]
    for name in ("greedy", "hgad"):
        specs = [PolicySpec(name=name)] * len(missions)
        assert all(batchable(m, s) for m, s in zip(missions, specs, strict=True))
        batched = run_fixed_batch(missions, specs, engine=engine)  # type: ignore[arg-type]
        for mission, log in zip(missions, batched, strict=True):
            reference = _run(mission, name)
            _same_log(reference, log)
            for field in ("affected", "chosen"):
                ours, theirs = getattr(log, field), getattr(reference, field)
                assert (ours is None) == (theirs is None), field
                if ours is not None:
                    assert np.array_equal(ours, theirs), field
        assert not np.array_equal(batched[0].served, batched[3].served)


def test_fault_missions_of_other_lengths_batch_like_the_reference() -> None:
    """One batch, three mission lengths (draws padded to the longest), both engines."""
    mission_spec = load_scenario("paper-sim-fixed").to_toml_dict()["mission"]
    missions = [
        build_mission(
            _with_faults(
                "paper-sim-fixed",
                MIXED_FAULTS,
                seed=seed,
                mission={**mission_spec, "duration_s": s},
            )
        )
        for seed, s in ((1, 500.0), (2, 120.0), (3, 37.0))
    ]
    assert sorted(m.n_slots for m in missions) == [37, 120, 500]
    engines = ["numpy", "compiled"] if compiled.available() else ["numpy"]
    for name in ("greedy", "hgad"):
        reference = [_run(mission, name) for mission in missions]
        for engine in engines:
            logs = run_fixed_batch(missions, [PolicySpec(name=name)] * 3, engine=engine)  # type: ignore[arg-type]
            for ours, theirs in zip(logs, reference, strict=True):
                _same_log(ours, theirs)
                assert np.array_equal(ours.chosen, theirs.chosen)  # type: ignore[arg-type]


@pytest.mark.skipif(not compiled.available(), reason="numba not installed")
@pytest.mark.parametrize("fault", MIXED_FAULTS, ids=lambda fault: fault["kind"])
def test_compiled_batch_equals_numpy_batch_under_each_fault(fault: dict[str, Any]) -> None:
    """Array for array (the policy's choices too) and summary for summary, Greedy and HGAD."""
    missions = [build_mission(_with_faults("paper-sim-fixed", [fault], seed=s)) for s in (4, 5)]
    missions.append(build_mission(load_scenario("paper-sim-fixed")))
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad"), PolicySpec(name="hgad")]
    batch = stack_missions(missions, specs)
    ours, theirs = run_batch(batch, "compiled"), run_batch(batch, "numpy")
    for field in fields(BatchResult):
        np.testing.assert_array_equal(getattr(ours, field.name), getattr(theirs, field.name))
    # the fault acts: HGAD with it downloads otherwise than HGAD without (the last mission)
    assert not np.array_equal(ours.downloaded_bit[1], ours.downloaded_bit[2])
    names = ["x"] * len(missions)
    summary = summarize_fixed_batch(missions, specs, names, engine="compiled")
    assert summary == summarize_fixed_batch(missions, specs, names, engine="numpy")


@pytest.mark.skipif(not compiled.available(), reason="numba not installed")
def test_gps_error_and_battery_leave_a_fixed_batch_as_the_reference_does() -> None:
    """Neither acts on a fixed path (docs/faults.md): both engines give the reference's log."""
    faults = [
        {"kind": "gps-error", "params": {"std_m": 20.0}},
        {"kind": "battery", "params": {"capacity_wh": 15.0, "reserve_fraction": 0.2}},
    ]
    mission = build_mission(_with_faults("paper-sim-fixed", faults))
    assert mission.faults is not None and mission.faults.battery is not None
    for name in ("greedy", "hgad"):
        reference = _run(mission, name)
        for engine in ("numpy", "compiled"):
            (log,) = run_fixed_batch([mission], [PolicySpec(name=name)], engine=engine)  # type: ignore[arg-type]
            _same_log(log, reference)
            assert np.array_equal(log.chosen, reference.chosen)  # type: ignore[arg-type]


def test_compiled_refuses_an_snr_error_on_a_shannon_table_and_a_wind_is_not_batched() -> None:
    noise = [{"kind": "snr-error", "params": {"std_db": 3.0}}]
    radio = {**load_scenario("paper-sim-fixed").to_toml_dict()["radio"], "rate_table": "shannon"}
    shannon = build_mission(_with_faults("paper-sim-fixed", noise, radio=radio))
    spec = PolicySpec(name="hgad")
    with pytest.raises(SkymuleError, match="SNR error on a rate table other than a step table"):
        run_fixed_batch([shannon], [spec], engine="compiled")
    assert run_fixed_batch([shannon], [spec])[0].chosen is not None  # auto: numpy
    wind = [{"kind": "wind", "params": {"speed_mps": 4.0}}]
    windy = build_mission(_with_faults("paper-sim-fixed", wind))
    assert not batchable(windy, spec)
    with pytest.raises(SkymuleError, match="wind"):
        run_fixed_batch([windy], [spec], engine="numpy")


def test_slots_csv_marks_the_faulty_slots() -> None:
    outage = {"kind": "outage", "params": {"sensors": ["LW3"], "start_s": 10, "duration_s": 5}}
    mission = build_mission(_with_faults("paper-sim-fixed", [outage]))
    frame = slots_frame(_run(mission), mission.frame)
    assert frame["fault"].tolist()[8:17] == [0, 0, 1, 1, 1, 1, 1, 0, 0]
    clean = build_mission(load_scenario("paper-sim-fixed"))
    assert "fault" not in slots_frame(_run(clean), clean.frame).columns


def test_fleet_applies_faults_through_its_flights() -> None:
    outage = {"kind": "outage", "params": {"sensors": ["LW2"], "start_s": 0, "duration_s": 1e4}}
    scenario = _with_faults("paper-sim-autonomous", [outage], uavs=[{"name": "A"}, {"name": "B"}])
    fleet = build_fleet(scenario)
    assert all(m.faults is not None for m in fleet.missions)
    log = run_fleet(fleet, make_fleet_policy(fleet))
    for uav in log.logs:
        assert not (uav.served == 1).any()
        assert uav.affected is not None and uav.affected.all()
    assert log.logs[0].remaining_bit[-1, 1] == fleet.missions[0].buffers_bit[1]


def test_a_sweep_draws_each_missions_faults_from_its_seed(tmp_path: Path) -> None:
    import pandas as pd

    import skymule
    from conftest import run_cli
    from skymule.runner import simulate

    preset = Path(skymule.__file__).parent / "scenarios" / "paper-sim-fixed.toml"
    text = preset.read_text(encoding="utf-8")
    text += '\n[[faults]]\nkind = "outage"\nparams = { mean_duration_s = 60.0 }\n'
    text += '\n[[faults]]\nkind = "snr-error"\nparams = { std_db = 6.0 }\n'
    (tmp_path / "scen.toml").write_text(text, encoding="utf-8")
    (tmp_path / "sweep.toml").write_text(
        'base = "scen.toml"\nseed = 1\nmode = "product"\n\n[axes]\n'
        'policy.name = ["greedy", "hgad"]\nseed = { range = [0, 3] }\n',
        encoding="utf-8",
    )
    result = run_cli("sweep", tmp_path / "sweep.toml", "--out", tmp_path / "out")
    assert result.returncode == 0, result.stderr
    rows = pd.read_parquet(tmp_path / "out" / "results.parquet")
    scenario = load_scenario(tmp_path / "scen.toml")
    for row in rows.itertuples():
        alone = simulate(scenario.model_copy(update={"seed": row.seed}), policy=row.policy)
        assert row.total_downloaded_mbit == alone.summary["total_downloaded_mbit"]


@pytest.mark.parametrize("policy", ["greedy", "hgad", "hgad-robust", "planner"])
def test_autonomous_policies_run_under_every_fault_at_once(policy: str) -> None:
    faults = [
        *MIXED_FAULTS,
        {"kind": "gps-error", "params": {"std_m": 30.0, "correlation_s": 5.0}},
        {"kind": "wind", "params": {"speed_mps": 4.0, "from_deg": 90.0}},
    ]
    mission = build_mission(_with_faults("paper-sim-autonomous", faults))
    log = _run(mission, policy)
    _true_yield_holds(log)
    steps = np.diff(np.vstack([log.position_m, log.end_position_m[None]])[:, :2], axis=0)
    assert np.all(np.hypot(*steps.T) <= mission.max_step_m + 1e-9)
    assert mission.fence is None or all(
        mission.fence.buffer(1e-6).covers(Point(x, y)) for x, y in log.position_m[:, :2]
    )
