"""The compiled summaries equal ``metrics.summaries`` value for value.

The reductions of :mod:`skymule.sim.summary_kernels` run as plain Python here (and compiled
where numba is installed) on the numpy slot loop's records of random, fading and faulty
missions and on autonomous runs (first visits by target); the compiled loop's own summaries
(no per-slot log) are checked against the numpy path's, as plain Python too where numba is
absent, and so are the autonomous engine's summary rows.
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import skymule.metrics.summary as metrics
from engine_cases import (
    TWIN_RTOL,
    random_geometry,
    random_mission,
    random_spec,
    with_geometry,
    with_random_fading,
)
from engine_cases import (
    assert_summaries_equal as assert_rows_close,
)
from skymule.experiments.layouts import LayoutRanges, random_autonomous_scenario
from skymule.metrics.flights import Flights
from skymule.metrics.summary import Summaries, summaries
from skymule.policies import batch_policy
from skymule.rules.contract import NO_SENSOR
from skymule.scenario import PolicySpec, load_scenario
from skymule.sim import compiled
from skymule.sim.compiled_summaries import compiled_summaries, flights_summaries
from skymule.sim.fixed import FixedEngine
from skymule.sim.run import run_missions, summarize_missions
from skymule.world import build_mission
from test_fault_engines import MIXED_FAULTS, _with_faults

needs_numba = pytest.mark.skipif(not compiled.available(), reason="numba not installed")
SETTINGS = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


def assert_arrays_close(ours: np.ndarray, theirs: np.ndarray, name: str) -> None:
    """Same dtype and shape; floats within :data:`TWIN_RTOL` (numba sums in order, numpy
    pairwise: bit for bit when the kernels run as plain Python), the rest exactly."""
    assert ours.dtype == theirs.dtype and ours.shape == theirs.shape, name
    if theirs.dtype.kind == "f":
        np.testing.assert_allclose(ours, theirs, rtol=TWIN_RTOL, atol=0.0, err_msg=name)
    else:
        np.testing.assert_array_equal(ours, theirs, name, strict=True)


def assert_summaries_equal(got: Summaries, want: Summaries) -> None:
    """Every array of every field (the AADM parts too): same dtype, shape and values."""
    for field in fields(Summaries):
        ours, theirs = getattr(got, field.name), getattr(want, field.name)
        if field.name == "aadm":
            for part in fields(theirs):
                assert_arrays_close(getattr(ours, part.name), getattr(theirs, part.name), part.name)
        else:
            assert_arrays_close(ours, theirs, field.name)


def numpy_flights(missions, specs) -> Flights:
    """The numpy slot loop's record (no per-slot detail: what summaries read)."""
    return run_missions(missions, batch_policy(specs), detail=False, engine="numpy")


def loop_summaries(missions, specs) -> list[Summaries]:
    """The compiled loop's own summaries: compiled where numba is installed, and the same
    loop as plain Python always."""
    out = []
    loops = [compiled.slot_loop, *([compiled.compiled_loop()] if compiled.available() else [])]
    for loop in loops:
        engine = FixedEngine(missions, detail=False)
        policy = batch_policy(specs)
        policy.reset(engine.contexts())
        out.append(compiled_summaries(engine, policy.slot_rule(), loop))  # type: ignore[attr-defined]
    return out


@given(
    seed=st.integers(0, 2**32 - 1),
    n_tracks=st.integers(1, 40),
    k_max=st.integers(1, 600),
    scale=st.sampled_from([1e-3, 1.0, 150.0, 1e4]),
)
def test_track_steps_are_the_norm_float_for_float(seed, n_tracks, k_max, scale):
    """The step table the reductions look up is ``np.linalg.norm`` of each 3-D step, bit for
    bit (its three squares summed in numpy's order), altitude changes included."""
    rng = np.random.default_rng(seed)
    position = rng.normal(size=(n_tracks, k_max, 3)) * scale
    n_samples = rng.integers(0, k_max + 1, n_tracks)
    want = np.zeros((n_tracks, k_max))
    want[:, :-1] = np.linalg.norm(np.diff(position, axis=1), axis=2)
    want[np.arange(k_max) >= n_samples[:, None] - 1] = 0.0
    np.testing.assert_array_equal(metrics.track_steps_m(position, n_samples), want, strict=True)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 10), n_sensors=st.integers(1, 5))
