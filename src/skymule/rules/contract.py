"""The slot contract, executable: the one implementation every engine and policy calls.

The rules are stated in ``docs/contract.md``; this module is their numpy code. Functions are
vectorised over missions with sensor-major arrays, shape (N, B) for N sensors and B missions
(reductions over the short sensor axis then run as N elementwise steps over missions); one
mission is a batch of one (B = 1). The engines (``sim/fixed.py``, ``sim/autonomous.py``), the
built-in policies and the planner's look-ahead call these functions; the compiled fast path
calls their one-mission twins in :mod:`skymule.sim.kernels`, tested equal to them.

* :func:`served_bits` -- what a served sensor delivers in a slot, y = min(R dt, Q);
* :func:`greedy_choice` -- argmax SNR among sensors with data (ties: lowest index);
* :func:`hgad_choice` -- argmax rate among sensors with data (ties: higher SNR, lowest index);
* :func:`rate_choice` -- argmax rate among sensors with data (ties: lowest index): the planner's;
* :class:`HoverState`, :func:`hover_sensor_or`, :func:`hgad_update` -- HGAD's hover state
  machine on fixed trajectories (cooldown, trigger, budget);
* :func:`fleet_served` -- several UAVs: each sensor serves at most one UAV per slot (the
  higher rate wins a conflict, ties to the lower UAV index);
* :func:`serve_slot` -- the one place a slot's downloads leave the buffers: the window, fleet
  conflicts and faults settled, then y = min(R dt, Q) for every flight of a batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

NO_SENSOR = -1
"""Sensor index meaning "none": no sensor served, no hover, no target."""

HOVER_EPS_S = 1e-12
"""A hover ends once its remaining budget is at or below this [s] (round-off only)."""

ROUND_OFF = 1e-9
"""Relative slack of slot counts: a time or distance that is a whole number of slots (or
steps) up to float round-off counts as that number, not one more."""


def seen_snr_db(snr_db: Any) -> Any:
    """SNR as policies and rate tables read it: NaN (no link, no sample) becomes -inf."""
    snr = np.asarray(snr_db, float)
    return np.where(np.isnan(snr), -np.inf, snr)


def slots_to_cover(amount: Any, per_slot: Any) -> Any:
    """Whole slots (or steps) that cover ``amount`` at ``per_slot`` each: ceil(amount /
    per_slot), a whole number up to round-off counting as itself (elementwise; a float for
    scalars)."""
    return np.ceil(np.asarray(amount, float) / per_slot - ROUND_OFF)


def window_slots(window_s: Any, slot_s: Any) -> Any:
    """Slots k that start inside a download window: k * slot_s < window_s - ROUND_OFF, i.e.
    the first ``window_slots`` slots (elementwise). The engines stop serving from there and the
    AADM score counts nothing after it."""
    return np.ceil((np.asarray(window_s, float) - ROUND_OFF) / slot_s)


def served_bits(rate_bps: Any, remaining_bit: Any, slot_s: Any) -> Any:
    """Bits a served sensor delivers in one slot: y = min(R * dt, Q) (elementwise, any shape).

    Args:
        rate_bps: rate of the served sensor [bit/s].
        remaining_bit: data it holds at the start of the slot [bit].
        slot_s: slot length dt [s].
    """
    return np.minimum(rate_bps * slot_s, remaining_bit)


def fleet_served(choice: np.ndarray, chosen_rate_bps: np.ndarray) -> np.ndarray:
    """(K, B) the sensor each of K UAVs serves this slot, given what each chose.

    Every UAV serves at most one sensor (its choice) and every sensor serves at most one UAV:
    when several UAVs choose the same sensor, the one with the highest rate to it gets it, ties
    to the lowest UAV index; the others serve nothing this slot (NO_SENSOR).

    Args:
        choice: (K, B) sensor each UAV chose, or NO_SENSOR.
        chosen_rate_bps: (K, B) each UAV's rate to the sensor it chose [bit/s] (any value
            where it chose none).
    """
    uav = np.arange(choice.shape[0])[:, None, None]
    # [k, j, b]: UAV j chose the same sensor as UAV k and beats it
    same = (choice[:, None, :] == choice[None, :, :]) & (choice[:, None, :] >= 0)
    rate_k, rate_j = chosen_rate_bps[:, None, :], chosen_rate_bps[None, :, :]
    beats = (rate_j > rate_k) | ((rate_j == rate_k) & (uav.transpose(1, 0, 2) < uav))
    lost = (same & beats).any(axis=1)
    return np.where(lost, NO_SENSOR, choice)


def serve_slot(
    sensor: np.ndarray,
    deliver_bps: np.ndarray,
    deliverable: np.ndarray | None,
    remaining_bit: np.ndarray,
    group: np.ndarray,
    uavs: int,
    slot_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One slot's downloads of B flights: (served (B,), bits (B,), lost (B,) or None).

    The one place bits leave buffers. Flights are columns; ``group`` names the buffers each
    one downloads from (the UAVs of a fleet mission share theirs, K = ``uavs`` contiguous
    columns per mission). In order:

    1. UAVs of one fleet mission that chose the same sensor: :func:`fleet_served` (the higher
       rate to it wins, ties to the lower UAV index); the others lose it (``lost``);
    2. a fault blocks a link (``deliverable`` False): nothing is served there;
    3. each served sensor delivers y = min(R dt, Q) at its true rate (:func:`served_bits`),
       taken from its buffer in place (no sensor is served twice in one mission).

    Args:
        sensor: (B,) the sensor each flight's policy chose (NO_SENSOR: none, and for flights
            that are over or whose download window has closed).
        deliver_bps: (N, B) the rate a served sensor delivers at [bit/s] (C order).
        deliverable: (N, B) False where a fault blocks the link, or None (no faults).
        remaining_bit: (N, G) buffers [bit] (C order), updated in place.
        group: (B,) each flight's buffer column.
        uavs: K, the UAVs of each fleet mission (1: every flight is a mission of its own).
        slot_s: (B,) slot length [s].
    """
    columns = np.arange(sensor.shape[0])
    cell = cells(sensor, columns)
    rate = deliver_bps.reshape(-1).take(cell)
    lost = None
    if uavs > 1:
        k, g = uavs, sensor.shape[0] // uavs
        won = fleet_served(sensor.reshape(g, k).T, rate.reshape(g, k).T).T.reshape(-1)
        lost = (sensor != NO_SENSOR) & (won == NO_SENSOR)
        sensor = won
    if deliverable is not None:
        sensor = np.where(deliverable.reshape(-1).take(cell), sensor, NO_SENSOR)
    flat = remaining_bit.reshape(-1)
    if uavs == 1:  # buffers are (N, B): a flight that serves nobody rewrites its row 0 as it is
        left = flat.take(cell)
        bits = served_bits(rate, left, slot_s)
        bits[sensor < 0] = 0.0
        flat[cell] = left - bits
        return sensor, bits, lost
    cell = np.maximum(sensor, 0) * remaining_bit.shape[1] + group
    left = flat.take(cell)
    bits = served_bits(rate, left, slot_s)
    bits[sensor < 0] = 0.0
    serving = np.flatnonzero(sensor >= 0)
    flat[cell[serving]] = left[serving] - bits[serving]
    return sensor, bits, lost


