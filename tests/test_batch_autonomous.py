"""The autonomous engine over a batch: every column is its own mission, under any policy.

A mission gives the same log alone (a batch of one) and inside a batch of other layouts,
policies, lengths, signal sources and fading; the batch's summaries are those of
``skymule run``; the batched navigator queries answer each row as if it were asked alone.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from conftest import preset_mission
from engine_cases import TWIN_RTOL, assert_logs_equal, assert_summaries_equal
from skymule.errors import SkymuleError
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.experiments.run import _flat_summary, run_chunk
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.flight.navigation import Navigator
from skymule.metrics.summary import summarize
from skymule.policies import batch_policy
from skymule.scenario import PolicySpec, load_scenario, scenario_from_dict
from skymule.sim.batch_signal import BatchSignal
from skymule.sim.run import run_mission, run_missions, summarize_missions
from skymule.tasks.simulate import simulate
from skymule.world import build_mission

PRESET = "paper-sim-autonomous"
# paper Table II: the four buffer cases [Mbit] of LW1..LW4 (benchmarks/bench_autonomous.py)
TABLE_II = [
    (700, 500, 800, 1000),
    (500, 800, 1000, 700),
    (800, 500, 700, 1000),
    (500, 1000, 700, 800),
]
U_FENCE = Polygon([(0, 0), (30, 0), (30, 30), (20, 30), (20, 10), (10, 10), (10, 30), (0, 30)])


def by_sensor_count(missions):
    groups: dict[int, list] = {}
    for mission in missions:
        groups.setdefault(mission.n_sensors, []).append(mission)
    return list(groups.values())


def assert_batch_equals_alone(missions, specs, engine: str = "numpy"):
    """One batch of ``missions`` (one sensor count, one fence) under ``specs`` equals each
    mission run alone, every log field; returns the batch's logs."""
    flights = run_missions(missions, batch_policy(specs), engine=engine)
    for b, (mission, spec) in enumerate(zip(missions, specs, strict=True)):
        assert_logs_equal(flights.mission(b), run_mission(mission, batch_policy([spec]), engine))
    return flights.missions()


@pytest.fixture(scope="module")
def preset():
    return load_scenario(PRESET)


@pytest.fixture(scope="module")
def layouts(preset):
    """Random layouts: 3..6 sensors, return home or not, some with fading, shadowing, another
    path-loss model, altitude or download window, some short enough that the return-home
    override binds."""
    rng = np.random.default_rng(7)
    ranges = LayoutRanges(return_home_probability=0.5, duration_s=(120, 300))
    scenarios = [random_autonomous_scenario(rng, preset, ranges) for _ in range(18)]
    changes = {
        2: {"fading": "rician"},
        5: {"fading": "rayleigh", "shadowing_std_db": 6.0},
        8: {"shadowing_std_db": 4.0},
        11: {"model": "two-ray"},
    }
    for k, change in changes.items():
        radio = scenarios[k].radio.model_copy(update=change)
        scenarios[k] = scenarios[k].model_copy(update={"radio": radio})
    higher = scenarios[13].trajectory.model_copy(update={"altitude_m": 60.0})
    scenarios[13] = scenarios[13].model_copy(update={"trajectory": higher})
    missions = [build_mission(s) for s in scenarios]
    missions[15] = replace(missions[15], aadm_window_s=60.0)
    return missions


def test_batch_peak_rates_equal_each_missions(layouts):
    """HGAD's R*_i of a whole batch, bit for bit those of each mission in a batch of one
    (fading, shadowing and two-ray layouts included): the rate at its own hover point."""
    for missions in by_sensor_count(layouts):
        hover = np.stack([np.asarray(m.hover_points_m, float) for m in missions], axis=1)
        hover[0, 0] = np.nan  # a sensor without a hover point: rate 0
        missions = [replace(missions[0], hover_points_m=hover[:, 0]), *missions[1:]]
        peak = BatchSignal(missions, missions[0].n_sensors).peak_rate_bps(hover)
        for b, mission in enumerate(missions):
            alone = BatchSignal([mission], mission.n_sensors).peak_rate_bps(hover[:, b : b + 1])
            np.testing.assert_array_equal(peak[:, b], alone[:, 0])
            at_hover = np.column_stack(
                [np.nan_to_num(hover[:, b]), np.full(mission.n_sensors, mission.altitude_m)]
            )
            own = np.diag(mission.rate_bps(mission.source.snr_db(at_hover)))  # by hand
            known = np.isfinite(hover[:, b, 0])
            np.testing.assert_array_equal(alone[known, 0], own[known])
        assert peak[0, 0] == 0.0 and peak[1:, 0].all()


