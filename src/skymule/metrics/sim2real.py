"""Pure metrics of ``skymule sim2real``: which twin to trust, with confidence intervals.

Everything here works on arrays and knows nothing of scenarios or files:

* :func:`block_bootstrap`: a statistic of paired series with a moving-block bootstrap
  confidence interval (Künsch 1989: blocks of ``block`` consecutive samples drawn with
  replacement and laid end to end, so the serial correlation of a flight's samples stays
  inside each block; the interval is the percentile interval of the resampled statistic);
* :func:`snr_errors`, :func:`rate_errors`, :func:`coverage`: the per-tower scores;
* :func:`running_median`, :func:`fit_log_distance`: the reference rows (the trace's noise
  floor, log-distance fitted on a calibration set or refitted on the scored samples);
* :func:`execute`: serving decisions executed on a table of rates (``y = min(R dt, Q)``, the
  slot contract), from which :func:`relative_change` gives the same-decisions error, the
  decision regret and the policy's own error;
* :func:`own_error_defined`, :func:`rank_by`: when a policy's own Mbit compares like with like,
  and the ranking of twins by their decision regret.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.rules.contract import NO_SENSOR, served_bits
from skymule.units import BITS_PER_MBIT

BLOCK_SAMPLES = 10
"""Consecutive samples per bootstrap block (10 s at one sample a second: several shadowing
decorrelation lengths at survey speed)."""
RESAMPLES = 1000
"""Bootstrap resamples."""
CI_LEVEL = 0.90
"""Two-sided confidence level of every interval."""
NOISE_WINDOW = 5
"""Samples in the running median whose residual is the trace's noise floor."""
COVERAGE_Z = 1.959964
"""Two-sided 95% normal quantile: a twin's interval is prediction +- COVERAGE_Z sigma."""


@dataclass(frozen=True)
class Bootstrap:
    """How confidence intervals are drawn: a seeded moving-block bootstrap.

    Attributes:
        block: consecutive samples (or slots) per block.
        resamples: number of bootstrap resamples.
        level: two-sided confidence level (0.90: the 5th to the 95th percentile).
        seed: seed of the numpy Generator (one fresh Generator per statistic, so every
            number is reproducible on its own).
    """

    block: int = BLOCK_SAMPLES
    resamples: int = RESAMPLES
    level: float = CI_LEVEL
    seed: int = 0

    def to_json(self) -> dict[str, Any]:
        return {
            "method": "moving-block bootstrap, percentile interval",
            "block": self.block,
            "resamples": self.resamples,
            "level": self.level,
            "seed": self.seed,
        }


@dataclass(frozen=True)
class Estimate:
    """A number with its confidence interval [low, high] (NaN: not estimable)."""

    value: float
    low: float
    high: float

    @property
    def ci(self) -> tuple[float, float]:
        return (self.low, self.high)

    def scaled(self, factor: float) -> Estimate:
        """The estimate times ``factor`` (a negative factor swaps the interval's ends)."""
        ends = sorted((self.low * factor, self.high * factor))
        if any(math.isnan(e) for e in ends):
            ends = [math.nan, math.nan]
        return Estimate(self.value * factor, ends[0], ends[1])


NAN_ESTIMATE = Estimate(math.nan, math.nan, math.nan)
DEFAULT_BOOTSTRAP = Bootstrap()
"""Block of :data:`BLOCK_SAMPLES`, :data:`RESAMPLES` resamples, 90%, seed 0."""


