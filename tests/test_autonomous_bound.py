"""The autonomous upper bound (skymule.bounds.autonomous): validity, tightness, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from conftest import preset_mission
from skymule.bounds.autonomous import (
    autonomous_bound,
    best_rate_bps,
    closest_distances_m,
    geodesic_closest_distances_m,
    reach_radii_m,
)
from skymule.errors import SkymuleError
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.policies import HGAD, Greedy
from skymule.policies.planner import Planner
from skymule.scenario import load_scenario
from skymule.sim.run import run_mission
from skymule.world import build_mission, with_fence

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
        assert bound <= autonomous_bound(mission, reach="euclidean").upper_bound_bit * (1 + REL)
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
    mission = preset_mission("paper-sim-fixed")
    with pytest.raises(SkymuleError) as info:
        autonomous_bound(mission)
    assert "trajectory.mode" in str(info.value) and "\n" not in str(info.value)


def test_geodesic_reach_is_never_looser_than_the_straight_line_disc():
    rng = np.random.default_rng(77)
    tighter = 0
    for _ in range(8):
        mission = build_mission(random_scenario(rng))
        geodesic, how = best_rate_bps(mission)
        euclidean, _ = best_rate_bps(mission, reach="euclidean")
        assert "geodesic reach" in how
        assert (geodesic <= euclidean).all()
        tighter += int((geodesic < euclidean).any())
        old = autonomous_bound(mission, reach="euclidean").upper_bound_bit
        assert autonomous_bound(mission).upper_bound_bit <= old * (1 + REL)
    assert tighter  # on the concave Lake Wheeler fence some per-slot rates do drop


def test_every_point_within_travel_distance_is_in_the_geodesic_reach_set():
    """Validity of the reach set itself: a fence point at in-fence travel distance d from home
    lies in G(d) (distance 0), for random homes and points on the Lake Wheeler fence."""
    rng = np.random.default_rng(11)
    geometry = preset_mission(PRESET)  # carries navigator, home, hover points
    nav = geometry.navigator
    x0, y0, x1, y1 = nav.fence.bounds

    def inside(count: int) -> np.ndarray:
        points: list[np.ndarray] = []
        while len(points) < count:
            p = rng.uniform([x0, y0], [x1, y1])
            if nav.fence.covers(Point(p)):
                points.append(p)
        return np.array(points)

    for home in inside(2):
        points = inside(40)
        travel = np.array([nav.travel_distance(tuple(home), tuple(p)) for p in points])
        own = np.diag(geodesic_closest_distances_m(nav, home, points, travel + 1e-9))
        assert own.max() <= 1e-6
        shy = np.diag(geodesic_closest_distances_m(nav, home, points, travel - 5.0))
        assert (shy > 0).all()  # and the set is not much larger than the geodesic ball


def _u_fence_mission(duration_s: float):
    """A U-shaped fence (300 x 200 m box with a 20 m wide notch from the top down to y = 40);
    home at the top of the left arm, the sensor 40 m east of it across the notch, at the
    top of the right arm (geodesic distance 2 * 150.33 + 20 = 320.67 m)."""
    base = load_scenario(PRESET)
    sensor = base.sensors[0].model_copy(
        update={
            "lat": None,
            "lon": None,
            "x_m": 170.0,
            "y_m": 190.0,
            "height_m": 0.0,
            "buffer_mbit": 1e6,
        }
    )
    scenario = base.model_copy(
        update={
            "sensors": [sensor],
            "site": base.site.model_copy(update={"geofence": None}),
            "mission": base.mission.model_copy(update={"duration_s": duration_s}),
            "radio": base.radio.model_copy(update={"rate_table": "shannon"}),
            "trajectory": base.trajectory.model_copy(
                update={"home": [130.0, 190.0], "max_speed_mps": 10.0, "return_home": True}
            ),
        }
    )
    fence = Polygon(
        [(0, 0), (300, 0), (300, 200), (160, 200), (160, 40), (140, 40), (140, 200), (0, 200)]
    )
    return with_fence(build_mission(scenario), fence)


def test_u_fence_geodesic_bound_is_tighter_and_matches_hand_computation():
    mission = _u_fence_mission(20.0)  # 20 slots of 1 s, 10 m per slot: radii 0, 10, ..., 100
    altitude = mission.scenario.trajectory.altitude_m
    sensor = mission.sensor_m[0]

    def rate(distance_m: float) -> float:  # rate at that horizontal distance from the sensor
        probe = np.array([[sensor[0] - distance_m, sensor[1], altitude]])
        return float(mission.rate_bps(mission.source.snr_db(probe))[0, 0])

    # radius of slot t: 10 min(t, 20 - t) m -> 0 once, 10..90 twice each, 100 once.
    # geodesic: the right arm is hidden from home and the notch's corners are 150 m away, so
    # the nearest reachable point is (130 + r, 190) until it meets the notch wall at r = 10:
    # distance 40 at r = 0, then 30 (the wall point (140, 190)).
    geodesic = rate(40.0) + 19 * rate(30.0)
    # straight line: the disc reaches the right arm across the notch at r = 30.
    euclidean = rate(40.0) + 4 * rate(30.0) + 2 * rate(10.0) + 13 * rate(0.0)
    new = autonomous_bound(mission).upper_bound_bit
    old = autonomous_bound(mission, reach="euclidean").upper_bound_bit
    assert new == pytest.approx(geodesic * mission.slot_s, rel=1e-4)
    assert old == pytest.approx(euclidean * mission.slot_s, rel=1e-4)
    assert new < old * 0.99


def test_u_fence_reach_around_the_notch():
    """Beyond the notch's corners the reach bends around them: from the far corner (160, 40),
    reached after 150.33 + 20 m, the sensor is 150.33 m away, so the distance is
    min(30, 320.67 - r) (30: the notch wall seen from home)."""
    mission = _u_fence_mission(20.0)
    geometry = mission
    around = 2 * math.hypot(10.0, 150.0) + 20.0
    radii = np.array([100.0, 250.0, 300.0, 310.0, around + 1.0])
    sensor = mission.sensor_m[:, :2]
    got = geodesic_closest_distances_m(geometry.navigator, geometry.home_m, sensor, radii)[:, 0]
    expected = np.array([30.0, 30.0, around - 300.0, around - 310.0, 0.0])
    assert got == pytest.approx(expected, abs=0.05)
    straight = closest_distances_m(geometry.navigator.fence, geometry.home_m, sensor, radii)[:, 0]
    assert straight == pytest.approx(0.0, abs=1e-9)  # the disc covers the sensor from r = 40