def test_kernels_equal_metrics_on_random_missions(base_mission, seed, n_missions, n_sensors):
    """Random tracks, buffers, windows, geometry, HGAD parameters; half with fading."""
    rng = np.random.default_rng(seed)
    missions = [
        with_random_fading(random_mission(base_mission, rng, n_sensors), rng)
        for _ in range(n_missions)
    ]
    missions = with_geometry(missions, [random_geometry(rng, n_sensors) for _ in missions])
    flights = numpy_flights(missions, [random_spec(rng) for _ in missions])
    assert_summaries_equal(flights_summaries(flights, use_numba=False), summaries(flights))


@pytest.mark.parametrize("policy", ["greedy", "hgad"])
def test_kernels_equal_metrics_on_fault_missions(policy):
    """Outages, Gilbert-Elliott loss, SNR error and missed polls leave gaps in the service."""
    missions = [
        build_mission(_with_faults("paper-sim-fixed", MIXED_FAULTS, seed=seed)) for seed in (1, 2)
    ]
    flights = numpy_flights(missions, [PolicySpec(name=policy)] * 2)
    want = summaries(flights)
    assert_summaries_equal(flights_summaries(flights, use_numba=False), want)
    if compiled.available():
        assert_summaries_equal(flights_summaries(flights), want)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_compiled_loop_summaries_equal_numpy_summaries(base_mission, seed, n_missions, n_sensors):
    rng = np.random.default_rng(seed)
    missions = [random_mission(base_mission, rng, n_sensors) for _ in range(n_missions)]
    missions = with_geometry(missions, [random_geometry(rng, n_sensors) for _ in missions])
    specs = [random_spec(rng) for _ in missions]
    want = summaries(numpy_flights(missions, specs))
    for got in loop_summaries(missions, specs):
        assert_summaries_equal(got, want)


@pytest.mark.parametrize("threshold", [1.0, 0.8, 0.5])
def test_compiled_loop_summaries_on_paper_preset(base_mission, threshold):
    """Random buffers (some emptied: the AADM bonus), HGAD thresholds, a 300-s window."""
    rng = np.random.default_rng(int(threshold * 10))
    missions = [replace(base_mission, buffers_bit=rng.uniform(0, 1500e6, 4)) for _ in range(12)]
    missions[0] = replace(missions[0], buffers_bit=np.array([1e6, 2e6, 0.0, 3e6]))
    missions[1] = replace(missions[1], aadm_window_s=300.0)
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad", hover_threshold=threshold)] * 6
    flights = numpy_flights(missions, specs)
    want = summaries(flights)
    for got in loop_summaries(missions, specs):
        assert_summaries_equal(got, want)
    assert want.aadm.complete[0] and (want.hover_time_s[1::2] > 0).all()
    assert_summaries_equal(flights_summaries(flights, use_numba=compiled.available()), want)


def test_straight_walks_of_other_lengths_on_one_track(base_mission):
    """Greedy missions sharing a track but not their length: each sums its own steps."""
    missions = [replace(base_mission, n_slots=n) for n in (500, 120, 120, 7, 500, 0, 31)]
    specs = [PolicySpec(name="greedy")] * len(missions)
    flights = numpy_flights(missions, specs)
    want = summaries(flights)
    assert len(set(want.distance_m.tolist())) == 5
    for got in loop_summaries(missions, specs):
        assert_summaries_equal(got, want)
    assert_summaries_equal(flights_summaries(flights, use_numba=False), want)


@pytest.fixture(scope="module")
def autonomous_flights() -> list[Flights]:
    """Autonomous runs as the sweep path summarises them, Greedy and HGAD: the preset,
    random layouts (return home or not; the preset's sensor count, so one batch), a mission
    too short to reach any hover point and one that runs no slot."""
    preset = load_scenario("paper-sim-autonomous")
    rng = np.random.default_rng(11)
    ranges = LayoutRanges(n_sensors=(4, 4), return_home_probability=0.5, duration_s=(120, 300))
    missions = [build_mission(random_autonomous_scenario(rng, preset, ranges)) for _ in range(6)]
    missions = [build_mission(preset), *missions]
    missions += [replace(missions[1], n_slots=3), replace(missions[2], n_slots=0)]
    assert {m.return_home for m in missions} == {True, False}
    return [
        run_missions(missions, batch_policy([PolicySpec(name=name)] * len(missions)), detail=False)
        for name in ("greedy", "hgad")
    ]