def block_indices(n: int, block: int, resamples: int, rng: np.random.Generator) -> np.ndarray:
    """(resamples, n) indices of moving-block resamples of a series of length ``n``.

    Each row lays ceil(n / L) blocks of L = min(block, n) consecutive indices end to end,
    each starting uniformly in [0, n - L], and keeps the first n.
    """
    length = max(1, min(block, n))
    count = -(-n // length)
    starts = rng.integers(0, n - length + 1, size=(resamples, count))
    rows = (starts[:, :, None] + np.arange(length)).reshape(resamples, -1)
    return rows[:, :n]


def block_bootstrap(
    statistic: Callable[..., np.ndarray],
    series: Sequence[np.ndarray],
    boot: Bootstrap = DEFAULT_BOOTSTRAP,
) -> Estimate:
    """``statistic`` of paired ``series`` (each (n,)) and its block-bootstrap interval.

    ``statistic`` takes the series as arrays of shape (..., n) and reduces the last axis: it
    is called once on the data and once on all (resamples, n) resamples together. Fewer than
    two samples: NaN.
    """
    arrays = [np.asarray(s, float) for s in series]
    n = arrays[0].shape[0]
    if any(a.shape != (n,) for a in arrays):
        raise ValueError("block_bootstrap: every series needs the same shape (n,)")
    if n < 2:
        return NAN_ESTIMATE
    value = float(statistic(*arrays))
    rng = np.random.default_rng(boot.seed)
    rows = block_indices(n, boot.block, boot.resamples, rng)
    draws = np.asarray(statistic(*(a[rows] for a in arrays)), float)
    draws = draws[np.isfinite(draws)]
    if not draws.size or not math.isfinite(value):
        return Estimate(value, math.nan, math.nan)
    tail = 100.0 * (1.0 - boot.level) / 2.0
    low, high = np.percentile(draws, [tail, 100.0 - tail])
    return Estimate(value, float(low), float(high))


def _rmse(error: np.ndarray) -> np.ndarray:
    return np.sqrt(np.mean(error**2, axis=-1))


def _bias(error: np.ndarray) -> np.ndarray:
    return np.mean(error, axis=-1)


def _mae(error: np.ndarray) -> np.ndarray:
    return np.mean(np.abs(error), axis=-1)


def snr_errors(
    predicted_db: np.ndarray, measured_db: np.ndarray, boot: Bootstrap = DEFAULT_BOOTSTRAP
) -> dict[str, Estimate]:
    """RMSE, bias (predicted - measured) and MAE [dB] of one tower's paired samples (S,),
    in time order, each with its block-bootstrap interval. Pass valid samples only."""
    error = np.asarray(predicted_db, float) - np.asarray(measured_db, float)
    return {
        "rmse_db": block_bootstrap(_rmse, [error], boot),
        "bias_db": block_bootstrap(_bias, [error], boot),
        "mae_db": block_bootstrap(_mae, [error], boot),
    }


def rate_errors(
    predicted_bps: np.ndarray, measured_bps: np.ndarray, boot: Bootstrap = DEFAULT_BOOTSTRAP
) -> dict[str, Estimate]:
    """RMSE and bias (predicted - measured) of a rate [Mbit/s] from paired rates [bit/s]."""
    error = (np.asarray(predicted_bps, float) - np.asarray(measured_bps, float)) / BITS_PER_MBIT
    return {
        "rate_rmse_mbps": block_bootstrap(_rmse, [error], boot),
        "rate_bias_mbps": block_bootstrap(_bias, [error], boot),
    }


def coverage(
    predicted_db: np.ndarray,
    sigma_db: np.ndarray,
    measured_db: np.ndarray,
    boot: Bootstrap = DEFAULT_BOOTSTRAP,
) -> Estimate:
    """Share of measurements inside the twin's 95% interval (prediction +- COVERAGE_Z sigma)."""
    inside = np.abs(np.asarray(predicted_db) - measured_db) <= COVERAGE_Z * np.asarray(sigma_db)
    return block_bootstrap(_bias, [inside.astype(float)], boot)


def running_median(values: np.ndarray, window: int = NOISE_WINDOW) -> np.ndarray:
    """(S,) centred running median of ``values`` over ``window`` samples (edges repeated).

    Its residual ``values - running_median(values)`` is the trace's noise floor: what no
    smooth map can predict.
    """
    from scipy.ndimage import median_filter

    half = max(window, 1) // 2
    return median_filter(np.asarray(values, float), size=2 * half + 1, mode="nearest")


@dataclass(frozen=True)
class LogDistance:
    """SNR = intercept_db - slope_db * log10(d / 1 m): a least-squares trend of one tower."""

    intercept_db: float
    slope_db: float

    def snr_db(self, distance_m: np.ndarray) -> np.ndarray:
        """Predicted SNR [dB] at 3-D distances [m] (at least 1 m)."""
        return self.intercept_db - self.slope_db * np.log10(np.maximum(distance_m, 1.0))


def fit_log_distance(distance_m: np.ndarray, snr_db: np.ndarray) -> LogDistance:
    """The least-squares :class:`LogDistance` through (distance, SNR) samples (valid only).

    One sample, or one distance only: a flat fit (slope 0) through the mean.
    """
    x = np.log10(np.maximum(np.asarray(distance_m, float), 1.0))
    y = np.asarray(snr_db, float)
    if y.size == 0:
        raise ValueError("fit_log_distance: no samples")
    spread = x - x.mean()
    denominator = float(spread @ spread)
    if y.size < 2 or denominator <= 1e-12:
        return LogDistance(float(y.mean()), 0.0)
    slope = float(spread @ (y - y.mean())) / denominator
    return LogDistance(float(y.mean() - slope * x.mean()), -slope)


def execute(
    rate_bps: np.ndarray,
    sample: np.ndarray,
    served: np.ndarray,
    buffers_bit: np.ndarray,
    slot_s: float,
) -> np.ndarray:
    """(T,) bits delivered by serving decisions executed on a table of rates.

    Args:
        rate_bps: (K, N) rate to each sensor at each track sample [bit/s].
        sample: (T,) the track sample the UAV is at in each slot (clipped to K - 1).
        served: (T,) the sensor served in each slot, or NO_SENSOR.
        buffers_bit: (N,) data each sensor holds at the start [bit].
        slot_s: slot length [s].

    Each slot a served sensor delivers y = min(R dt, Q) (the slot contract) and its buffer
    shrinks by y; a decision to serve an empty buffer delivers nothing.
    """
    rates = np.asarray(rate_bps, float)
    at = np.minimum(np.asarray(sample, np.int64), rates.shape[0] - 1)
    who = np.asarray(served, np.int64)
    left = np.array(buffers_bit, float)
    bits = np.zeros(who.shape[0])
    for t in np.flatnonzero(who != NO_SENSOR):
        j = who[t]
        got = float(served_bits(rates[at[t], j], left[j], slot_s))
        bits[t] = got
        left[j] -= got
    return bits


def _change(after: np.ndarray, before: np.ndarray) -> np.ndarray:
    total = np.sum(before, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, (np.sum(after, axis=-1) - total) / total, np.nan)


def relative_change(
    after_bit: np.ndarray, before_bit: np.ndarray, boot: Bootstrap = DEFAULT_BOOTSTRAP
) -> Estimate:
    """(sum after - sum before) / sum before of two per-slot series (T,), with a block
    bootstrap over slots (the pairs of slot t resampled together). NaN when before is 0.

    * same-decisions error: after = the twin's bits, before = the real bits, same decisions;
    * the policy's own error: after = its bits on the twin, before = its bits on the trace;
    * decision regret: see :func:`regret`.
    """
    return block_bootstrap(_change, [after_bit, before_bit], boot)


def regret(
    executed_bit: np.ndarray, best_bit: np.ndarray, boot: Bootstrap = DEFAULT_BOOTSTRAP
) -> Estimate:
    """Decision regret: (sum best - sum executed) / sum best, with its interval.

    ``executed_bit``: the real bits of the decisions the policy made on the twin;
    ``best_bit``: the real bits of the policy run on the real trace. 0 when the twin leads to
    the same decisions; negative when its decisions happen to do better.
    """
    return relative_change(executed_bit, best_bit, boot).scaled(-1.0)


def own_error_defined(hover_real: np.ndarray, hover_twin: np.ndarray) -> bool:
    """True when a policy's own Mbit on the twin and on the real trace compare like with like.

    The recorded flight never hovers: slot t is at sample t. A policy that hovers freezes the
    sample index, so after its first hover it is somewhere the recorded flight was not at that
    time; its Mbit on the twin and on the trace then follow different paths.
    """
    return not (np.any(hover_real) or np.any(hover_twin))


def on_path_slots(hover_real: np.ndarray, hover_twin: np.ndarray) -> int:
    """Slots in which both sides are still on the recorded path with its timing: up to and
    including the first slot after which either side hovers (all slots if neither does)."""
    firsts = [int(np.argmax(h)) for h in (np.asarray(hover_real), np.asarray(hover_twin))
              if np.any(h)]  # fmt: skip
    if not firsts:
        return max(len(hover_real), len(hover_twin))
    return min(firsts) + 1


def rank_by(keys: Sequence[tuple[float, ...]]) -> list[int]:
    """Indices of ``keys`` in increasing lexicographic order, a NaN after every number (ties
    keep the given order)."""

    def key(i: int) -> tuple[Any, ...]:
        return tuple((not math.isfinite(v), v if math.isfinite(v) else 0.0) for v in keys[i])

    return sorted(range(len(keys)), key=key)


__all__ = [
    "BLOCK_SAMPLES",
    "CI_LEVEL",
    "COVERAGE_Z",
    "DEFAULT_BOOTSTRAP",
    "NAN_ESTIMATE",
    "NOISE_WINDOW",
    "RESAMPLES",
    "Bootstrap",
    "Estimate",
    "LogDistance",
    "block_bootstrap",
    "block_indices",
    "coverage",
    "execute",
    "fit_log_distance",
    "on_path_slots",
    "own_error_defined",
    "rank_by",
    "rate_errors",
    "regret",
    "relative_change",
    "running_median",
    "snr_errors",
]
