"""Random fault processes as pure functions of a numpy Generator, vectorised over missions.

Every function returns arrays with a leading missions axis M (then slots T, then sensors or
coordinates), so a batch of missions is drawn in one call and one mission is the M = 1 case.
Nothing here knows about engines or policies: :mod:`skymule.faults.draws` assembles these
into per-mission masks, and ``docs/faults.md`` states how engines apply them.
"""

from __future__ import annotations

import math

import numpy as np

from skymule.faults.specs import OutageParams


def stationary_bad_share(p_good_to_bad: float, p_bad_to_good: float) -> float:
    """pi_B = p / (p + r): long-run share of slots a two-state chain spends in the bad state."""
    return p_good_to_bad / (p_good_to_bad + p_bad_to_good)


def _run_lengths(rng: np.random.Generator, p_leave: float, count: int, n_slots: int) -> np.ndarray:
    """``count`` sojourn lengths [slots] in a state left with probability ``p_leave`` a slot."""
    if p_leave == 0.0:
        return np.full(count, n_slots, dtype=np.int64)  # never left within the mission
    # a sojourn past the mission's end is cut there (p ~ 1e-300 draws ~2^63: sums overflow)
    return np.minimum(rng.geometric(p_leave, count), n_slots)


def _one_chain(rng: np.random.Generator, p: float, r: float, n_slots: int) -> np.ndarray:
    """(T,) bool, True in the bad state; starts in the stationary distribution.

    Drawn as alternating geometric sojourns (good: Geometric(p), bad: Geometric(r)) instead of
    slot by slot, so 10^6 slots take a few thousand draws. A chain that starts in a state
    keeps it for a Geometric sojourn too (memorylessness), so the result has the law of the
    slot-by-slot chain.
    """
    if n_slots == 0:
        return np.zeros(0, dtype=bool)
    bad = bool(rng.random() < stationary_bad_share(p, r))
    mean_cycle = (1.0 / p if p > 0 else n_slots) + (1.0 / r if r > 0 else n_slots)
    pieces: list[np.ndarray] = []
    states: list[np.ndarray] = []
    total = 0
    while total < n_slots:
        cycles = int(min(n_slots, (n_slots - total) / mean_cycle * 1.2 + 8))
        first = _run_lengths(rng, r if bad else p, cycles, n_slots)
        second = _run_lengths(rng, p if bad else r, cycles, n_slots)
        pieces.append(np.column_stack([first, second]).ravel())
        states.append(np.tile([bad, not bad], cycles))
        total += int(pieces[-1].sum())
    return np.repeat(np.concatenate(states), np.concatenate(pieces))[:n_slots]


def two_state_chain(
    rng: np.random.Generator, p_good_to_bad: float, p_bad_to_good: float, shape: tuple[int, ...]
) -> np.ndarray:
    """Gilbert-Elliott state, True = bad, of shape ``(..., T)``: independent chains along the
    last axis (time), each started in its stationary distribution.

    Gilbert, "Capacity of a burst-noise channel", Bell Syst. Tech. J. 39(5):1253-1265, 1960;
    Elliott, "Estimates of error rates for codes on burst-noise channels", Bell Syst. Tech. J.
    42(5):1977-1997, 1963. One step a slot: good -> bad with probability p, bad -> good with r.
    """
    *lead, n_slots = shape
    chains = math.prod(lead)
    out = np.empty((chains, n_slots), dtype=bool)
    for c in range(chains):
        out[c] = _one_chain(rng, p_good_to_bad, p_bad_to_good, n_slots)
    return out.reshape(shape)


def gilbert_elliott_loss(
    rng: np.random.Generator,
    p_good_to_bad: float,
    p_bad_to_good: float,
    loss_good: float,
    loss_bad: float,
    shape: tuple[int, ...],
) -> np.ndarray:
    """Lost slots, True = no data, of shape ``(..., T)`` (time last)."""
    bad = two_state_chain(rng, p_good_to_bad, p_bad_to_good, shape)
    if loss_good == 0.0 and loss_bad == 1.0:
        return bad  # the classic Gilbert channel: everything lost in the bad state
    return rng.random(shape) < np.where(bad, loss_bad, loss_good)


def outage_windows(
    rng: np.random.Generator, params: OutageParams, shape: tuple[int, int, int], slot_s: float
) -> np.ndarray:
    """(M, T, K) bool, True while an outage window covers the slot's start time.

    K is the number of affected sensors. A fixed window (``start_s`` and ``duration_s``) is
    the same for all of them; otherwise each (mission, sensor) draws ``windows`` windows with
    start uniform over the mission and/or exponential length.
    """
    n_missions, n_slots, n_sensors = shape
    start_of_slot = np.arange(n_slots) * slot_s  # (T,)
    out = np.zeros(shape, dtype=bool)
    size = (n_missions, 1, n_sensors)
    for _ in range(params.windows):
        if params.start_s is not None:
            start = np.full(size, params.start_s)
        else:
            start = rng.uniform(0.0, n_slots * slot_s, size)
        if params.duration_s is not None:
            length = np.full(size, params.duration_s)
        else:
            assert params.mean_duration_s is not None  # checked by OutageParams
            length = rng.exponential(params.mean_duration_s, size)
        t = start_of_slot[None, :, None]
        out |= (t >= start) & (t < start + length)
    return out


def ar1_normal(rng: np.random.Generator, shape: tuple[int, ...], correlation: float) -> np.ndarray:
    """Standard normal noise along axis 1 (time), AR(1) with lag-one ``correlation`` in [0, 1).

    x_0 ~ N(0, 1); x_t = rho x_{t-1} + sqrt(1 - rho^2) e_t: every sample has unit variance.
    """
    noise = rng.standard_normal(shape)
    if correlation == 0.0:
        return noise
    if correlation >= 1.0:  # exp(-dt/tau) rounds to 1 for dt << tau: one draw held throughout
        return np.repeat(noise[:, :1], noise.shape[1], axis=1)
    from scipy.signal import lfilter  # ~0.2 s to import: only for correlated errors

    scale = math.sqrt(1.0 - correlation * correlation)
    noise[:, 0] /= scale  # so the filtered first sample is e_0 itself: stationary start
    return np.asarray(lfilter([scale], [1.0, -correlation], noise, axis=1))


def correlation_per_slot(correlation_s: float, slot_s: float) -> float:
    """Lag-one correlation exp(-slot_s / correlation_s) (0 for independent slots)."""
    return 0.0 if correlation_s == 0.0 else math.exp(-slot_s / correlation_s)