def assert_kernels_equal_metrics(flights: Flights) -> Summaries:
    """Plain-Python kernels, and compiled ones where numba is installed, equal
    ``metrics.summaries``; returns that."""
    want = summaries(flights)
    assert_summaries_equal(flights_summaries(flights, use_numba=False), want)
    if compiled.available():
        assert_summaries_equal(flights_summaries(flights), want)
    return want


def test_kernels_equal_metrics_on_autonomous_flights(autonomous_flights):
    """First visits by target (heading for a sensor and ending the slot near it), HGAD hovers
    included; the same flights without targets follow the hover and place rules instead."""
    for flights in autonomous_flights:
        want = assert_kernels_equal_metrics(flights)
        assert (want.visit_order[-2:] == NO_SENSOR).all()  # too short to visit, no slot
        assert (want.visit_order[:-2, 0] != NO_SENSOR).all()
        untargeted = assert_kernels_equal_metrics(replace(flights, target=None))
        assert (untargeted.visit_order != want.visit_order).any()  # the target rule matters
    hgad = summaries(autonomous_flights[1])
    assert (hgad.hover_time_s[:-2] > 0).all() and (hgad.aadm.score > 0).any()


def test_kernels_equal_metrics_on_rows_the_target_rule_skips(autonomous_flights):
    """Rows with no known hover point (a log without them) or no slot run fall back to the
    hover rule (HGAD) or the place rule; other radii move the first visits."""
    for flights in autonomous_flights:
        hover = flights.hover_points_m.copy()
        hover[1::3] = np.nan
        hover[2, 1] = np.nan  # one sensor unknown: that row keeps the target rule
        assert_kernels_equal_metrics(replace(flights, hover_points_m=hover))
        for radius in (0.0, 5.0, 400.0):
            wider = replace(flights, visit_radius_m=np.full_like(flights.visit_radius_m, radius))
            assert_kernels_equal_metrics(wider)


def test_kernels_equal_metrics_with_radii_on_the_boundary(autonomous_flights):
    """Each mission's visit radius set to exactly the distance at which the UAV ended some slot
    heading for a sensor: the test ``distance <= radius`` holds with equality there, so
    the kernels' hypot must be numpy's to the last bit (numba calls the same C function)."""
    for flights in autonomous_flights:
        assert flights.target is not None
        radius = flights.visit_radius_m.copy()
        for b in range(radius.size):
            n_run = flights.n_run[b]
            heading = np.flatnonzero(flights.target[b, :n_run] != NO_SENSOR)
            if heading.size == 0:
                continue
            t = heading[heading.size // 2]
            k = flights.sample[b, t + 1] if t + 1 < n_run else flights.end_sample[b]
            end = flights.track_position_m[flights.track_id[b], k, :2]
            offset = end - flights.hover_points_m[b, flights.target[b, t]]
            radius[b] = np.hypot(offset[0], offset[1])
        assert_kernels_equal_metrics(replace(flights, visit_radius_m=radius))


@needs_numba
def test_compiled_autonomous_summaries_equal_numpy_summaries(autonomous_flights):
    """The sweep path: ``summarize_missions`` with the compiled engine (compiled path
    queries and reductions) gives the numpy engine's rows, Greedy and HGAD."""
    preset = load_scenario("paper-sim-autonomous")
    mission = build_mission(preset)
    missions = [mission, replace(mission, n_slots=3), replace(mission, n_slots=120)]
    for policy in ("greedy", "hgad"):
        specs = [PolicySpec(name=policy)] * len(missions)
        names = [f"m{k}" for k in range(len(missions))]
        want = summarize_missions(missions, specs, names, engine="numpy")
        got = summarize_missions(missions, specs, names, engine="compiled")
        assert_rows_close(got, want, TWIN_RTOL)
        assert want[1]["visit_order"] == [] and want[0]["visit_order"]