def servable(rate_bps: np.ndarray, remaining_bit: np.ndarray) -> np.ndarray:
    """True where a sensor can be served: it has data left and a usable link (R > 0).

    A policy whose every sensor is unservable serves nothing (rather than a sensor that would
    deliver 0 bits).
    """
    return (remaining_bit > 0) & (rate_bps > 0)


def first_true(mask: np.ndarray) -> np.ndarray:
    """(B,) index of the first True down each column of ``mask`` (N, B); 0 where none
    (``argmax`` returns the first of equal maxima, and 0 for a column of False)."""
    mask = np.asarray(mask, bool)
    if mask.shape[0] == 0:
        return np.zeros(mask.shape[1], np.int64)
    return mask.argmax(axis=0).astype(np.int64, copy=False)


def greedy_choice(snr_db: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) Greedy's sensor: argmax SNR among servable sensors, ties to the lowest index.

    Args:
        snr_db: (N, B) SNR the UAV observes [dB] (-inf: no link).
        has_data: (N, B) :func:`servable`: data left and a usable link.

    Returns:
        (B,) sensor index, or NO_SENSOR where no sensor is servable.
    """
    return _best_servable(snr_db, has_data)


def _best_servable(value: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) argmax of ``value`` (N, B) among servable sensors, ties to the lowest index;
    NO_SENSOR where none is servable."""
    masked = np.where(has_data, value, -np.inf)
    choice = first_true(masked == masked.max(axis=0))
    choice[~has_data.any(axis=0)] = NO_SENSOR
    return choice