def test_navigator_answers_each_row_as_if_alone(preset):
    """Shortest paths, travel distances and steps of many pairs at once, in two concave
    fences, are those of each pair asked alone (start on a vertex, start == goal and starts
    outside the fence included); paths stay in the fence and steps land on the path."""
    rng = np.random.default_rng(3)
    for navigator in (Navigator(U_FENCE), build_mission(preset).navigator):
        assert len(navigator.vertices) > 0  # concave: paths bend
        low_x, low_y, high_x, high_y = navigator.fence.bounds
        points = rng.uniform([low_x, low_y], [high_x, high_y], (500, 2))
        points = points[navigator.covers_goals(points)]
        starts, goals = points[: len(points) // 2], points[len(points) // 2 :][: len(points) // 2]
        starts[:2] = navigator.vertices[:2]
        starts[4:6] += [(high_x - low_x) * 0.2, 0.0]  # some land outside: the way in first
        goals[2:4] = starts[2:4]
        steps = rng.uniform(0.0, 0.3 * (high_x - low_x), len(starts))
        distances = navigator.travel_distances(starts, goals)
        moved = navigator.steps(starts, goals, steps)
        paths, count = navigator.shortest_paths(starts, goals)
        cover = navigator.fence.buffer(1e-5)
        for p, (a, b) in enumerate(zip(map(tuple, starts), map(tuple, goals), strict=True)):
            assert paths[p, : count[p]].tolist() == [list(x) for x in navigator.shortest_path(a, b)]
            assert distances[p] == navigator.travel_distance(a, b)
            assert tuple(moved[p]) == navigator.step(a, b, steps[p])
            assert distances[p] >= math.dist(a, b) - 1e-9
            inner = paths[p, 1 : count[p]] if not cover.covers(shapely.Point(a)) else paths[p]
            assert cover.covers(shapely.linestrings(inner[: max(count[p] - 1, 2)]))
        assert not np.all(count == 2)  # some paths bend at reflex vertices
        reached = navigator.steps(starts, goals, distances + 1e-9)
        np.testing.assert_allclose(reached, goals, atol=1e-9)


def test_navigator_rejects_goals_outside_the_fence():
    navigator = Navigator(U_FENCE)
    with pytest.raises(ValueError, match="outside the fence"):
        navigator.travel_distances(np.array([[5.0, 5.0]]), np.array([[15.0, 25.0]]))


def test_a_start_outside_the_fence_flies_straight_in_first():
    """From (25, 35), 5 m above the U's right arm: straight down to the nearest fence point
    (25, 30), then straight on inside the arm to the goal (hand-worked: 30 m)."""
    navigator = Navigator(U_FENCE)
    path = navigator.shortest_path((25.0, 35.0), (25.0, 5.0))
    assert path[0] == (25.0, 35.0) and path[1] == pytest.approx((25.0, 30.0))
    assert navigator.travel_distance((25.0, 35.0), (25.0, 5.0)) == pytest.approx(30.0)


def test_preset_and_table_ii_cases_batch_like_alone(preset):
    cases = [build_mission(preset)]
    for buffers in TABLE_II:
        sensors = [
            sensor.model_copy(update={"buffer_mbit": float(b)})
            for sensor, b in zip(preset.sensors, buffers, strict=True)
        ]
        cases.append(build_mission(preset.model_copy(update={"sensors": sensors})))
    specs = [
        PolicySpec(name="greedy"),
        PolicySpec(name="hgad", max_hover_s=7.0),
        PolicySpec(name="hgad"),
        PolicySpec(name="hgad-robust"),
        PolicySpec(name="greedy"),
    ]
    assert_batch_equals_alone(cases, specs)


def test_random_layouts_batch_like_alone(layouts):
    assert len({m.n_sensors for m in layouts}) > 1
    assert {m.return_home for m in layouts} == {True, False}
    assert any(m.fading_db is not None for m in layouts)
    for missions in by_sensor_count(layouts):
        for name in ("greedy", "hgad"):
            assert_batch_equals_alone(missions, [PolicySpec(name=name)] * len(missions))


def test_any_policy_runs_in_a_batch(layouts):
    """Per-mission policies (the planner) run one instance per column, next to batched ones."""
    missions = by_sensor_count(layouts)[0][:3]
    specs = [PolicySpec(name="planner"), PolicySpec(name="hgad"), PolicySpec(name="planner")]
    logs = assert_batch_equals_alone(missions, specs)
    assert [log.policy for log in logs] == ["planner", "hgad", "planner"]


def test_return_home_override_binds_on_a_short_mission(preset):
    """A mission just long enough to fly out: with return_home the engine brings the UAV home
    (overriding the tour), without it the UAV ends away."""
    base = build_mission(preset)
    nav, home = base.navigator, tuple(base.home_m)
    far = max(nav.travel_distance(home, tuple(p)) for p in base.hover_points_m)
    duration = math.ceil(far / base.max_step_m) + 5.0
    mission = preset.model_copy(
        update={"mission": preset.mission.model_copy(update={"duration_s": duration})}
    )
    away = mission.model_copy(
        update={"trajectory": mission.trajectory.model_copy(update={"return_home": False})}
    )
    missions = [build_mission(mission), build_mission(away)]
    for name in ("greedy", "hgad"):
        logs = assert_batch_equals_alone(missions, [PolicySpec(name=name)] * 2)
        assert np.allclose(logs[0].end_position_m[:2], base.home_m, atol=1e-6)
        assert not np.allclose(logs[1].end_position_m[:2], base.home_m, atol=1e-6)


def test_no_sensor_reachable(preset):
    """All rates 0 (a transmitter far too weak): nothing served, tours still flown."""
    radio = preset.radio.model_copy(update={"tx_power_dbm": -200.0})
    mission = build_mission(preset.model_copy(update={"radio": radio}))
    for name in ("greedy", "hgad"):
        log = run_mission(mission, batch_policy([PolicySpec(name=name)]))
        assert np.all(log.rate_bps == 0) and np.all(log.served == -1)
        assert np.ptp(log.position_m[:, 0]) > 0


def test_summaries_of_a_batch_are_those_of_skymule_run(preset, layouts):
    missions = [build_mission(preset), *layouts[:6]]
    specs = [PolicySpec(name=("greedy", "hgad")[k % 2]) for k in range(len(missions))]
    names = [f"m{k}" for k in range(len(missions))]
    for engine in ("numpy", "auto"):
        rows = summarize_missions(missions, specs, names, batch_size=4, engine=engine)
        for mission, spec, name, row in zip(missions, specs, names, rows, strict=True):
            want = summarize(run_mission(mission, batch_policy([spec])), name)
            assert_summaries_equal(row, want, TWIN_RTOL)


def test_a_batch_needs_one_fence_and_autonomous_missions(preset):
    mission = build_mission(preset)
    small = replace(mission, navigator=Navigator(shapely.box(-500.0, -500.0, 500.0, 500.0)))
    greedy = [PolicySpec(name="greedy")] * 2
    with pytest.raises(SkymuleError, match="another geofence"):
        run_missions([mission, small], batch_policy(greedy))
    fixed = preset_mission("paper-sim-fixed")
    with pytest.raises(SkymuleError, match="one trajectory mode"):
        run_missions([mission, fixed], batch_policy(greedy))


AUTONOMOUS_SWEEP = """
base = "paper-sim-autonomous"
seed = 2
[axes]
policy.name = ["greedy", "hgad", "planner"]
radio.fading = ["none", "rician"]
"sensors[*].buffer_mbit" = { dist = "uniform", low = 100, high = 900 }
"mission.duration_s" = [300]
"""


def test_sweep_rows_of_autonomous_missions_equal_skymule_run(tmp_path):
    """A sweep worker batches autonomous missions, any policy; its rows are ``skymule run``'s."""
    path = tmp_path / "sweep.toml"
    path.write_text(AUTONOMOUS_SWEEP)
    missions = list(iter_missions(load_sweep(path)))
    tasks = [(m.index, m.mission_id, m.params, m.scenario) for m in missions]
    frame = run_chunk(tasks, str(tmp_path))
    assert len(frame) == 6
    for row, mission in zip(frame.to_dict("records"), missions, strict=True):
        scenario = scenario_from_dict(mission.scenario, "t", Path("."))
        want = _flat_summary(simulate(scenario).summary)
        assert_summaries_equal({key: row[key] for key in want}, want, TWIN_RTOL)
