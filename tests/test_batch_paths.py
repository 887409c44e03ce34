"""The compiled batched autonomous engine equals the numpy one, value for value: the path
kernels against the navigator's queries, and whole missions against ``engine="numpy"``."""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest
import shapely

import test_batch_autonomous
from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator
from skymule.scenario import PolicySpec
from skymule.sim import batch_autonomous, compiled, path_kernels
from skymule.sim.batch_autonomous import (
    TourParams,
    run_autonomous_batch,
    run_tours,
    summarize_autonomous_batch,
)
from skymule.world import build_mission
from test_batch_autonomous import TABLE_II, U_FENCE

# the same cases as the numpy engine's tests against the reference engine
preset = test_batch_autonomous.preset
layouts = test_batch_autonomous.layouts

needs_numba = pytest.mark.skipif(not compiled.available(), reason="numba not installed")


def test_python_hypot_equals_math_hypot():
    """The kernels' hypot is CPython's, bit for bit (np.hypot is not, for ~1 pair in 200)."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=4000) * rng.choice([1e-3, 1.0, 150.0, 1e4], 4000)
    y = rng.normal(size=4000) * rng.choice([1e-3, 1.0, 150.0, 1e4], 4000)
    x[:50], y[50:100] = 0.0, 0.0
    x[100:200], y[100:200] = np.round(x[100:200]), np.round(y[100:200])
    got = [path_kernels.python_hypot(a, b) for a, b in zip(x.tolist(), y.tolist(), strict=True)]
    want = [math.hypot(a, b) for a, b in zip(x.tolist(), y.tolist(), strict=True)]
    assert got == want
    assert np.any(np.hypot(x, y) != np.array(want))  # the C library's differs: the port matters
    assert path_kernels.python_hypot(0.0, 0.0) == 0.0


def test_numpy_sum_equals_np_sum():
    rng = np.random.default_rng(6)
    for n in range(1, 129):
        values = rng.uniform(0.0, 500.0, n)
        assert path_kernels.numpy_sum(values, n) == np.sum(values), n


@needs_numba
def test_compiled_path_queries_equal_navigator(preset):
    """steps and travel distances of many random pairs (starts on vertices, start == goal,
    with and without the goals' sights) equal the navigator's, bit for bit."""
    from skymule.sim.batch_paths import CompiledPaths

    rng = np.random.default_rng(4)
    # a fence of 300 edges keeps shapely's test (the certificate would be slower there)
    circle = shapely.Point(0.0, 0.0).buffer(1000.0, quad_segs=75)
    notched = circle.difference(shapely.box(-100.0, -1100.0, 100.0, 200.0))
    assert len(notched.exterior.coords) > 256
    for navigator in (Navigator(U_FENCE), build_mission(preset).navigator, Navigator(notched)):
        paths = CompiledPaths(navigator)
        low_x, low_y, high_x, high_y = navigator.fence.bounds
        points = rng.uniform([low_x, low_y], [high_x, high_y], (3000, 2))
        points = points[navigator.covers_goals(points)]
        half = len(points) // 2
        starts, goals = points[:half], points[half : 2 * half]
        vertices = navigator.vertices
        starts[: len(vertices)] = vertices
        goals[len(vertices) : 2 * len(vertices)] = vertices
        goals[-3:] = starts[-3:]
        steps = rng.uniform(0.0, 0.5 * (high_x - low_x), half)
        for sight in (None, navigator.sights(goals)):
            want = navigator.steps(starts, goals, steps, sight)
            np.testing.assert_array_equal(paths.steps(starts, goals, steps, sight), want)
            np.testing.assert_array_equal(
                paths.travel_distances(starts, goals, sight),
                navigator.travel_distances(starts, goals, sight),
            )
        assert np.any(navigator.shortest_paths(starts, goals)[1] > 2)  # some paths bend
        with pytest.raises(ValueError, match="outside the fence"):
            paths.steps(np.array([[low_x - 10.0, low_y]]), goals[:1], 1.0)


def assert_results_equal(got: batch_autonomous.TourResult, want: batch_autonomous.TourResult):
    """Every array of two batch results, bit for bit (positions included)."""
    for field in fields(want):
        np.testing.assert_array_equal(
            getattr(got, field.name), getattr(want, field.name), err_msg=field.name
        )


def assert_engines_equal(missions, params) -> None:
    want = run_tours(missions, [params] * len(missions), engine="numpy")
    got = run_tours(missions, [params] * len(missions), engine="compiled")
    assert_results_equal(got, want)


ALL_TOURS = [
    TourParams(hgad=False),
    TourParams(hgad=True),
    TourParams(hgad=True, priority="remaining"),
    TourParams(hgad=True, max_hover_s=7.0),
]


@needs_numba
def test_compiled_engine_equals_numpy_on_preset_and_table_ii(preset):
    cases = [build_mission(preset)]
    for buffers in TABLE_II:
        sensors = [
            sensor.model_copy(update={"buffer_mbit": float(b)})
            for sensor, b in zip(preset.sensors, buffers, strict=True)
        ]
        cases.append(build_mission(preset.model_copy(update={"sensors": sensors})))
    for params in ALL_TOURS:
        assert_engines_equal(cases, params)


@needs_numba
def test_compiled_engine_equals_numpy_on_random_layouts(layouts):
    """3-6 sensors, return home on and off, fading, shadowing, two-ray, short missions."""
    for params in ALL_TOURS[:2]:
        assert_engines_equal(layouts, params)
    specs = [PolicySpec(name=("greedy", "hgad")[k % 2]) for k in range(len(layouts))]
    names = [f"m{k}" for k in range(len(layouts))]
    assert summarize_autonomous_batch(
        layouts, specs, names, engine="compiled"
    ) == summarize_autonomous_batch(layouts, specs, names, engine="numpy")


@needs_numba
def test_compiled_engine_equals_numpy_when_the_override_binds(preset):
    """Missions just long enough to fly out and back: the return-home override binds."""
    base = build_mission(preset)
    far = max(
        base.navigator.travel_distance(tuple(base.home_m), tuple(p)) for p in base.hover_points_m
    )
    for extra in (2.0, 5.0, 30.0):
        duration = math.ceil(far / base.max_step_m) + extra
        short = preset.model_copy(
            update={"mission": preset.mission.model_copy(update={"duration_s": duration})}
        )
        for params in ALL_TOURS[:2]:
            assert_engines_equal([build_mission(short)], params)


def test_engine_is_checked(preset, monkeypatch):
    mission = build_mission(preset)
    with pytest.raises(SkymuleError, match="engine = 'fast'; allowed: auto, numpy, compiled"):
        run_tours([mission], [TourParams(hgad=False)], engine="fast")  # type: ignore[arg-type]
    monkeypatch.setattr(compiled, "available", lambda: False)
    with pytest.raises(SkymuleError, match="numba is not installed"):
        run_tours([mission], [TourParams(hgad=False)], engine="compiled")
    # without numba, "auto" runs the numpy path
    (log,) = run_autonomous_batch([mission], [PolicySpec(name="greedy")])
    assert log.served.size == mission.n_slots


@needs_numba
def test_compiled_engine_equals_numpy_in_a_convex_fence(preset):
    """No reflex vertices: every path is straight (the kernels' graph tables are empty)."""
    box = Navigator(shapely.box(-5000.0, -5000.0, 5000.0, 5000.0))
    mission = replace(build_mission(preset), navigator=box)
    assert len(box.vertices) == 0
    for params in ALL_TOURS[:2]:
        assert_engines_equal([mission, mission], params)