def rate_choice(rate_bps: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) the best rate among servable sensors, ties to the lowest index (no SNR tie-break).

    The planner's choice on its way between targets and in its look-ahead
    (``policies/planner.py``, ``sim/plans.py``): the look-ahead predicts rates only, so the
    flight takes the rule its plan was scored with. HGAD (:func:`hgad_choice`) breaks rate ties
    by SNR instead (``tests/test_rules.py::test_rate_choice_differs_from_hgad_on_ties``).

    Args:
        rate_bps: (N, B) rate to each sensor [bit/s].
        has_data: (N, B) :func:`servable`: data left and a usable link.

    Returns:
        (B,) sensor index, or NO_SENSOR where no sensor is servable.
    """
    return _best_servable(rate_bps, has_data)


def hgad_choice(rate_bps: np.ndarray, snr_db: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) HGAD's sensor: argmax rate among servable sensors; ties: higher SNR, lowest index.

    Args:
        rate_bps: (N, B) rate to each sensor [bit/s].
        snr_db: (N, B) SNR the UAV observes [dB] (-inf: no link).
        has_data: (N, B) :func:`servable`: data left and a usable link.

    Returns:
        (B,) sensor index, or NO_SENSOR where no sensor is servable.
    """
    masked_rate = np.where(has_data, rate_bps, -np.inf)
    best = masked_rate == masked_rate.max(axis=0)
    masked_snr = np.where(best, snr_db, -np.inf)
    best &= masked_snr == masked_snr.max(axis=0)
    choice = first_true(best)
    choice[~has_data.any(axis=0)] = NO_SENSOR
    return choice


def cells(sensor: np.ndarray, columns: np.ndarray | None = None) -> np.ndarray:
    """(B,) flat index of (sensor[b], b) into a C-ordered (N, B) array (NO_SENSOR -> row 0).

    ``columns`` is ``np.arange(B)``, passed in by callers that step many slots.
    """
    columns = np.arange(sensor.shape[0]) if columns is None else columns
    return np.maximum(sensor, 0) * sensor.shape[0] + columns


@dataclass(frozen=True)
class HoverState:
    """HGAD's state between slots, for B missions (arrays updated in place).

    Attributes:
        sensor: (B,) the sensor being hovered on, or NO_SENSOR when not hovering.
        budget_s: (B,) hover time left [s].
        cooling: (N * B,) flat (N, B) True where a sensor cools down after its hover: it cannot
            trigger a hover again until its rate drops below its threshold.
    """

    sensor: np.ndarray
    budget_s: np.ndarray
    cooling: np.ndarray

    @classmethod
    def start(cls, n_sensors: int, n_missions: int) -> HoverState:
        """Not hovering, nothing cooling down."""
        return cls(
            sensor=np.full(n_missions, NO_SENSOR, np.int64),
            budget_s=np.zeros(n_missions),
            cooling=np.zeros(n_sensors * n_missions, bool),
        )


def hover_budget_s(left_bit: Any, peak_rate_bps: Any, max_hover_s: Any) -> Any:
    """HGAD's hover length T_hover = min(Q_i / R*_i, max_hover_s) [s] (elementwise; R*_i > 0)."""
    return np.minimum(left_bit / peak_rate_bps, max_hover_s)


