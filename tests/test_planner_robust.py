"""Robust tour planner (planner-robust, issue 15): silent towers, noisy SNR, GPS error."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from conftest import preset_mission
from skymule.errors import ScenarioError
from skymule.metrics.flights import MissionLog
from skymule.policies import make_policy
from skymule.policies.base import Observation
from skymule.policies.planner import ground_speed_mps
from skymule.policies.planner_robust import RobustPlanner
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import PolicySpec, Scenario, load_scenario, scenario_from_dict
from skymule.sim.run import mission_context, run_mission
from skymule.world import Mission, build_mission
from test_autonomous_bound import random_scenario
from test_fault_engines import MIXED_FAULTS, _true_yield_holds

PRESET = "paper-sim-autonomous"


def _with(faults: list[dict[str, Any]] | None = None, **mission: Any) -> Scenario:
    base = load_scenario(PRESET)
    data = base.to_toml_dict()
    data["mission"].update(mission)
    if faults:
        data["faults"] = faults
    return scenario_from_dict(data, PRESET, Path(base.base_dir))


def _run(mission: Mission, name: str, **params: Any) -> MissionLog:
    return run_mission(mission, make_policy(PolicySpec(name=name, params=params)))


def _dead_runs(log: MissionLog, sensor: int) -> list[int]:
    """Lengths of the runs of slots in which ``sensor`` was chosen and nothing delivered."""
    assert log.chosen is not None
    dead = (log.chosen == sensor) & (log.served == NO_SENSOR)
    runs, run = [], 0
    for flag in [*dead, False]:
        if flag:
            run += 1
        elif run:
            runs.append(run)
            run = 0
    return runs


def _same(a: MissionLog, b: MissionLog) -> None:
    for field in ("served", "downloaded_bit", "position_m", "remaining_bit"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))


def test_without_faults_smoothing_and_tolerance_it_is_the_planner() -> None:
    rng = np.random.default_rng(7)
    scenarios = [load_scenario(PRESET), *(random_scenario(rng) for _ in range(3))]
    for scenario in scenarios:
        mission = build_mission(scenario)
        plain = _run(mission, "planner")
        _same(plain, _run(mission, "planner-robust", window_slots=1, arrive_m=0.0))
        # the model predicts the fault-free SNR exactly: the smoothed offset is 0, no change
        _same(plain, _run(mission, "planner-robust", arrive_m=0.0))
        # arrive_m starts a hover up to a slot early: within 1 % of the planner
        robust = _run(mission, "planner-robust")
        assert robust.downloaded_bit.sum() >= 0.99 * plain.downloaded_bit.sum()


@pytest.mark.parametrize("fail_slots", [2, 3])
def test_a_tower_silent_all_mission_is_left_after_fail_slots(fail_slots: int) -> None:
    """LW4 (the largest buffer, the planner's first target) is out for the whole mission.

    The plain planner flies there and serves it for every slot its plan allotted, getting
    nothing; the robust one serves it exactly ``fail_slots`` slots per visit, marks it down
    and re-plans (it tries again after each back-off: 60 s, then 120 s, ...). In 400 s the
    wasted hover costs the plain planner data the robust one collects elsewhere.
    """
    outage = {"kind": "outage", "params": {"sensors": ["LW4"], "start_s": 0, "duration_s": 1e4}}
    mission = build_mission(_with([outage], duration_s=400))
    lw4 = mission.sensor_names.index("LW4")
    plain = _run(mission, "planner")
    robust = _run(mission, "planner-robust", fail_slots=fail_slots)
    assert plain.downloaded_bit.sum() > 0 and not plain.downloaded_bit[plain.served == lw4].any()
    assert max(_dead_runs(plain, lw4)) > 10 * fail_slots
    runs = _dead_runs(robust, lw4)
    assert runs and all(run == fail_slots for run in runs)
    assert robust.downloaded_bit.sum() > plain.downloaded_bit.sum()


def test_a_silent_tower_that_comes_back_is_served_again() -> None:
    """An outage of LW4 from 0 to 60 s: marked down, then back once it reports again."""
    outage = {"kind": "outage", "params": {"sensors": ["LW4"], "start_s": 0, "duration_s": 60}}
    mission = build_mission(_with([outage]))
    robust = _run(mission, "planner-robust")
    lw4 = mission.sensor_names.index("LW4")
    assert robust.remaining_bit[-1, lw4] == 0.0  # its whole buffer, after the outage
    assert max(_dead_runs(robust, lw4), default=0) <= 3


def test_the_smoothed_estimate_follows_the_mean_offset_and_drops_silent_sensors() -> None:
    """Hand-worked: at home, sensor j's seen SNR is prediction + 6, - 6 dB in two slots.

    With ``window_slots = 2`` the mean offset in the second slot is 0, so the rate the
    robust planner goes by is the predicted one (the plain planner's is the observed, 6 dB
    low); a sensor that reports nothing now is rate 0 whatever its past.
    """
    mission = preset_mission(PRESET)
    context = mission_context(mission)
    assert context.predict_snr_db is not None and context.rate_of_snr_bps is not None
    here = np.array([0.0, 0.0, mission.altitude_m])
    predicted = context.predict_snr_db(here[None])[0]
    policy = RobustPlanner(window_slots=2)
    policy.reset(context)

    def observe(slot: int, error_db: np.ndarray) -> Observation:
        snr = predicted + error_db
        rate = context.rate_of_snr_bps(snr)
        return Observation(slot, here, snr, rate, mission.buffers_bit)

    # a sensor whose rate drops with 6 dB less SNR (LW1, 14 m from home, is at the top rate)
    j = int(
        np.flatnonzero(
            context.rate_of_snr_bps(predicted - 6.0) < context.rate_of_snr_bps(predicted)
        )[0]
    )
    noise = np.zeros(len(predicted))
    noise[j] = 6.0
    policy.act(observe(0, noise))
    second = observe(1, -noise)
    policy.act(second)
    seen = policy._seen_rate_bps(second)
    expected = context.rate_of_snr_bps(predicted)
    np.testing.assert_allclose(seen, expected)
    assert second.rate_bps[j] < expected[j]  # what the plain planner would go by
    silent = noise.copy()
    silent[j] = -np.inf  # it reports nothing in the third slot
    third = observe(2, silent)
    policy.act(third)
    assert policy._seen_rate_bps(third)[j] == 0.0


def test_robust_planner_hovers_despite_gps_error() -> None:
    gps = {"kind": "gps-error", "params": {"std_m": 5.0}}
    mission = build_mission(_with([gps], duration_s=300))
    plain, robust = _run(mission, "planner"), _run(mission, "planner-robust")
    # the reported position never equals a hover point: the plain planner never arrives
    assert robust.downloaded_bit.sum() > 1.02 * plain.downloaded_bit.sum()


def test_robust_planner_parameters_are_validated() -> None:
    data = load_scenario(PRESET).to_toml_dict()
    for bad in ({"fail_slots": 0}, {"backoff_s": 0.0}, {"window_slots": 0}, {"arrive_m": -1.0}):
        data["policy"] = {"name": "planner-robust", "params": bad}
        with pytest.raises(ScenarioError, match=next(iter(bad))):
            scenario_from_dict(data, "x", Path("."))
    data["policy"] = {"name": "planner-robust", "params": {"fail_slots": 2, "backoff_s": 30.0}}
    policy = make_policy(scenario_from_dict(data, "x", Path(".")).policy)
    assert isinstance(policy, RobustPlanner)
    assert (policy.fail_slots, policy.backoff_s, policy.window_slots) == (2, 30.0, 5)


def test_ground_speed_follows_the_wind_triangle() -> None:
    """docs/faults.md: a 5 m/s headwind halves 10 m/s, 6 m/s across leaves 8, a tailwind
    never speeds the UAV up."""
    east = np.array([[1.0, 0.0]])
    for wind, expected in (((-5.0, 0.0), 5.0), ((0.0, 6.0), 8.0), ((6.0, 0.0), 10.0)):
        speed = ground_speed_mps(east, np.array(wind), 10.0)
        np.testing.assert_allclose(speed, [expected])


@pytest.mark.parametrize(("from_deg", "wind"), [(0.0, (0.0, -6.0)), (225.0, (4.2426, 4.2426))])
def test_the_wind_is_estimated_from_slowed_steps_and_the_uav_gets_home(
    from_deg: float, wind: tuple[float, float]
) -> None:
    """A steady 6 m/s wind the policy is not told about: the robust planner infers it from its
    own slowed steps. Both end at home: the engine times the way home at the ground speed the
    wind allows and overrides a plan that would miss it (docs/faults.md), the plain planner's
    tour included."""
    faults = [{"kind": "wind", "params": {"speed_mps": 6.0, "from_deg": from_deg}}]
    mission = build_mission(_with(faults))
    plain = _run(mission, "planner")
    policy = make_policy(PolicySpec(name="planner-robust", params={}))
    robust = run_mission(mission, policy)
    assert isinstance(policy, RobustPlanner) and policy._wind_mps is not None
    np.testing.assert_allclose(policy._wind_mps, wind, atol=1e-3)
    assert np.hypot(*(plain.end_position_m[:2] - plain.home_m)) < 1e-6
    assert np.hypot(*(robust.end_position_m[:2] - robust.home_m)) < 1e-6


def test_robust_planner_runs_under_every_fault_at_once() -> None:
    faults = [
        *MIXED_FAULTS,
        {"kind": "gps-error", "params": {"std_m": 30.0, "correlation_s": 5.0}},
        {"kind": "wind", "params": {"speed_mps": 4.0, "from_deg": 90.0}},
    ]
    mission = build_mission(_with(faults))
    policy = make_policy(PolicySpec(name="planner-robust", params={}))
    log = run_mission(mission, policy)
    _true_yield_holds(log)
    steps = np.diff(np.vstack([log.position_m, log.end_position_m[None]])[:, :2], axis=0)
    assert np.all(np.hypot(*steps.T) <= mission.max_step_m + 1e-9)
    # a 30 m position error: no reported step is parallel to the commanded one, no estimate
    assert isinstance(policy, RobustPlanner) and policy._wind_mps is None
