"""The pure metrics of ``skymule sim2real`` (:mod:`skymule.metrics.sim2real`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from skymule.metrics.sim2real import (
    Bootstrap,
    Estimate,
    block_bootstrap,
    block_indices,
    coverage,
    execute,
    fit_log_distance,
    on_path_slots,
    own_error_defined,
    rank_by,
    regret,
    relative_change,
    running_median,
    snr_errors,
)
from skymule.rules.contract import NO_SENSOR


def _mean(x: np.ndarray) -> np.ndarray:
    return np.mean(x, axis=-1)


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    """A stationary AR(1) series of unit innovations (its mean is 0)."""
    shocks = rng.standard_normal(n)
    x = np.empty(n)
    x[0] = shocks[0] / math.sqrt(1 - phi**2)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + shocks[i]
    return x


def _coverage_of_mean(phi: float, block: int, datasets: int = 200) -> float:
    rng = np.random.default_rng(5)
    hits = 0
    for k in range(datasets):
        x = 3.0 + _ar1(rng, 300, phi)
        estimate = block_bootstrap(_mean, [x], Bootstrap(block=block, resamples=300, seed=k))
        hits += estimate.low <= 3.0 <= estimate.high
    return hits / datasets


def test_the_90_percent_interval_covers_a_known_mean() -> None:
    """Over 200 independent series the 90% interval holds the true mean about 90% of the
    time (measured 90%; binomial sd 2.1 points); on serially correlated samples only blocks
    keep it:
    one-sample blocks cover less than 60% (measured 41%), 20-sample blocks 75% or more
    (measured 80.5%)."""
    assert 0.82 <= _coverage_of_mean(0.0, 10) <= 0.96
    assert _coverage_of_mean(0.8, 1) < 0.6
    assert _coverage_of_mean(0.8, 20) >= 0.75


def test_bootstrap_is_seeded_and_blocks_are_consecutive() -> None:
    x = np.random.default_rng(0).standard_normal(97)
    first = block_bootstrap(_mean, [x], Bootstrap(seed=3))
    assert first == block_bootstrap(_mean, [x], Bootstrap(seed=3))
    assert first != block_bootstrap(_mean, [x], Bootstrap(seed=4))
    assert first.value == pytest.approx(x.mean())
    rows = block_indices(97, 10, 50, np.random.default_rng(1))
    assert rows.shape == (50, 97) and rows.min() >= 0 and rows.max() <= 96
    steps = np.diff(rows.reshape(50, -1)[:, :90].reshape(50, 9, 10), axis=2)
    assert np.all(steps == 1)  # inside a block, consecutive samples
    assert math.isnan(block_bootstrap(_mean, [x[:1]]).value)  # one sample: no estimate


def test_snr_errors_and_coverage_match_their_definitions() -> None:
    rng = np.random.default_rng(2)
    measured = rng.normal(20.0, 5.0, 400)
    predicted = measured + 2.0 + rng.standard_normal(400)
    scores = snr_errors(predicted, measured)
    error = predicted - measured
    assert scores["bias_db"].value == pytest.approx(error.mean())
    assert scores["rmse_db"].value == pytest.approx(np.sqrt(np.mean(error**2)))
    assert scores["mae_db"].value == pytest.approx(np.abs(error).mean())
    assert scores["bias_db"].low < 2.0 < scores["bias_db"].high
    # a sigma that is right covers ~95%; one 3x too small covers far less
    right = coverage(predicted - 2.0, np.ones(400), measured)
    assert 0.9 < right.value <= 1.0
    assert coverage(predicted - 2.0, np.full(400, 1 / 3), measured).value < 0.6


def test_running_median_removes_spikes_and_log_distance_recovers_a_trend() -> None:
    values = np.full(30, 10.0)
    values[[5, 17]] = 40.0
    assert np.all(running_median(values, 5) == 10.0)
    distance = np.geomspace(20.0, 2000.0, 200)
    fitted = fit_log_distance(distance, 80.0 - 27.0 * np.log10(distance))
    assert fitted.intercept_db == pytest.approx(80.0) and fitted.slope_db == pytest.approx(27.0)
    assert fit_log_distance(np.full(5, 100.0), np.arange(5.0)).slope_db == 0.0


def test_execute_is_the_slot_contract() -> None:
    """y = min(R dt, Q) per served slot, the buffer shrinking; an empty buffer gives 0."""
    rates = np.array([[4e6, 1e6], [2e6, 3e6], [5e6, 5e6]])
    sample = np.array([0, 1, 1, 2])
    served = np.array([0, 1, NO_SENSOR, 0])
    bits = execute(rates, sample, served, np.array([5e6, 1e9]), slot_s=1.0)
    np.testing.assert_array_equal(bits, [4e6, 3e6, 0.0, 1e6])
    # a sample past the table's end holds the last row
    assert execute(rates, np.array([9]), np.array([1]), np.array([1e9, 1e9]), 2.0)[0] == 1e7


def test_regret_and_same_decisions_error_of_a_twin_equal_to_the_real_trace_are_zero() -> None:
    rng = np.random.default_rng(4)
    real = rng.uniform(0, 5e6, 300)
    for estimate in (regret(real, real), relative_change(real, real)):
        assert estimate == Estimate(0.0, 0.0, 0.0)


def test_a_biased_twin_with_the_same_decisions_has_no_regret_but_a_rate_error() -> None:
    """A twin 20% optimistic everywhere picks the same sensors (the argmax is unchanged):
    what trusting it costs is 0, but its Mbit along those decisions are 20% too many."""
    rng = np.random.default_rng(6)
    real_rates = rng.uniform(1e5, 5e6, (200, 3))
    twin_rates = 1.2 * real_rates
    sample = np.arange(200)
    buffers = np.full(3, 1e12)
    decide = np.argmax  # a greedy rule: the best rate in each slot

    on_real = decide(real_rates, axis=1)
    on_twin = decide(twin_rates, axis=1)
    best = execute(real_rates, sample, on_real, buffers, 1.0)
    executed = execute(real_rates, sample, on_twin, buffers, 1.0)
    assert regret(executed, best).value == 0.0
    same = relative_change(execute(twin_rates, sample, on_real, buffers, 1.0), best)
    assert same.value == pytest.approx(0.2)
    assert same.low == pytest.approx(0.2) and same.high == pytest.approx(0.2)
    # a twin that ranks the sensors wrongly costs something
    wrong = execute(real_rates, sample, np.argmin(real_rates, axis=1), buffers, 1.0)
    assert regret(wrong, best).low > 0.3


def test_own_error_is_defined_only_without_hovering_and_on_path_until_a_hover() -> None:
    still = np.zeros(5, bool)
    hover = np.array([False, True, False, False, False])
    assert own_error_defined(still, still)
    assert not own_error_defined(hover, still) and not own_error_defined(still, hover)
    # both on the recorded path up to and including the slot after which one first hovers
    assert on_path_slots(still, still) == 5
    assert on_path_slots(hover, still) == 2
    assert on_path_slots(still, np.array([False, False, False, True, True])) == 4


def test_rank_by_puts_nan_last_and_keeps_ties_in_order() -> None:
    keys = [(0.2, 1.0), (math.nan, 0.0), (0.1, 5.0), (0.2, 0.5), (0.2, 1.0)]
    assert rank_by(keys) == [2, 3, 0, 4, 1]


def test_scaled_estimates_keep_low_below_high() -> None:
    flipped = Estimate(0.1, 0.05, 0.2).scaled(-100.0)
    assert flipped.value == pytest.approx(-10.0)
    assert flipped.low == pytest.approx(-20.0) and flipped.high == pytest.approx(-5.0)
