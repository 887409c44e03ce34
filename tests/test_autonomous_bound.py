"""The autonomous upper bound (skymule.bounds_autonomous): validity, tightness, errors."""

from __future__ import annotations

import numpy as np
import pytest

from skymule.bounds_autonomous import autonomous_bound, best_rate_bps, reach_radii_m
from skymule.engine import run_mission
from skymule.errors import SkymuleError
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.policies.greedy import Greedy
from skymule.policies.hgad import HGAD
from skymule.policies.planner import Planner
from skymule.scenario import load_scenario
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
REL = 1e-9


def random_scenario(rng: np.random.Generator, base=None, *, n_sensors: int | None = None):
    """A random, flyable autonomous scenario around the Lake Wheeler fence (seeded by ``rng``)."""
    ranges = LayoutRanges(
        n_sensors=(n_sensors, n_sensors) if n_sensors else (2, 6),
        buffer_mbit=(0.0, 1500.0),
        duration_s=(160, 419),
        max_speed_mps=(5.0, 15.0),
        return_home_probability=0.8,
        draw_seed=True,
    )
    return random_autonomous_scenario(rng, base or load_scenario(PRESET), ranges)


def test_reach_radii_with_and_without_return_home():
    out_and_back = reach_radii_m(5, 10.0, True)
    assert np.allclose(out_and_back, [0, 10, 20, 20, 10], atol=1e-2)
    assert np.allclose(reach_radii_m(5, 10.0, False), [0, 10, 20, 30, 40], atol=1e-2)


def test_bound_on_the_preset_and_harder_variants():
    scenario = load_scenario(PRESET)
    result = autonomous_bound(build_mission(scenario))
    assert result.upper_bound_bit == pytest.approx(3000e6)  # everything fits in 500 s
    assert result.served_time_s.shape == (0, 4) and result.dwell_time_s.shape == (0,)
    assert result.last_sample == -1 and "exact reach sets" in result.method
    short = scenario.model_copy(
        update={"mission": scenario.mission.model_copy(update={"duration_s": 300.0})}
    )
    mission = build_mission(short)
    bound = autonomous_bound(mission).upper_bound_bit
    assert bound < 3000e6
    for policy in (Greedy(), HGAD(), Planner()):
        assert run_mission(mission, policy).downloaded_bit.sum() <= bound * (1 + REL)


def test_bound_is_tight_for_a_sensor_under_home():
    """A sensor right below home: the UAV can serve it every slot from home (optimum)."""
    scenario = load_scenario(PRESET)
    sensor = scenario.sensors[0].model_copy(
        update={"lat": None, "lon": None, "x_m": 0.0, "y_m": 0.0, "buffer_mbit": 1e5}
    )
    one = scenario.model_copy(update={"sensors": [sensor]})
    mission = build_mission(one)
    bound = autonomous_bound(mission).upper_bound_bit
    got = run_mission(mission, Planner()).downloaded_bit.sum()
    assert got == pytest.approx(bound, rel=1e-9)


def test_no_policy_beats_the_bound_on_random_missions():
    rng = np.random.default_rng(2024)
    for case in range(7):
        scenario = random_scenario(rng)
        if case % 3 == 2:  # per-slot fading: the bound adds it slot by slot
            scenario = scenario.model_copy(
                update={"radio": scenario.radio.model_copy(update={"fading": "rician"})}
            )
        mission = build_mission(scenario)
        bound = autonomous_bound(mission).upper_bound_bit
        assert bound <= mission.buffers_bit.sum() * (1 + REL)
        for policy in (Greedy(), HGAD(), Planner()):
            got = run_mission(mission, policy).downloaded_bit.sum()
            assert got <= bound * (1 + REL) + 1.0, (case, policy.name, got, bound)


def test_best_rate_dominates_what_the_uav_sees():
    """Per slot, no policy observes a rate above the bound's best rate for that slot."""
    rng = np.random.default_rng(5)
    mission = build_mission(random_scenario(rng, n_sensors=4))
    best, _ = best_rate_bps(mission)
    for policy in (Greedy(), HGAD(), Planner()):
        log = run_mission(mission, policy)
        assert (log.rate_bps <= best + 1e-6).all()


def test_shadowing_uses_the_grid_method():
    scenario = load_scenario(PRESET)
    shadowed = scenario.model_copy(
        update={"radio": scenario.radio.model_copy(update={"shadowing_std_db": 4.0})}
    )
    mission = build_mission(shadowed)
    result = autonomous_bound(mission)
    assert "grid" in result.method and "dB margin" in result.method
    assert run_mission(mission, HGAD()).downloaded_bit.sum() <= result.upper_bound_bit


def test_fixed_mission_is_refused_with_one_line():
    mission = build_mission(load_scenario("paper-sim-fixed"))
    with pytest.raises(SkymuleError) as info:
        autonomous_bound(mission)
    assert "trajectory.mode" in str(info.value) and "\n" not in str(info.value)
