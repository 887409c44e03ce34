"""What :func:`skymule.metrics.summaries` needs from a mission's slots, one mission at a time.

The summaries reduce each mission's per-slot arrays (served sensor, bits, hover flag, track
sample) to a few numbers: bits downloaded, distance, energy, handovers, hover slots, the slot
each sensor was first visited in and the AADM score's progress. :mod:`skymule.metrics.summary` does
it with numpy over (B, T) arrays, the reference; this module does the same reductions for one
mission's rows in the subset of Python numba compiles, so the compiled slot loop
(:mod:`skymule.sim.compiled`) can reduce each mission while its slots are still in cache and
never write the (B, T) logs, and a pass over arrays already written (:func:`reduce_rows`: the
numpy loop's logs, or the batched autonomous engine's arrays, whose first visits follow the
targets, :func:`first_target_arrivals`). Like :mod:`skymule.sim.kernels`, nothing here imports
a compiler: the tests run these functions as plain Python too, and check the compiled summaries
equal ``metrics.summaries``: bit for bit as plain Python; compiled, to a relative 1e-12
(numba sums a row in order, numpy pairwise). The AADM progress is the same running sum as
numpy's ``cumsum``, so counts and first slots agree exactly.
The lookup tables (distance and power per track sample, the first track sample near each
sensor) come from the same functions ``metrics`` uses (``metrics.power_tables``,
``metrics.near_samples``); the distance to a hover point is ``np.hypot``, as in
:mod:`skymule.metrics.visits` (numba calls the same C library function).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from skymule.rules.contract import NO_SENSOR


class SlotTotals(NamedTuple):
    """Per-mission reductions of B missions' slots (arrays filled by :func:`mission_totals`).

    Attributes:
        downloaded_bit: (B,) bits downloaded (sum over the slots run).
        distance_m: (B,) distance flown (sum of the per-slot steps).
        power_sum_w: (B,) sum of the per-slot propulsion power [W] (energy / slot_s).
        handovers: (B,) changes of served sensor over the slots that served one.
        hover_slots: (B,) slots the UAV held its position in.
        first_visit: (B, N) slot each sensor was first visited in (n_run: never).
        aadm_bit: (B,) the AADM running sum of counted downloads (its last value).
        aadm_first: (B,) first counted slot at which that sum reached the threshold (-1: never).
    """

    downloaded_bit: np.ndarray
    distance_m: np.ndarray
    power_sum_w: np.ndarray
    handovers: np.ndarray
    hover_slots: np.ndarray
    first_visit: np.ndarray
    aadm_bit: np.ndarray
    aadm_first: np.ndarray


class SummaryTables(NamedTuple):
    """What the reductions look up, per mission (built by ``metrics``'s table functions).

    Attributes:
        steps_m: (P, K + 1) distance flown from each track sample (column K: a hover) [m].
        power_w: (P, K + 1) propulsion power of that step [W].
        pair: (B,) each mission's row in ``steps_m`` / ``power_w``.
        near: (G, N) first track sample within the visit radius of each sensor (K: never).
        group: (B,) each mission's row in ``near``.
        aadm_threshold_bit: (B,) bits that count as everything (total x (1 - rtol)).
        aadm_window_slots: (B,) slots counted by the AADM download window
            (``rules.contract.window_slots``).
        aadm_per_slot: True when some window closes inside the batch's slots: only slots
            starting before their mission's window count (``aadm_scores``'s mask).
        width: T_max, the slots of the batch's padded arrays.
    """

    steps_m: np.ndarray
    power_w: np.ndarray
    pair: np.ndarray
    near: np.ndarray
    group: np.ndarray
    aadm_threshold_bit: np.ndarray
    aadm_window_slots: np.ndarray
    aadm_per_slot: bool
    width: int


class TargetTables(NamedTuple):
    """What the first-visit rule of autonomous runs looks up (``visits.first_visit_slots``).

    Attributes:
        target: (B, T) sensor the UAV was heading for in each slot (NO_SENSOR: none).
        by_target: (B,) True where that rule gives the first visits: the mission ran some slots
            and knows some hover point; the other rows follow :func:`mission_totals`'s rules.
        position_m: (U, K, 3) track positions [m].
        track_id: (B,) each mission's track.
        end_sample: (B,) track sample after the last slot.
        hover_points_m: (B, N, 2) point each sensor is served from [m] (NaN: unknown).
        visit_radius_m: (B,) a sensor counts as visited within this distance [m].
    """

    target: np.ndarray
    by_target: np.ndarray
    position_m: np.ndarray
    track_id: np.ndarray
    end_sample: np.ndarray
    hover_points_m: np.ndarray
    visit_radius_m: np.ndarray


def new_totals(n_missions: int, n_sensors: int) -> SlotTotals:
    """Zeroed :class:`SlotTotals` for B missions."""
    return SlotTotals(
        downloaded_bit=np.zeros(n_missions),
        distance_m=np.zeros(n_missions),
        power_sum_w=np.zeros(n_missions),
        handovers=np.zeros(n_missions, np.int64),
        hover_slots=np.zeros(n_missions, np.int64),
        first_visit=np.zeros((n_missions, n_sensors), np.int64),
        aadm_bit=np.zeros(n_missions),
        aadm_first=np.zeros(n_missions, np.int64),
    )


def mission_totals(
    b: int,
    served: np.ndarray,
    downloaded: np.ndarray,
    hovering: np.ndarray,
    sample: np.ndarray,
    n_run: int,
    slot_s: float,
    tables: SummaryTables,
    scratch: np.ndarray,
    memo: np.ndarray,
    totals: SlotTotals,
) -> None:
    """Mission b's reductions into row b of ``totals``, from its rows (T,) of slots.

    As ``metrics.summaries`` (the reference) computes them from (B, T) arrays:

    * bits, distance and power: sums over the slots run; a slot's step and power
      are looked up at its track sample, or in the hover column when the UAV held position;
    * handovers: served sensor changes, NO_SENSOR slots skipped;
    * first visits: if the UAV hovered while serving, the first such slot per sensor, else
      the slots spent before the first track sample near the sensor (the UAV walks its track
      one sample per slot, so ``sample`` never decreases);
    * AADM: a running sum of the downloads in counted slots and the first counted slot at
      which it reached the threshold.

    A mission that never hovered and moved one sample per slot from sample 0 (a straight
    walk: Greedy, until a track ends) flew the first ``n_run`` steps of its track, so its
    distance and power sums are those of the tables' first ``n_run`` columns, the same for
    every such mission: ``memo`` (4,) keeps the last [row, n_run, distance, power sum].
    ``scratch`` is (2, T) float space for the per-slot steps and power of other missions.
    """
    pair = tables.pair[b]
    hover_column = tables.steps_m.shape[1] - 1
    last = NO_SENSOR
    handovers = 0
    hover_slots = 0
    hovered_serving = False
    threshold = tables.aadm_threshold_bit[b]
    window = tables.aadm_window_slots[b]
    aadm = 0.0
    aadm_first = -1
    straight = True
    for t in range(n_run):
        sensor = served[t]
        if sensor != NO_SENSOR:
            if last != NO_SENSOR and sensor != last:
                handovers += 1
            last = sensor
        if hovering[t]:
            straight = False
            hover_slots += 1
            hovered_serving = hovered_serving or sensor != NO_SENSOR
        elif sample[t] != t:
            straight = False
        counted = not tables.aadm_per_slot or t < window
        got = downloaded[t] if counted else 0.0
        aadm = got if t == 0 else aadm + got
        if aadm_first < 0 and counted and aadm >= threshold:
            aadm_first = t
    if n_run < tables.width:  # numpy's running sum goes on over the zero padding
        aadm = aadm + 0.0
    totals.downloaded_bit[b] = downloaded[:n_run].sum()
    if straight:
        if memo[0] != pair or memo[1] != n_run:
            memo[0], memo[1] = pair, n_run
            memo[2] = tables.steps_m[pair, :n_run].sum()
            memo[3] = tables.power_w[pair, :n_run].sum()
        totals.distance_m[b], totals.power_sum_w[b] = memo[2], memo[3]
    else:
        for t in range(n_run):
            column = hover_column if hovering[t] else sample[t]
            scratch[0, t] = tables.steps_m[pair, column]
            scratch[1, t] = tables.power_w[pair, column]
        totals.distance_m[b] = scratch[0, :n_run].sum()
        totals.power_sum_w[b] = scratch[1, :n_run].sum()
    totals.handovers[b] = handovers
    totals.hover_slots[b] = hover_slots
    totals.aadm_bit[b] = aadm
    totals.aadm_first[b] = aadm_first
    first = totals.first_visit[b]
    first[:] = n_run
    if hovered_serving:
        for t in range(n_run):
            sensor = served[t]
            if hovering[t] and sensor != NO_SENSOR and first[sensor] == n_run:
                first[sensor] = t
        return
    near = tables.near[tables.group[b]]
    for i in range(first.shape[0]):
        first[i] = slots_before(sample, n_run, near[i])


def slots_before(sample: np.ndarray, n_run: int, k: int) -> int:
    """Slots among the first ``n_run`` spent at track samples below ``k``: the first slot at
    sample ``k`` or later (samples never decrease), by bisection."""
    low, high = 0, n_run
    while low < high:
        middle = (low + high) // 2
        if sample[middle] < k:
            low = middle + 1
        else:
            high = middle
    return low


def first_target_arrivals(
    b: int, sample: np.ndarray, n_run: int, targets: TargetTables, first: np.ndarray
) -> None:
    """Mission b's first visits (N,) into ``first`` by the autonomous rule: sensor i at the
    first slot the UAV was heading for i (target i) and ended within the visit radius of i's
    hover point, horizontally (n_run: never).

    The UAV ends slot t at the sample of slot t + 1, the last slot at ``end_sample`` (as
    ``visits._positions_after``); the distance is ``np.hypot``, as there (a NaN hover point
    is never near). Targets outside 0..N-1 (NO_SENSOR, home) visit nothing.
    """
    n_sensors = first.shape[0]
    first[:] = n_run
    u = targets.track_id[b]
    row = targets.target[b]
    hover = targets.hover_points_m[b]
    radius = targets.visit_radius_m[b]
    left = n_sensors  # sensors not yet visited: the scan stops when none is left
    for t in range(n_run):
        i = row[t]
        if i < 0 or i >= n_sensors or first[i] != n_run:
            continue
        k = sample[t + 1] if t + 1 < n_run else targets.end_sample[b]
        dx = targets.position_m[u, k, 0] - hover[i, 0]
        dy = targets.position_m[u, k, 1] - hover[i, 1]
        if np.hypot(dx, dy) <= radius:
            first[i] = t
            left -= 1
            if left == 0:
                return


def reduce_rows(
    served: np.ndarray,
    downloaded: np.ndarray,
    hovering: np.ndarray,
    sample: np.ndarray,
    n_run: np.ndarray,
    slot_s: np.ndarray,
    tables: SummaryTables,
    totals: SlotTotals,
    targets: TargetTables,
) -> None:
    """:func:`mission_totals` of every row of (B, T) slot arrays (a ``metrics.Flights``); rows
    ``targets.by_target`` (autonomous runs) take their first visits from
    :func:`first_target_arrivals` instead."""
    width = served.shape[1]
    scratch = np.empty((2, width))
    memo = np.full(4, -1.0)
    for b in range(served.shape[0]):
        mission_totals(
            b, served[b], downloaded[b], hovering[b], sample[b], n_run[b], slot_s[b], tables,
            scratch, memo, totals,
        )  # fmt: skip
        if targets.by_target[b]:
            first_target_arrivals(b, sample[b], n_run[b], targets, totals.first_visit[b])
