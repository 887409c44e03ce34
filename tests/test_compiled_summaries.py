"""The compiled summaries equal ``metrics.summaries`` value for value.

The reductions of :mod:`skymule.sim.summary_kernels` run as plain Python here (and compiled
where numba is installed) on the numpy loop's logs of random, fading and faulty missions; the
compiled loop's own summaries (no per-slot log) are checked against the numpy path's.
"""

from __future__ import annotations

from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from skymule.metrics import Summaries, summaries
from skymule.scenario import PolicySpec, load_scenario
from skymule.sim import compiled, summary_kernels
from skymule.sim.batch import batch_flights, run_numpy, stack_missions
from skymule.sim.compiled_summaries import compiled_summaries, flights_summaries
from skymule.world import build_mission
from test_batch import (
    random_geometry,
    random_mission,
    random_spec,
    with_geometry,
    with_random_fading,
)
from test_fault_engines import MIXED_FAULTS, _with_faults

needs_numba = pytest.mark.skipif(not compiled.available(), reason="numba not installed")
SETTINGS = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@pytest.fixture(scope="module")
def base_mission():
    return build_mission(load_scenario("paper-sim-fixed"))


def assert_summaries_equal(got: Summaries, want: Summaries) -> None:
    """Every array of every field (the AADM parts too): same dtype, shape and values."""
    for field in fields(Summaries):
        ours, theirs = getattr(got, field.name), getattr(want, field.name)
        if field.name == "aadm":
            for part in fields(theirs):
                np.testing.assert_array_equal(
                    getattr(ours, part.name), getattr(theirs, part.name), part.name, strict=True
                )
        else:
            np.testing.assert_array_equal(ours, theirs, field.name, strict=True)


def numpy_flights(missions, specs):
    batch = stack_missions(missions, specs)
    return batch, batch_flights(batch, run_numpy(batch), missions)


@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 3000), spread=st.floats(-3, 9))
def test_pairwise_sum_is_numpys_sum_bit_for_bit(seed, n, spread):
    rng = np.random.default_rng(seed)
    values = rng.standard_normal(n) * 10.0 ** rng.uniform(-3, spread, n)
    stack, partial = np.empty((128, 3), np.int64), np.empty(128)
    assert summary_kernels.pairwise_sum(values, n, stack, partial) == values.sum()
    rows = values[: n - n % 3].reshape(3, -1)  # as metrics.row_sums sums a block of rows
    for row, want in zip(rows, rows.sum(axis=1), strict=True):
        assert summary_kernels.pairwise_sum(row, row.size, stack, partial) == want


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
    _, flights = numpy_flights(missions, [random_spec(rng) for _ in missions])
    assert_summaries_equal(flights_summaries(flights, use_numba=False), summaries(flights))


@pytest.mark.parametrize("policy", ["greedy", "hgad"])
def test_kernels_equal_metrics_on_fault_missions(policy):
    """Outages, Gilbert-Elliott loss, SNR error and missed polls leave gaps in the service."""
    missions = [
        build_mission(_with_faults("paper-sim-fixed", MIXED_FAULTS, seed=seed)) for seed in (1, 2)
    ]
    _, flights = numpy_flights(missions, [PolicySpec(name=policy)] * 2)
    want = summaries(flights)
    assert_summaries_equal(flights_summaries(flights, use_numba=False), want)
    if compiled.available():
        assert_summaries_equal(flights_summaries(flights), want)


@needs_numba
@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), n_missions=st.integers(1, 12), n_sensors=st.integers(1, 5))
def test_compiled_loop_summaries_equal_numpy_summaries(base_mission, seed, n_missions, n_sensors):
    rng = np.random.default_rng(seed)
    missions = [random_mission(base_mission, rng, n_sensors) for _ in range(n_missions)]
    missions = with_geometry(missions, [random_geometry(rng, n_sensors) for _ in missions])
    batch, flights = numpy_flights(missions, [random_spec(rng) for _ in missions])
    assert_summaries_equal(compiled_summaries(batch, missions), summaries(flights))


@needs_numba
@pytest.mark.parametrize("threshold", [1.0, 0.8, 0.5])
def test_compiled_loop_summaries_on_paper_preset(base_mission, threshold):
    """Random buffers (some emptied: the AADM bonus), HGAD thresholds, a 300-s window."""
    rng = np.random.default_rng(int(threshold * 10))
    missions = [replace(base_mission, buffers_bit=rng.uniform(0, 1500e6, 4)) for _ in range(12)]
    missions[0] = replace(missions[0], buffers_bit=np.array([1e6, 2e6, 0.0, 3e6]))
    missions[1] = replace(missions[1], aadm_window_s=300.0)
    specs = [PolicySpec(name="greedy"), PolicySpec(name="hgad", hover_threshold=threshold)] * 6
    batch, flights = numpy_flights(missions, specs)
    want = summaries(flights)
    assert_summaries_equal(compiled_summaries(batch, missions), want)
    assert want.aadm.complete[0] and (want.hover_time_s[1::2] > 0).all()
    assert_summaries_equal(flights_summaries(flights), want)


@needs_numba
def test_straight_walks_of_other_lengths_on_one_track(base_mission):
    """Greedy missions sharing a track but not their length: each sums its own steps."""
    missions = [replace(base_mission, n_slots=n) for n in (500, 120, 120, 7, 500, 0, 31)]
    specs = [PolicySpec(name="greedy")] * len(missions)
    batch, flights = numpy_flights(missions, specs)
    want = summaries(flights)
    assert len(set(want.distance_m.tolist())) == 5
    assert_summaries_equal(compiled_summaries(batch, missions), want)
    assert_summaries_equal(flights_summaries(flights, use_numba=False), want)
