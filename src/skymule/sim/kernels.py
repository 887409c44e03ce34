"""The slot contract for one mission at a time: scalar kernels a compiler can take as they are.

:mod:`skymule.rules.contract` states each rule once, vectorised over missions (sensor-major
(N, B) arrays). A compiled loop runs one mission at a time in registers, so it needs the same
rules as plain functions of one mission's (N,) arrays and scalars. They are here, written in
the subset of Python and numpy that numba compiles (loops, scalar arithmetic, 1-D indexing);
nothing here imports a compiler, so the module also runs (slowly) as plain Python, which is
how the tests check each kernel against its vectorised original on random inputs.

The kernels compute what the vectorised functions compute (the same masks, the same maximum,
the same "first index equal to the maximum", in one pass over the sensors), so ties, empty
buffers, -inf and NaN resolve the same way: ``tests/test_compiled.py`` checks every kernel
against :mod:`~skymule.rules.contract` and the compiled batch against the numpy batch, value for
value. ``served_bits`` is not
repeated: the compiled core compiles :func:`skymule.rules.contract.served_bits` itself.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from skymule.rules.contract import HOVER_EPS_S, NO_SENSOR


def greedy_pick(snr_db: np.ndarray, rate_bps: np.ndarray, remaining_bit: np.ndarray) -> int:
    """One mission of ``contract.greedy_choice`` over ``contract.servable`` sensors: argmax
    SNR among sensors with data and R > 0, in one pass.

    As the vectorised rule: the masked SNR (-inf where not servable) is maximised and the
    first index equal to the maximum wins; a NaN maximum equals nothing, which gives index 0.
    """
    any_data = False
    nan = False
    best = -np.inf
    index = 0
    for i in range(snr_db.shape[0]):
        has_data = remaining_bit[i] > 0 and rate_bps[i] > 0
        any_data = any_data or has_data
        value = snr_db[i] if has_data else -np.inf
        if value != value:
            nan = True
        elif i == 0 or value > best:  # strictly greater: ties keep the first index
            best, index = value, i
    if not any_data:
        return NO_SENSOR
    return 0 if nan else index


def hgad_pick(rate_bps: np.ndarray, snr_db: np.ndarray, remaining_bit: np.ndarray) -> int:
    """One mission of ``contract.hgad_choice`` over ``contract.servable`` sensors: argmax rate;
    ties: higher SNR, lowest index; in one pass.

    The masked rate is never NaN (servable needs R > 0); among the sensors at the best rate,
    the first with the best SNR wins, and a NaN SNR among them equals nothing (index 0), as
    in the vectorised rule.
    """
    any_data = False
    best_rate = -np.inf
    best_snr = -np.inf
    nan = False
    index = 0
    for i in range(rate_bps.shape[0]):
        if not (remaining_bit[i] > 0 and rate_bps[i] > 0):
            continue
        any_data = True
        rate, snr = rate_bps[i], snr_db[i]
        if rate > best_rate:  # a new best rate: its sensor alone is tied so far
            best_rate, best_snr, nan, index = rate, snr, snr != snr, i
        elif rate == best_rate and not nan:
            if snr != snr:
                nan = True
            elif snr > best_snr:
                best_snr, index = snr, i
    if not any_data:
        return NO_SENSOR
    return 0 if nan else index


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


def step_rate(
    snr_db: float, thresholds_db: np.ndarray, efficiency: np.ndarray, bandwidth_hz: float
) -> float:
    """``rate_bps(StepTable, snr_db, bandwidth_hz)`` for one SNR: the efficiency of the
    number of thresholds reached (``searchsorted(side="right")`` on ascending thresholds; NaN
    reaches none) x bandwidth."""
    reached = 0
    for threshold in thresholds_db:
        if threshold <= snr_db:
            reached += 1
    return efficiency[reached] * bandwidth_hz


def fault_view(
    rate_bps: np.ndarray,
    snr_db: np.ndarray,
    sample: int,
    deliverable: np.ndarray,
    snr_error_db: np.ndarray,
    slot: int,
    uses_error: bool,
    thresholds_db: np.ndarray,
    efficiency: np.ndarray,
    bandwidth_hz: float,
    seen_rate_bps: np.ndarray,
    seen_snr_db: np.ndarray,
    deliver_bps: np.ndarray,
) -> None:
    """One mission, one slot of ``batch_faults.apply_faults`` (``docs/faults.md``): fills what
    the policy sees (SNR + error where deliverable, else -inf, and its rate) and what a
    served sensor delivers (the true rate where deliverable, else 0).

    The true rate and SNR are row ``sample`` of the mission's track, ``rate_bps`` /
    ``snr_db`` (K, N); its draws are row ``slot`` of ``deliverable`` / ``snr_error_db``
    (T, N). Without an SNR error the seen rate is the true rate where deliverable (the rate table of
    the unchanged SNR); a blocked link's seen rate is that of -inf, 0 in every table. Reads by
    index, no array views per slot.
    """
    for i in range(seen_rate_bps.shape[0]):
        rate, snr = rate_bps[sample, i], snr_db[sample, i]
        if deliverable[slot, i]:
            seen = snr + snr_error_db[slot, i]
            seen_snr_db[i] = seen
            if uses_error:
                seen_rate_bps[i] = step_rate(seen, thresholds_db, efficiency, bandwidth_hz)
            else:
                seen_rate_bps[i] = rate
            deliver_bps[i] = rate
        else:
            seen_snr_db[i] = -np.inf
            seen_rate_bps[i] = 0.0
            deliver_bps[i] = 0.0


class KernelFaults(NamedTuple):
    """The fault draws of a batch as the compiled loop reads them, mission by mission.

    Attributes:
        fault_of: (B,) each mission's row g in the arrays below, -1 without faults.
        deliverable: (G, T_max, N) ``BatchFaults.deliverable``.
        snr_error_db: (G, T_max, N) ``BatchFaults.snr_error_db``.
        uses_error: (G,) True where some error is non-zero: the seen rate is then looked up
            in the mission's rate table; elsewhere it is the true rate (or 0 where blocked).
        model: (G,) each mission's rate model (a row of the tables below).
        thresholds_db: (M, L) the step tables' thresholds, padded with +inf.
        efficiency: (M, L + 1) efficiency of 0, 1, ... L thresholds reached [bit/s/Hz].
        bandwidth_hz: (M,) bandwidth of each model [Hz].
    """

    fault_of: np.ndarray
    deliverable: np.ndarray
    snr_error_db: np.ndarray
    uses_error: np.ndarray
    model: np.ndarray
    thresholds_db: np.ndarray
    efficiency: np.ndarray
    bandwidth_hz: np.ndarray
