"""The slot contract for one mission at a time: scalar kernels a compiler can take as they are.

:mod:`skymule.sim.contract` states each rule once, vectorised over missions (sensor-major
(N, B) arrays). A compiled loop runs one mission at a time in registers, so it needs the same
rules as plain functions of one mission's (N,) arrays and scalars. They are here, written in
the subset of Python and numpy that numba compiles (loops, scalar arithmetic, 1-D indexing);
nothing here imports a compiler, so the module also runs (slowly) as plain Python, which is
how the tests check each kernel against its vectorised original on random inputs.

The kernels mirror the vectorised functions step by step (the same masks, the same maximum,
the same "first index equal to the maximum"), so ties, empty buffers, -inf and NaN resolve the
same way: ``tests/test_compiled.py`` checks every kernel against :mod:`~skymule.sim.contract`
and the compiled batch against the numpy batch, value for value. ``served_bits`` is not
repeated: the compiled core compiles :func:`skymule.sim.contract.served_bits` itself.
"""

from __future__ import annotations

import numpy as np

from skymule.sim.contract import HOVER_EPS_S, NO_SENSOR


def column_max(values: np.ndarray) -> float:
    """The largest of ``values`` (N,), NaN if any is NaN (as ``ndarray.max``)."""
    best = values[0]
    for i in range(1, values.shape[0]):
        value = values[i]
        if value > best or value != value:  # once NaN, best stays NaN
            best = value
    return best


def first_equal(values: np.ndarray, target: float) -> int:
    """First index i with values[i] == target, 0 if none (as ``contract.first_true``)."""
    for i in range(values.shape[0]):
        if values[i] == target:
            return i
    return 0


def greedy_pick(
    snr_db: np.ndarray, rate_bps: np.ndarray, remaining_bit: np.ndarray, masked: np.ndarray
) -> int:
    """One mission of ``contract.greedy_choice`` over ``contract.servable`` sensors: argmax
    SNR among sensors with data and R > 0. ``masked`` is (N,) scratch space.
    """
    any_data = False
    for i in range(snr_db.shape[0]):
        has_data = remaining_bit[i] > 0 and rate_bps[i] > 0
        any_data = any_data or has_data
        masked[i] = snr_db[i] if has_data else -np.inf
    if not any_data:
        return NO_SENSOR
    return first_equal(masked, column_max(masked))


def hgad_pick(
    rate_bps: np.ndarray, snr_db: np.ndarray, remaining_bit: np.ndarray, masked: np.ndarray
) -> int:
    """One mission of ``contract.hgad_choice`` over ``contract.servable`` sensors: argmax rate;
    ties: higher SNR, lowest index. ``masked`` is (N,) scratch space.
    """
    n = rate_bps.shape[0]
    any_data = False
    for i in range(n):
        has_data = remaining_bit[i] > 0 and rate_bps[i] > 0
        any_data = any_data or has_data
        masked[i] = rate_bps[i] if has_data else -np.inf
    if not any_data:
        return NO_SENSOR
    best_rate = column_max(masked)
    for i in range(n):
        masked[i] = snr_db[i] if masked[i] == best_rate else -np.inf
    best_snr = column_max(masked)
    for i in range(n):  # first i with masked rate == its max and masked SNR == its max
        masked_rate = rate_bps[i] if remaining_bit[i] > 0 and rate_bps[i] > 0 else -np.inf
        if masked_rate == best_rate and masked[i] == best_snr:
            return i
    return 0


def hgad_hover_step(
    hover: np.ndarray,
    cooling: np.ndarray,
    sensor: int,
    rate_bps: np.ndarray,
    left_after_bit: float,
    threshold_bps: np.ndarray,
    peak_rate_bps: np.ndarray,
    max_hover_s: float,
    slot_s: float,
    enabled: bool,
) -> bool:
    """One mission, one slot of ``contract.hgad_update``; True where the UAV holds position.

    Args:
        hover: (2,) state [hovered sensor (NO_SENSOR: none), budget left [s]], updated in place.
        cooling: (N,) True where a sensor cools down, updated in place.
        sensor: sensor served this slot (the hovered one while hovering), or NO_SENSOR.
        rate_bps: (N,) rates this slot [bit/s].
        left_after_bit: the served sensor's buffer after this slot [bit].
        threshold_bps: (N,) trigger thresholds [bit/s]; peak_rate_bps: (N,) peaks R*_i.
        max_hover_s: longest hover [s]; slot_s: slot length [s].
        enabled: False for a policy that never hovers (Greedy).
    """
    hovering = hover[0] >= 0
    for i in range(cooling.shape[0]):
        cooling[i] = cooling[i] and not (rate_bps[i] < threshold_bps[i])
    cell = max(sensor, 0)
    if hovering:
        hover[1] -= slot_s
        if hover[1] <= HOVER_EPS_S or left_after_bit <= 0:
            cooling[cell] = True
            hover[0] = NO_SENSOR
        return True
    if not enabled or sensor < 0:
        return False
    rate = rate_bps[cell]
    peak = peak_rate_bps[cell]
    if (
        rate > 0
        and peak > 0
        and rate >= threshold_bps[cell]
        and left_after_bit > 0
        and not cooling[cell]
    ):
        budget = left_after_bit / peak
        # np.minimum for scalars: NaN if either is NaN
        hover[1] = budget if budget <= max_hover_s or budget != budget else max_hover_s
        hover[0] = sensor
        return True
    return False
