"""Faults applied by the engines (docs/faults.md, "How the engines apply them"), hand-worked."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from shapely.geometry import Point

from conftest import preset_mission
from engine_cases import TWIN_RTOL, assert_summaries_equal
from skymule.errors import SkymuleError
from skymule.faults import no_faults
from skymule.io.runs import slots_frame
from skymule.metrics.flights import MissionLog
from skymule.metrics.summary import summarize
from skymule.policies import batch_policy
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import PolicySpec, Scenario, load_scenario, scenario_from_dict
from skymule.sim import compiled
from skymule.sim.autonomous import AutonomousEngine
from skymule.sim.fixed import FixedEngine
from skymule.sim.fleet import build_fleet
from skymule.sim.run import run_mission, run_missions, summarize_missions
from skymule.tasks.fleet import make_fleet_policy, run_fleet
from skymule.world import Mission, build_mission

PRESETS = ("paper-sim-fixed", "paper-sim-autonomous")


def _with_faults(preset: str, faults: list[dict[str, Any]], **update: Any) -> Scenario:
    base = load_scenario(preset)
    data = base.to_toml_dict()
    data["faults"] = faults
    data.update(update)
    return scenario_from_dict(data, preset, Path(base.base_dir))


def _run(mission: Mission, policy: str | None = None, engine: str = "auto") -> MissionLog:
    spec = mission.scenario.policy if policy is None else PolicySpec(name=policy)
    return run_mission(mission, batch_policy([spec]), engine)


def _batch(missions: list[Mission], policy: str, engine: str = "auto") -> tuple[MissionLog, ...]:
    return run_missions(missions, batch_policy([PolicySpec(name=policy)] * len(missions)),
                        engine=engine).missions()  # fmt: skip


def _same_log(a: MissionLog, b: MissionLog) -> None:
    for name in ("served", "downloaded_bit", "remaining_bit", "position_m", "hovering"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def _same_faults(a: MissionLog, b: MissionLog) -> None:
    for name in ("affected", "chosen"):
        ours, theirs = getattr(a, name), getattr(b, name)
        assert (ours is None) == (theirs is None), name
        if ours is not None:
            assert np.array_equal(ours, theirs), name


@pytest.mark.parametrize("preset", PRESETS)
def test_fault_free_mission_takes_the_fault_free_path(preset: str) -> None:
    mission = preset_mission(preset)
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
    clean = _run(preset_mission(preset), "greedy")
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
    clean = preset_mission("paper-sim-fixed")
    assert mission.track is not None and clean.track is not None
    assert np.array_equal(mission.track.position_m, clean.track.position_m)  # log: true path


def test_gps_error_moves_what_the_policy_sees_not_the_uav() -> None:
    gps = {"kind": "gps-error", "params": {"bias_m": [30.0, -40.0]}}
    mission = build_mission(_with_faults("paper-sim-fixed", [gps]))
    seen = FixedEngine([mission]).observe().position_m[0]
    assert mission.track is not None
    assert np.allclose(seen - mission.track.position_m[0], [30.0, -40.0, 0.0])


def test_headwind_slows_an_autonomous_uav_and_a_fixed_one_falls_behind() -> None:
    wind = [{"kind": "wind", "params": {"speed_mps": 5.0, "from_deg": 0.0}}]
    for preset in PRESETS:
        calm = _run(preset_mission(preset), "greedy")
        windy = _run(build_mission(_with_faults(preset, wind)), "greedy")
        steps = np.diff(np.vstack([windy.position_m, windy.end_position_m[None]])[:, :2], axis=0)
        limit = preset_mission(preset).max_step_m
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
    flight = AutonomousEngine([mission])
    policy = batch_policy([mission.scenario.policy])
    policy.reset(flight.contexts())
    while not flight.done:
        flight.step(policy.act(flight.observe()))
    log = flight.record(["hgad"]).mission(0)
    assert mission.home_m is not None
    clean = _run(preset_mission("paper-sim-autonomous"))
    # a 15 Wh pack (12 Wh usable) cannot fly the whole mission: it comes home early
    battery_ = mission.faults.battery
    one_slot = float(battery_.slot_energy_j(mission.max_speed_mps, mission.slot_s))
    assert flight.landed[0] and flight.used_j[0] <= battery_.usable_j + one_slot
    assert np.hypot(*(log.end_position_m[:2] - mission.home_m)) < 1.0
    assert log.downloaded_bit.sum() < clean.downloaded_bit.sum()


def test_a_landed_uav_is_not_served() -> None:
    # a 1-Wh pack sends Greedy home within seconds; on the ground nothing more comes down
    # (the AADM controller stops at disarm), where it used to "download" for the rest
    battery = [{"kind": "battery", "params": {"capacity_wh": 1.0}}]
    mission = build_mission(_with_faults("paper-sim-autonomous", battery))
    flight = AutonomousEngine([mission])
    policy = batch_policy([PolicySpec(name="greedy")])
    policy.reset(flight.contexts())
    landed_at = None
    bits: list[float] = []
    while not flight.done:
        bits.append(float(flight.step(policy.act(flight.observe()))[0]))
        if landed_at is None and flight.landed[0]:
            landed_at = len(bits)
    assert landed_at is not None and 0 < landed_at < 60
    assert sum(bits[:landed_at]) > 0 and not any(bits[landed_at:])
    assert len(bits) == mission.n_slots


MIXED_FAULTS = [
    {"kind": "outage", "params": {"sensors": ["LW1"], "start_s": 40, "duration_s": 80}},
    {"kind": "gilbert-elliott", "params": {"p_good_to_bad": 0.05, "p_bad_to_good": 0.3}},
    {"kind": "snr-error", "params": {"bias_db": -1.0, "std_db": 4.0, "correlation_s": 3.0}},
    {"kind": "missed-polls", "params": {"probability": 0.05}},
]


@pytest.mark.parametrize("engine", ["numpy", "compiled"])
def test_fault_missions_in_a_batch_equal_each_alone(engine: str) -> None:
    """Three seeds' draws and a fault-free mission in one batch, three mission lengths (draws
    padded to the longest): each column is its mission run alone, choices included."""
    if engine == "compiled" and not compiled.available():
        pytest.skip("numba not installed")
    mission_spec = load_scenario("paper-sim-fixed").to_toml_dict()["mission"]
    faulty = [
        build_mission(
            _with_faults(
                "paper-sim-fixed",
                MIXED_FAULTS,
                seed=seed,
                mission={**mission_spec, "duration_s": duration},
            )
        )
        for seed, duration in ((1, 500.0), (2, 120.0), (3, 37.0))
    ]
    missions = [*faulty, preset_mission("paper-sim-fixed")]
    for name in ("greedy", "hgad"):
        batched = _batch(missions, name, engine)
        for mission, log in zip(missions, batched, strict=True):
            alone = _run(mission, name, "numpy")
            _same_log(log, alone)
            _same_faults(log, alone)
        assert not np.array_equal(batched[0].served, batched[3].served)


@pytest.mark.parametrize("fault", MIXED_FAULTS, ids=lambda fault: fault["kind"])
def test_compiled_loop_equals_numpy_loop_under_each_fault(fault: dict[str, Any]) -> None:
    """Record for record (the policy's choices too) and summary for summary, Greedy and HGAD
    (the plain-Python loop always, the compiled one where numba is installed)."""
    from test_compiled import assert_loops_equal_numpy

    missions = [build_mission(_with_faults("paper-sim-fixed", [fault], seed=s)) for s in (4, 5)]
    missions.append(preset_mission("paper-sim-fixed"))
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad"), PolicySpec(name="hgad")]
    assert_loops_equal_numpy(missions, specs)
    logs = run_missions(missions, batch_policy(specs), engine="numpy").missions()
    # the fault acts: HGAD with it downloads otherwise than HGAD without (the last mission)
    assert not np.array_equal(logs[1].downloaded_bit, logs[2].downloaded_bit)
    if compiled.available():
        names = ["x"] * len(missions)
        summary = summarize_missions(missions, specs, names, engine="compiled")
        want = summarize_missions(missions, specs, names, engine="numpy")
        assert_summaries_equal(summary, want, TWIN_RTOL)


def test_gps_error_does_not_act_on_a_fixed_path() -> None:
    """It does not move the track (docs/faults.md): Greedy and HGAD fly as without it."""
    faults = [{"kind": "gps-error", "params": {"std_m": 20.0}}]
    mission = build_mission(_with_faults("paper-sim-fixed", faults))
    clean = preset_mission("paper-sim-fixed")
    for name in ("greedy", "hgad"):
        log, plain = _run(mission, name), _run(clean, name)
        for field in ("served", "downloaded_bit", "hovering", "position_m"):
            assert np.array_equal(getattr(log, field), getattr(plain, field)), field
        assert log.affected is not None and log.affected.all()  # the GPS error, every slot


def test_compiled_refuses_an_snr_error_on_a_shannon_table_and_a_wind() -> None:
    noise = [{"kind": "snr-error", "params": {"std_db": 3.0}}]
    radio = {**load_scenario("paper-sim-fixed").to_toml_dict()["radio"], "rate_table": "shannon"}
    shannon = build_mission(_with_faults("paper-sim-fixed", noise, radio=radio))
    wind = [{"kind": "wind", "params": {"speed_mps": 4.0}}]
    windy = build_mission(_with_faults("paper-sim-fixed", wind))
    why = ("SNR error on a rate table other than a step table", "a wind fault")
    for mission, reason in zip((shannon, windy), why, strict=True):
        if compiled.available():
            with pytest.raises(SkymuleError, match=reason):
                _run(mission, "hgad", "compiled")
        assert _run(mission, "hgad").chosen is not None  # auto: the numpy loop runs it


def test_slots_csv_marks_the_faulty_slots() -> None:
    outage = {"kind": "outage", "params": {"sensors": ["LW3"], "start_s": 10, "duration_s": 5}}
    mission = build_mission(_with_faults("paper-sim-fixed", [outage]))
    frame = slots_frame(_run(mission), mission.frame)
    assert frame["fault"].tolist()[8:17] == [0, 0, 1, 1, 1, 1, 1, 0, 0]
    clean = preset_mission("paper-sim-fixed")
    assert "fault" not in slots_frame(_run(clean), clean.frame).columns


def test_fleet_applies_faults_through_its_flights() -> None:
    outage = {"kind": "outage", "params": {"sensors": ["LW2"], "start_s": 0, "duration_s": 1e4}}
    scenario = _with_faults("paper-sim-autonomous", [outage], uavs=[{"name": "A"}, {"name": "B"}])
    fleet = build_fleet(scenario)
    assert all(m.faults is not None for m in fleet.missions)
    log = run_fleet(fleet, make_fleet_policy(fleet))
    for uav in log.missions():
        assert not (uav.served == 1).any()
        assert uav.affected is not None and uav.affected.all()
    assert log.mission(0).remaining_bit[-1, 1] == fleet.missions[0].buffers_bit[1]


def test_a_sweep_draws_each_missions_faults_from_its_seed(tmp_path: Path) -> None:
    import pandas as pd

    import skymule
    from conftest import run_cli
    from skymule.tasks.simulate import simulate

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