def hover_ends(budget_left_s: Any, left_after_bit: Any) -> Any:
    """True where a hover ends after this slot: its budget (already counted down by this slot)
    is used up, within :data:`HOVER_EPS_S`, or the hovered buffer is empty."""
    return (budget_left_s <= HOVER_EPS_S) | (left_after_bit <= 0)


def end_hover(state: HoverState, cell: np.ndarray, ends: np.ndarray) -> None:
    """Stop the hovers of missions ``ends`` ((B,) bool); each hovered sensor (``cell``, its
    :func:`cells`) cools down."""
    state.cooling[cell[ends]] = True
    state.sensor[ends] = NO_SENSOR


def hover_sensor_or(state: HoverState, choice: np.ndarray) -> np.ndarray:
    """(B,) the sensor served this slot: the hovered one while hovering, else ``choice``."""
    return np.where(state.sensor >= 0, state.sensor, choice)


def hgad_update(
    state: HoverState,
    *,
    sensor: np.ndarray,
    cell: np.ndarray,
    rate_bps: np.ndarray,
    rate_served_bps: np.ndarray,
    left_after_bit: np.ndarray,
    threshold_bps: np.ndarray,
    peak_rate_bps: np.ndarray,
    max_hover_s: np.ndarray,
    slot_s: np.ndarray,
    enabled: np.ndarray | bool = True,
    active: np.ndarray | bool = True,
) -> np.ndarray:
    """Advance HGAD's hover state over one slot; (B,) True where the UAV holds its position.

    The rules (``docs/contract.md``): at the start of the slot any sensor whose rate is below
    its threshold gamma_i stops cooling down; a hover in progress counts dt off its budget and
    ends after the slot in which the budget reaches 0 or the buffer empties (the sensor then
    cools down); otherwise the served sensor triggers a hover of min(Q_i / R*_i, max_hover_s)
    when R_i > 0, R*_i > 0, R_i >= gamma_i, data is left after this slot and it is not
    cooling down. The trigger slot and every hover slot hold the UAV where it is.

    Args:
        state: updated in place.
        sensor: (B,) sensor served this slot (:func:`hover_sensor_or`), or NO_SENSOR.
        cell: (B,) :func:`cells` of ``sensor``.
        rate_bps: (N, B) rate to each sensor this slot [bit/s] (C order).
        rate_served_bps: (B,) rate of the served sensor [bit/s] (``rate_bps`` at ``cell``).
        left_after_bit: (B,) the served sensor's buffer after this slot's download [bit].
        threshold_bps: (N * B,) flat (N, B) trigger thresholds gamma_i [bit/s].
        peak_rate_bps: (N * B,) flat (N, B) peak rates R*_i [bit/s].
        max_hover_s: (B,) longest hover [s].
        slot_s: (B,) slot length [s].
        enabled: (B,) False for missions whose policy never hovers (mixed batches).
        active: (B,) False for missions that are over (their state is left alone).
    """
    serving = sensor >= 0
    rate_served = rate_served_bps
    hover_flag = (state.sensor >= 0) & active
    np.logical_and(state.cooling, ~(rate_bps.reshape(-1) < threshold_bps), out=state.cooling)
    np.subtract(state.budget_s, slot_s, out=state.budget_s, where=hover_flag)
    end_hover(state, cell, hover_flag & hover_ends(state.budget_s, left_after_bit))
    peak_served = peak_rate_bps.take(cell)
    trigger = (
        enabled
        & ~hover_flag
        & serving
        & (rate_served > 0)
        & (peak_served > 0)
        & (rate_served >= threshold_bps.take(cell))
        & (left_after_bit > 0)
        & ~state.cooling.take(cell)
    )
    if not trigger.any():
        return hover_flag
    chosen = np.flatnonzero(trigger)
    max_hover = np.broadcast_to(max_hover_s, trigger.shape)
    state.budget_s[chosen] = hover_budget_s(
        left_after_bit[chosen], peak_served[chosen], max_hover[chosen]
    )
    state.sensor[chosen] = sensor[chosen]
    return hover_flag | trigger
