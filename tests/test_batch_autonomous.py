"""The batched autonomous engine (sim.batch_autonomous) equals the reference engine value for
value, and the vectorised navigator queries equal the scalar ones."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import Polygon

from skymule.errors import SkymuleError
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.experiments.run import _flat_summary, run_chunk
from skymule.experiments.sweep import iter_missions, load_sweep
from skymule.flight.navigation import Navigator
from skymule.metrics import summarize
from skymule.policies.greedy import Greedy
from skymule.policies.hgad import HGAD
from skymule.runner import simulate
from skymule.scenario import PolicySpec, load_scenario, scenario_from_dict
from skymule.sim.batch_autonomous import (
    TourParams,
    batchable,
    mission_log,
    padded,
    run_autonomous_batch,
    run_tours,
    summarize_autonomous_batch,
)
from skymule.sim.batch_signal import BatchSignal
from skymule.sim.context import autonomous_peak_rate_bps
from skymule.flights import MissionLog
from skymule.sim.run import run_mission
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


def assert_logs_equal(got: MissionLog, want: MissionLog) -> None:
    """Every field: positions to 1e-9 m, choices exactly, bits to 1e-6."""
    for name in ("policy", "sensor_names", "slot_s", "visit_radius_m", "aadm_window_s"):
        assert getattr(got, name) == getattr(want, name), name
    for name in ("position_m", "end_position_m", "home_m", "hover_points_m"):
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=0, atol=1e-9)
    for name in ("served", "target", "hovering"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name), err_msg=name)
    for name in ("buffers_bit", "downloaded_bit", "remaining_bit"):
        np.testing.assert_allclose(getattr(got, name), getattr(want, name), rtol=0, atol=1e-6)
    np.testing.assert_allclose(got.snr_db, want.snr_db, rtol=0, atol=1e-9)
    np.testing.assert_allclose(got.rate_bps, want.rate_bps, rtol=0, atol=1e-6)
    assert got.affected is None and want.affected is None
    assert got.chosen is None and want.chosen is None


def assert_batched_equal(missions, policies) -> list[MissionLog]:
    """Batched logs of ``missions`` under each reference policy factory equal the reference."""
    logs = []
    for factory in policies:
        reference = [run_mission(m, factory()) for m in missions]
        tour = factory()
        params = TourParams(
            hgad=isinstance(tour, HGAD),
            max_hover_s=getattr(tour, "max_hover_s", 60.0),
            priority=getattr(tour, "priority", "initial"),
        )
        result = run_tours(missions, [params] * len(missions), engine="numpy")
        for b, (mission, want) in enumerate(zip(missions, reference, strict=True)):
            got = mission_log(result, b, mission, want.policy)
            assert_logs_equal(got, want)
            logs.append(got)
    return logs


@pytest.fixture(scope="module")
def preset():
    return load_scenario(PRESET)


@pytest.fixture(scope="module")
def layouts(preset):
    """Random layouts: 3..6 sensors (padded in one batch), return home or not, some with
    fading, shadowing, another path-loss model, altitude or download window, some short
    enough that the return-home override binds."""
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
    """HGAD's R*_i of the whole padded batch, bit for bit those of each mission (fading,
    shadowing and two-ray layouts included)."""
    n_sensors = max(m.n_sensors for m in layouts)
    hover = padded([np.asarray(m.hover_points_m, float) for m in layouts], n_sensors, np.nan)
    hover[0, 3] = np.nan  # a sensor without a hover point: rate 0
    missions = list(layouts)
    missions[3] = replace(missions[3], hover_points_m=hover[: missions[3].n_sensors, 3])
    peak = BatchSignal(missions, n_sensors).peak_rate_bps(hover)
    for b, mission in enumerate(missions):
        want = autonomous_peak_rate_bps(mission)
        np.testing.assert_array_equal(peak[: mission.n_sensors, b], want)
        assert not peak[mission.n_sensors :, b].any()
    assert peak[0, 3] == 0.0 and peak[1 : missions[3].n_sensors, 3].all()


def test_navigator_batched_queries_equal_scalar_ones(preset):
    """shortest paths, travel distances and steps of many pairs at once, in two concave
    fences, equal the scalar queries (start on a vertex, start == goal included)."""
    rng = np.random.default_rng(3)
    for navigator in (Navigator(U_FENCE), build_mission(preset).navigator):
        assert len(navigator.vertices) > 0  # concave: paths bend
        low_x, low_y, high_x, high_y = navigator.fence.bounds
        points = rng.uniform([low_x, low_y], [high_x, high_y], (500, 2))
        points = points[navigator.covers_goals(points)]
        starts, goals = points[: len(points) // 2], points[len(points) // 2 :][: len(points) // 2]
        starts[:2] = navigator.vertices[:2]
        goals[2:4] = starts[2:4]
        steps = rng.uniform(0.0, 0.3 * (high_x - low_x), len(starts))
        distances = navigator.travel_distances(starts, goals)
        moved = navigator.steps(starts, goals, steps)
        paths, count = navigator.shortest_paths(starts, goals)
        for p, (a, b) in enumerate(zip(map(tuple, starts), map(tuple, goals), strict=True)):
            want = navigator.shortest_path(a, b)
            np.testing.assert_allclose(paths[p, : count[p]], want, rtol=0, atol=1e-9)
            assert distances[p] == pytest.approx(navigator.travel_distance(a, b), abs=1e-9)
            np.testing.assert_allclose(moved[p], navigator.step(a, b, steps[p]), atol=1e-9)
        assert not np.all(count == 2)  # some paths bend at reflex vertices


def test_navigator_batched_queries_reject_points_outside_the_fence():
    navigator = Navigator(U_FENCE)
    with pytest.raises(ValueError, match="outside the fence"):
        navigator.travel_distances(np.array([[5.0, 5.0]]), np.array([[15.0, 25.0]]))


def test_preset_and_table_ii_cases_equal_reference(preset):
    assert_batched_equal([build_mission(preset)], [lambda: HGAD(max_hover_s=7.0)])
    cases = [build_mission(preset)]
    for buffers in TABLE_II:
        sensors = [
            sensor.model_copy(update={"buffer_mbit": float(b)})
            for sensor, b in zip(preset.sensors, buffers, strict=True)
        ]
        cases.append(build_mission(preset.model_copy(update={"sensors": sensors})))
    assert_batched_equal(cases, [Greedy, HGAD, lambda: HGAD(priority="remaining")])


def test_random_layouts_equal_reference(layouts):
    assert len({m.n_sensors for m in layouts}) > 1
    assert {m.return_home for m in layouts} == {True, False}
    assert any(m.fading_db is not None for m in layouts)
    assert_batched_equal(layouts, [Greedy, HGAD])


def test_return_home_override_binds_on_a_short_mission(preset):
    """A mission just long enough to fly out: with return_home the engine brings the UAV home
    (overriding the tour), without it the UAV ends away; both equal the reference."""
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
    logs = assert_batched_equal(missions, [Greedy, HGAD])
    for log in logs:
        at_home = np.allclose(log.end_position_m[:2], base.home_m, atol=1e-6)
        assert at_home == (log is logs[0] or log is logs[2])


def test_no_sensor_reachable_equals_reference(preset):
    """All rates 0 (a transmitter far too weak): nothing served, tours still flown."""
    radio = preset.radio.model_copy(update={"tx_power_dbm": -200.0})
    mission = build_mission(preset.model_copy(update={"radio": radio}))
    logs = assert_batched_equal([mission], [Greedy, HGAD])
    for log in logs:
        assert np.all(log.rate_bps == 0) and np.all(log.served == -1)


def assert_rows_equal(got: dict, want: dict) -> None:
    """Summary rows: the same keys, numbers to round-off, everything else exactly."""
    assert got.keys() == want.keys()
    for key, value in want.items():
        if isinstance(value, float) and math.isnan(value):
            assert isinstance(got[key], float) and math.isnan(got[key]), key
        elif isinstance(value, float):
            assert got[key] == pytest.approx(value, rel=1e-12, abs=1e-9), key
        else:
            assert got[key] == value, key


def test_summaries_equal_reference_summaries(preset, layouts):
    missions = [build_mission(preset), *layouts[:5]]
    specs = [PolicySpec(name=("greedy", "hgad")[k % 2]) for k in range(len(missions))]
    names = [f"m{k}" for k in range(len(missions))]
    rows = summarize_autonomous_batch(missions, specs, names, batch_size=4, engine="numpy")
    logs = run_autonomous_batch(missions, specs, batch_size=4, engine="numpy")
    for mission, spec, name, row, log in zip(missions, specs, names, rows, logs, strict=True):
        policy = Greedy() if spec.name == "greedy" else HGAD()
        want = summarize(run_mission(mission, policy), name)
        assert_rows_equal(summarize(log, name), want)
        assert_rows_equal(row, want)


def test_batchable_scope(preset):
    mission = build_mission(preset)
    assert batchable(mission, PolicySpec(name="greedy"))
    assert batchable(mission, PolicySpec(name="hgad"))
    assert not batchable(mission, PolicySpec(name="planner"))
    faulty = replace(mission, faults=object())  # type: ignore[arg-type]
    assert not batchable(faulty, PolicySpec(name="hgad"))
    assert not batchable(build_mission(load_scenario("paper-sim-fixed")), PolicySpec(name="hgad"))
    with pytest.raises(SkymuleError, match="no batched autonomous engine"):
        run_autonomous_batch([mission], [PolicySpec(name="planner")])
    with pytest.raises(SkymuleError, match="needs autonomous missions"):
        run_autonomous_batch([build_mission(load_scenario("paper-sim-fixed"))], [PolicySpec()])
    with pytest.raises(SkymuleError, match="does not apply faults"):
        run_tours([faulty], [TourParams(hgad=True)])


def test_batches_need_one_fence(preset):
    mission = build_mission(preset)
    small = replace(mission, navigator=Navigator(shapely.box(-500.0, -500.0, 500.0, 500.0)))
    with pytest.raises(ValueError, match="one geofence"):
        run_tours([mission, small], [TourParams(hgad=False)] * 2)


AUTONOMOUS_SWEEP = """
base = "paper-sim-autonomous"
seed = 2
[axes]
policy.name = ["greedy", "hgad"]
radio.fading = ["none", "rician"]
"sensors[*].buffer_mbit" = { dist = "uniform", low = 100, high = 900 }
"mission.duration_s" = [300]
"""


def test_sweep_rows_of_autonomous_missions_equal_skymule_run(tmp_path):
    """A sweep worker batches autonomous Greedy/HGAD missions; its rows are ``skymule run``'s."""
    path = tmp_path / "sweep.toml"
    path.write_text(AUTONOMOUS_SWEEP)
    missions = list(iter_missions(load_sweep(path)))
    tasks = [(m.index, m.mission_id, m.params, m.scenario) for m in missions]
    frame = run_chunk(tasks, str(tmp_path))
    assert len(frame) == 4
    for row, mission in zip(frame.to_dict("records"), missions, strict=True):
        scenario = scenario_from_dict(mission.scenario, "t", Path("."))
        want = _flat_summary(simulate(scenario).summary)
        assert_rows_equal({key: row[key] for key in want}, want)
