"""The compiled path queries equal the navigator's, value for value: the path kernels against
:meth:`Navigator.steps` / :meth:`~Navigator.travel_distances`, and whole autonomous batches on
``engine="compiled"`` against ``engine="numpy"``.

Every check runs without numba too: the kernels are plain Python that numba compiles, run as
they are (``CompiledPaths(plain=True)``, engine ``"plain"``) where it is absent, and compiled
as well where it is installed.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely

import test_batch_autonomous
from engine_cases import assert_logs_equal
from skymule.errors import SkymuleError
from skymule.flight.navigation import Navigator
from skymule.policies import batch_policy
from skymule.scenario import PolicySpec
from skymule.sim import compiled
from skymule.sim.autonomous import AutonomousEngine
from skymule.sim.batch_paths import CompiledPaths
from skymule.sim.run import run_missions
from skymule.world import build_mission
from test_batch_autonomous import TABLE_II, U_FENCE

preset = test_batch_autonomous.preset
layouts = test_batch_autonomous.layouts

#: The twins to check: the kernels as plain Python always, compiled where numba is installed.
TWINS = ["plain", *(["compiled"] if compiled.available() else [])]


@pytest.mark.parametrize("twin", TWINS)
def test_compiled_path_queries_equal_navigator(preset, twin):
    """steps and travel distances of many random pairs (starts on vertices, start == goal,
    with and without the goals' sights, some unknown and filled in) equal the navigator's,
    bit for bit."""
    rng = np.random.default_rng(4)
    # a fence of 300 edges keeps shapely's test (the certificate would be slower there)
    circle = shapely.Point(0.0, 0.0).buffer(1000.0, quad_segs=75)
    notched = circle.difference(shapely.box(-100.0, -1100.0, 100.0, 200.0))
    assert len(notched.exterior.coords) > 256
    size = 3000 if twin == "compiled" else 600
    for navigator in (Navigator(U_FENCE), build_mission(preset).navigator, Navigator(notched)):
        paths = CompiledPaths(navigator, plain=twin == "plain")
        low_x, low_y, high_x, high_y = navigator.fence.bounds
        points = rng.uniform([low_x, low_y], [high_x, high_y], (size, 2))
        points = points[navigator.covers_goals(points)]
        half = len(points) // 2
        starts, goals = points[:half], points[half : 2 * half]
        vertices = navigator.vertices
        starts[: len(vertices)] = vertices
        goals[len(vertices) : 2 * len(vertices)] = vertices
        goals[-3:] = starts[-3:]
        steps = rng.uniform(0.0, 0.5 * (high_x - low_x), half)
        known = navigator.sights(goals)
        partly = (known[0].copy(), known[1].copy())
        partly[1][::3] = np.nan  # unknown sights, filled in where a path bends
        for sight in (None, known, partly):
            want = navigator.steps(starts, goals, steps, sight)
            np.testing.assert_array_equal(paths.steps(starts, goals, steps, sight), want)
            np.testing.assert_array_equal(
                paths.travel_distances(starts, goals, sight),
                navigator.travel_distances(starts, goals, sight),
            )
        bent = navigator.shortest_paths(starts, goals)[1] > 2
        assert np.any(bent)  # some paths bend
        assert not np.isnan(partly[1][bent, 0]).any()  # the sights of bent paths were filled
        with pytest.raises(ValueError, match="outside the fence"):
            paths.steps(np.array([[low_x - 10.0, low_y]]), goals[:1], 1.0)


SPECS = [
    PolicySpec(name="greedy"),
    PolicySpec(name="hgad"),
    PolicySpec(name="hgad", max_hover_s=7.0),
    PolicySpec(name="hgad-robust"),
]


def assert_engines_equal(missions, specs, twin: str) -> None:
    """Every log field of a batch on the twin's path queries equals the numpy engine's."""
    want = run_missions(missions, batch_policy(specs), engine="numpy")
    engine = AutonomousEngine(missions, engine=twin)
    policy = batch_policy(specs)
    policy.reset(engine.contexts())
    while not engine.done:
        engine.step(policy.act(engine.observe()))
    got = engine.record([s.name for s in specs])
    for b in range(len(missions)):
        assert_logs_equal(got.mission(b), want.mission(b))


@pytest.mark.parametrize("twin", TWINS)
def test_compiled_engine_equals_numpy_on_preset_and_table_ii(preset, twin):
    cases = [build_mission(preset)]
    for buffers in TABLE_II:
        sensors = [
            sensor.model_copy(update={"buffer_mbit": float(b)})
            for sensor, b in zip(preset.sensors, buffers, strict=True)
        ]
        cases.append(build_mission(preset.model_copy(update={"sensors": sensors})))
    assert_engines_equal(cases, [*SPECS, SPECS[0]], twin)


@pytest.mark.parametrize("twin", TWINS)
def test_compiled_engine_equals_numpy_on_random_layouts(layouts, twin):
    """3-6 sensors, return home on and off, fading, shadowing, two-ray, short missions."""
    for missions in test_batch_autonomous.by_sensor_count(layouts):
        specs = [SPECS[k % 2] for k in range(len(missions))]
        assert_engines_equal(missions, specs, twin)


@pytest.mark.parametrize("twin", TWINS)
def test_compiled_engine_equals_numpy_when_the_override_binds(preset, twin):
    """Missions just long enough to fly out and back: the return-home override binds."""
    base = build_mission(preset)
    far = max(
        base.navigator.travel_distance(tuple(base.home_m), tuple(p)) for p in base.hover_points_m
    )
    missions = []
    for extra in (2.0, 5.0, 30.0):
        duration = math.ceil(far / base.max_step_m) + extra
        short = preset.model_copy(
            update={"mission": preset.mission.model_copy(update={"duration_s": duration})}
        )
        missions.append(build_mission(short))
    assert_engines_equal(missions, [SPECS[0], SPECS[1], SPECS[0]], twin)


def test_engine_is_checked(preset, monkeypatch):
    mission = build_mission(preset)
    greedy = [PolicySpec(name="greedy")]
    with pytest.raises(SkymuleError, match="engine = 'fast'; allowed: auto, numpy, compiled"):
        run_missions([mission], batch_policy(greedy), engine="fast")
    monkeypatch.setattr(compiled, "available", lambda: False)
    with pytest.raises(SkymuleError, match="numba is not installed"):
        run_missions([mission], batch_policy(greedy), engine="compiled")
    # without numba, "auto" runs the numpy path
    assert run_missions([mission], batch_policy(greedy)).n_run[0] == mission.n_slots


@pytest.mark.parametrize("twin", TWINS)
def test_compiled_engine_equals_numpy_in_a_convex_fence(preset, twin):
    """No reflex vertices: every path is straight (the kernels' graph tables are empty)."""
    box = Navigator(shapely.box(-5000.0, -5000.0, 5000.0, 5000.0))
    mission = replace(build_mission(preset), navigator=box)
    assert len(box.vertices) == 0
    assert_engines_equal([mission, mission], SPECS[:2], twin)
