"""Mission metrics: one implementation over padded arrays of B missions.

Every summary number (``summary.json``, sweep rows, comparison tables) comes from
:func:`summaries` over a :class:`Flights`: the batched engine builds one from its arrays
without any per-mission log, and :func:`summarize` is the one-mission case, built from a
:class:`~skymule.sim.log.MissionLog`. The AADM score comes from its one implementation,
:func:`skymule.aadm.score.aadm_scores`, called here for every summary.

Positions are given as tracks plus sample indices: mission b is at
``track_position_m[track_id[b], sample[b, t]]`` during slot t and ends at sample
``end_sample[b]``; a non-hovering slot moves to the next sample (or holds at a track's last
one). A log is its own track: its positions followed by its end position, sample t in slot t.
This is what lets the batched engine share one track among many missions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.aadm.score import AADM_WINDOW_S, AadmScore, aadm_scores
from skymule.energy import propulsion_power_w
from skymule.sim.log import NO_SENSOR, MissionLog

BITS_PER_MBIT = 1e6

HEADLINE_METRICS = (
    "total_downloaded_mbit",
    "completion",
    "handovers",
    "hover_time_s",
    "distance_m",
    "energy_kj",
    "aadm_score",
)
"""The summary fields shown in tables and aggregated over sweeps."""

#: The AERPAW testbed requires landing within this distance of the launch point [m] (a check
#: beside the AADM score, which has no landing term).
LANDING_TOLERANCE_M = 5.0


@dataclass(frozen=True)
class Flights:
    """What happened in B missions, as padded arrays (T slots at most, N sensors).

    Row b holds mission b; only its first ``n_run[b]`` slots happened, and the padding after
    them holds NO_SENSOR in ``served``, 0 in ``downloaded_bit`` and False in ``hovering``.

    Attributes:
        n_run: (B,) slots run T'.
        slot_s: (B,) slot length [s].
        buffers_bit: (B, N) initial buffers [bit].
        left_bit: (B, N) buffers after the last slot [bit].
        served: (B, T) served sensor, or NO_SENSOR.
        downloaded_bit: (B, T) bits downloaded in each slot.
        hovering: (B, T) True where the UAV held its position after the slot by choice.
        track_position_m: (U, K, 3) positions of U tracks [m].
        track_samples: (U,) samples in each track (the rest is padding).
        track_id: (B,) each mission's track.
        sample: (B, T) track sample the UAV is at during each slot (non-decreasing, from 0).
        end_sample: (B,) track sample after the last slot.
        home_m: (B, 2) home point [m] (NaN: no home).
        hover_points_m: (B, N, 2) point each sensor is served from [m] (NaN: unknown).
        visit_radius_m: (B,) a sensor counts as visited within this distance [m].
        target: (B, T) autonomous: sensor the policy was heading for (NO_SENSOR: none), or
            None when no mission has targets.
        aadm_window_s: (B,) the AADM download window the score counts downloads in [s].
    """

    n_run: np.ndarray
    slot_s: np.ndarray
    buffers_bit: np.ndarray
    left_bit: np.ndarray
    served: np.ndarray
    downloaded_bit: np.ndarray
    hovering: np.ndarray
    track_position_m: np.ndarray
    track_samples: np.ndarray
    track_id: np.ndarray
    sample: np.ndarray
    end_sample: np.ndarray
    home_m: np.ndarray
    hover_points_m: np.ndarray
    visit_radius_m: np.ndarray
    target: np.ndarray | None = None
    aadm_window_s: np.ndarray | None = None


def flights_from_log(log: MissionLog) -> Flights:
    """One mission's log as :class:`Flights` (its own track; B = U = 1)."""
    n_sensors, n_slots = len(log.sensor_names), log.n_slots
    track = np.vstack([log.position_m.reshape(-1, 3), log.end_position_m[None, :]])
    home = np.full((1, 2), np.nan) if log.home_m is None else np.reshape(log.home_m, (1, 2))
    hover = (
        np.full((1, n_sensors, 2), np.nan)
        if log.hover_points_m is None
        else np.reshape(log.hover_points_m, (1, n_sensors, 2))
    )
    left = log.remaining_bit[-1] if n_slots else log.buffers_bit
    return Flights(
        n_run=np.array([n_slots]),
        slot_s=np.array([log.slot_s], float),
        buffers_bit=np.reshape(log.buffers_bit, (1, n_sensors)),
        left_bit=np.reshape(left, (1, n_sensors)),
        served=log.served[None, :],
        downloaded_bit=log.downloaded_bit[None, :],
        hovering=log.hovering[None, :],
        track_position_m=track[None],
        track_samples=np.array([n_slots + 1]),
        track_id=np.zeros(1, np.int64),
        sample=np.arange(n_slots)[None, :],
        end_sample=np.array([n_slots]),
        home_m=home,
        hover_points_m=hover,
        visit_radius_m=np.array([log.visit_radius_m], float),
        target=None if log.target is None else log.target[None, :],
        aadm_window_s=np.array([log.aadm_window_s], float),
    )


# --- building blocks, vectorised over missions ----------------------------------------------


def row_sums(values: np.ndarray, n_run: np.ndarray) -> np.ndarray:
    """(B,) sum of the first ``n_run[b]`` entries of each row of ``values`` (B, T).

    Bit for bit ``values[b, :n].sum()``: rows of one length are summed as a C-contiguous
    (rows, n) block, which numpy reduces row by row with the same pairwise summation.
    """
    lengths = np.unique(n_run)
    if lengths.size == 1 and lengths[0] == values.shape[1]:
        return np.ascontiguousarray(values).sum(axis=1)
    sums = np.zeros(values.shape[0])
    for n in lengths:
        rows = np.flatnonzero(n_run == n)
        sums[rows] = np.ascontiguousarray(values[rows, :n]).sum(axis=1)
    return sums


def unique_rows(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of ``key`` (B, C) and each row's group (B,), as np.unique(axis=0).

    Fast path when every row is the same (a batch of one geometry); NaN equals NaN there.
    """
    first = key[:1]
    same = (key == first) | (np.isnan(key) & np.isnan(first))
    if same.all():
        return first, np.zeros(key.shape[0], np.int64)
    rows, group = np.unique(key, axis=0, return_inverse=True)
    return rows, group.reshape(-1)


def handover_counts(served: np.ndarray) -> np.ndarray:
    """(B,) changes of served sensor over the slots that served one, ``served`` (T, B).

    NO_SENSOR slots are skipped (serving A, nothing, A is no handover).
    """
    valid = served != NO_SENSOR
    if not (valid[1:] & ~valid[:-1]).any():
        # served slots form a prefix of every mission (Greedy/HGAD: buffers never refill)
        return np.count_nonzero((served[1:] != served[:-1]) & valid[1:], axis=0)
    slots = np.arange(served.shape[0])[:, None]
    last = np.maximum.accumulate(np.where(valid, slots, -1), axis=0)
    previous = np.vstack([np.full((1, served.shape[1]), -1), last[:-1]])
    previous_served = np.take_along_axis(served, np.maximum(previous, 0), axis=0)
    return np.count_nonzero(valid & (previous >= 0) & (previous_served != served), axis=0)


def track_steps_m(position_m: np.ndarray, n_samples: np.ndarray) -> np.ndarray:
    """(U, K) distance from track sample k to k + 1 [m]; 0 at and past the last sample."""
    n_tracks, k_max = position_m.shape[:2]
    steps = np.zeros((n_tracks, k_max))
    steps[:, :-1] = np.linalg.norm(position_m[:, 1:] - position_m[:, :-1], axis=2)
    steps[np.arange(steps.shape[1]) >= n_samples[:, None] - 1] = 0.0
    return steps


def power_tables(
    track_position_m: np.ndarray,
    track_samples: np.ndarray,
    track_id: np.ndarray,
    slot_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-slot distance and power looked up by track sample: (P, K + 1) steps [m], (P, K + 1)
    power [W] and each mission's row (B,), one row per distinct (track, slot length).

    Column k < K: a slot that moves from sample k; column K: a hover slot (0 m). Power is
    P(step / slot_s) (Zeng, Xu & Zhang 2019, eq. 12).
    """
    pairs, pair = unique_rows(np.column_stack([track_id, slot_s]))
    k_max = track_position_m.shape[1]
    steps = np.zeros((pairs.shape[0], k_max + 1))  # column k_max: a hover slot (0 m)
    steps[:, :k_max] = track_steps_m(track_position_m, track_samples)[pairs[:, 0].astype(int)]
    return steps, propulsion_power_w(steps / pairs[:, 1:2]), pair


def slot_steps_and_power(flights: Flights) -> tuple[np.ndarray, np.ndarray]:
    """(B, T) distance flown in each slot [m] and (B, T) propulsion power [W].

    A hovering slot flies 0 m; any other moves one track step (:func:`power_tables`).
    """
    steps, power, pair = power_tables(
        flights.track_position_m, flights.track_samples, flights.track_id, flights.slot_s
    )
    k_max = flights.track_position_m.shape[1]
    column = np.where(flights.hovering, k_max, flights.sample)
    index = column + pair[:, None] * (k_max + 1)
    return steps.take(index), power.take(index)


def completion_times_s(flights: Flights) -> np.ndarray:
    """(B,) end of the slot in which the last buffered bit was downloaded [s].

    NaN where the buffers were never all emptied; 0 where nothing was buffered. Buffers only
    shrink, by downloads, so a mission that ends empty emptied in its last downloading slot.
    """
    slots = np.arange(flights.downloaded_bit.shape[1])[None, :]
    last = np.where(flights.downloaded_bit > 0, slots, -1).max(axis=1, initial=-1)
    emptied = ~(flights.left_bit > 0).any(axis=1) & (last >= 0)
    done = np.where(emptied, (last + 1) * flights.slot_s, np.nan)
    return np.where(flights.buffers_bit.any(axis=1), done, 0.0)


def distance_to_home_m(flights: Flights) -> np.ndarray:
    """(B,) horizontal distance from the end position to home [m] (NaN: no home)."""
    end_m = flights.track_position_m[flights.track_id, flights.end_sample]
    return horizontal_distance_m(end_m, flights.home_m)


def horizontal_distance_m(from_m: np.ndarray, to_m: np.ndarray) -> np.ndarray:
    """(B,) horizontal distance between (B, >=2) points [m]."""
    return np.hypot(from_m[:, 0] - to_m[:, 0], from_m[:, 1] - to_m[:, 1])


# --- visit order ------------------------------------------------------------------------------


def visit_order(flights: Flights) -> np.ndarray:
    """(B, N) sensor indices in first-visit order, padded with NO_SENSOR.

    Autonomous runs (with targets): sensor i is visited at the first slot the UAV was heading
    for it and ended within ``visit_radius_m`` of its hover point (the paper's "navigation
    order", Table II). Otherwise a run in which the UAV hovered while serving (HGAD) visits
    sensor i at the first slot it hovered serving i; else (Greedy) at the first slot the UAV
    was within ``visit_radius_m`` of i's hover point.
    """
    return order_from_first(first_visit_slots(flights), flights.n_run)


def order_from_first(first: np.ndarray, n_run: np.ndarray) -> np.ndarray:
    """(B, N) sensors by first-visit slot ``first`` (B, N) (ties: lower index), NO_SENSOR for
    those never visited (first >= n_run)."""
    order = np.argsort(first, axis=1, kind="stable")
    reached = np.take_along_axis(first, order, axis=1) < n_run[:, None]
    return np.where(reached, order, NO_SENSOR)


def first_visit_slots(flights: Flights) -> np.ndarray:
    """(B, N) slot each sensor was first visited in (n_run: never), by :func:`visit_order`'s
    rules."""
    n_run = flights.n_run
    served = flights.served
    hovered = flights.hovering & (served != NO_SENSOR)
    n_sensors = flights.buffers_bit.shape[1]
    first = _first_hover_slots(served, hovered, n_run, n_sensors)
    by_place = ~hovered.any(axis=1)
    if flights.target is not None:
        # all-NaN hover points: unknown (a log without them), so no target-based visits
        by_target = (n_run > 0) & np.isfinite(flights.hover_points_m).any(axis=(1, 2))
        if by_target.any():
            rows = np.flatnonzero(by_target)
            first[rows] = _first_target_arrivals(flights, rows)
            by_place &= ~by_target
    if by_place.any():
        rows = np.flatnonzero(by_place)
        first[rows] = _first_slot_near(flights, rows)
    return first


def _first_hover_slots(
    served: np.ndarray, hovered: np.ndarray, n_run: np.ndarray, n_sensors: int
) -> np.ndarray:
    """(B, N) first slot each mission hovered serving each sensor (else n_run).

    Only the first slot of each hover run is looked at.
    """
    start = hovered.copy()
    start[:, 1:] &= ~(hovered[:, :-1] & (served[:, 1:] == served[:, :-1]))
    mission, slot = np.nonzero(start)  # mission-major, slots in order within a mission
    keys, at = np.unique(mission * n_sensors + served[mission, slot], return_index=True)
    first = np.repeat(n_run[:, None], n_sensors, axis=1)
    first.reshape(-1)[keys] = slot[at]
    return first


def _positions_after(flights: Flights, rows: np.ndarray) -> np.ndarray:
    """(R, T, 2) horizontal position after each slot of missions ``rows`` [m]."""
    sample = flights.sample[rows]
    after = np.empty_like(sample)
    after[:, :-1] = sample[:, 1:]
    n_run = flights.n_run[rows]
    # the slot after the last one run ends at end_sample
    last = np.maximum(n_run - 1, 0)
    after[:, -1] = sample[:, -1]
    after[np.arange(rows.size), last] = flights.end_sample[rows]
    track = flights.track_id[rows][:, None]
    return flights.track_position_m[track, after, :2]


def _first_target_arrivals(flights: Flights, rows: np.ndarray) -> np.ndarray:
    """(R, N) first slot the UAV, heading for sensor i, ended near i's hover point."""
    assert flights.target is not None
    n_sensors = flights.buffers_bit.shape[1]
    after = _positions_after(flights, rows)
    offset = after[:, :, None, :] - flights.hover_points_m[rows][:, None, :, :]
    near = np.hypot(offset[..., 0], offset[..., 1]) <= flights.visit_radius_m[rows][:, None, None]
    hits = near & (flights.target[rows][:, :, None] == np.arange(n_sensors)[None, None, :])
    hits &= (np.arange(hits.shape[1]) < flights.n_run[rows][:, None])[:, :, None]
    n_run = flights.n_run[rows][:, None]
    return np.where(hits.any(axis=1), hits.argmax(axis=1), n_run)


def near_samples(
    track_position_m: np.ndarray,
    track_samples: np.ndarray,
    track_id: np.ndarray,
    hover_points_m: np.ndarray,
    visit_radius_m: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(G, N) first track sample within the visit radius of each sensor's hover point
    (horizontally; K_max: never) and each mission's row (B,), one row per distinct
    (track, hover points, radius)."""
    n_missions, n_sensors = hover_points_m.shape[:2]
    k_max = track_position_m.shape[1]
    key = np.column_stack(
        [track_id, hover_points_m.reshape(n_missions, -1), visit_radius_m.reshape(n_missions)]
    )
    keys, group = unique_rows(key)
    first_near = np.empty((keys.shape[0], n_sensors), np.int64)
    for g, row in enumerate(keys):
        u = int(row[0])
        offset = track_position_m[u, :, None, :2] - row[1:-1].reshape(1, -1, 2)
        near = np.hypot(offset[..., 0], offset[..., 1]) <= row[-1]  # NaN -> False
        near[track_samples[u] :] = False
        first_near[g] = np.where(near.any(axis=0), near.argmax(axis=0), k_max)
    return first_near, group


def _first_slot_near(flights: Flights, rows: np.ndarray) -> np.ndarray:
    """(R, N) first slot missions ``rows`` were within the visit radius of each sensor's
    hover point (horizontally), or n_run if never.

    The UAV walks its track from sample 0 one sample at a time, so that slot is the first one
    at the first track sample k near the hover point: the number of slots spent before k.
    """
    n_run = flights.n_run[rows]
    k_max = flights.track_position_m.shape[1]
    first_near, group = near_samples(
        flights.track_position_m,
        flights.track_samples,
        flights.track_id[rows],
        flights.hover_points_m[rows],
        flights.visit_radius_m[rows],
    )
    # slots spent before each sample k (bin k_max collects the slots after the mission)
    bins = k_max + 1
    ran = np.arange(flights.sample.shape[1])[None, :] < n_run[:, None]
    flat = np.where(ran, flights.sample[rows], k_max) + np.arange(rows.size)[:, None] * bins
    counts = np.bincount(flat.ravel(), minlength=rows.size * bins).reshape(-1, bins)
    before = np.cumsum(counts, axis=1) - counts
    return np.take_along_axis(before, first_near[group], axis=1)


# --- summaries --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Summaries:
    """The summary of every mission of a :class:`Flights`, as arrays (SI units).

    Attributes:
        slots: (B,) slots run T'.
        slot_s: (B,) slot length [s].
        buffers_bit: (B, N) initial buffers [bit].
        total_downloaded_bit: (B,) bits downloaded [bit].
        per_sensor_downloaded_bit: (B, N) bits downloaded from each sensor [bit].
        completion: (B,) downloaded / buffered (1 with nothing buffered).
        handovers: (B,) changes of served sensor over the slots that served one.
        hover_time_s: (B,) time spent hovering [s].
        distance_m: (B,) distance flown [m].
        energy_j: (B,) propulsion energy [J].
        visit_order: (B, N) sensor indices in first-visit order, padded with NO_SENSOR.
        distance_to_home_m: (B,) horizontal end-to-home distance [m] (NaN: no home).
        aadm: the AADM challenge score and its parts (:mod:`skymule.aadm.score`).
    """

    slots: np.ndarray
    slot_s: np.ndarray
    buffers_bit: np.ndarray
    total_downloaded_bit: np.ndarray
    per_sensor_downloaded_bit: np.ndarray
    completion: np.ndarray
    handovers: np.ndarray
    hover_time_s: np.ndarray
    distance_m: np.ndarray
    energy_j: np.ndarray
    visit_order: np.ndarray
    distance_to_home_m: np.ndarray
    aadm: AadmScore


def summaries(flights: Flights) -> Summaries:
    """Every metric of every mission of ``flights``, vectorised over missions."""
    n_run, slot_s = flights.n_run, flights.slot_s
    steps, power = slot_steps_and_power(flights)
    return summaries_from_totals(
        n_run=n_run,
        slot_s=slot_s,
        buffers_bit=flights.buffers_bit,
        left_bit=flights.left_bit,
        downloaded_bit=row_sums(flights.downloaded_bit, n_run),
        distance_m=row_sums(steps, n_run),
        power_sum_w=row_sums(power, n_run),
        handovers=handover_counts(flights.served.T),
        hover_slots=np.count_nonzero(flights.hovering, axis=1),
        first_visit=first_visit_slots(flights),
        distance_to_home_m=distance_to_home_m(flights),
        aadm=aadm_scores(
            flights.downloaded_bit,
            flights.buffers_bit.sum(axis=1),
            n_run,
            slot_s,
            AADM_WINDOW_S if flights.aadm_window_s is None else flights.aadm_window_s,
        ),
    )


def summaries_from_totals(
    *,
    n_run: np.ndarray,
    slot_s: np.ndarray,
    buffers_bit: np.ndarray,
    left_bit: np.ndarray,
    downloaded_bit: np.ndarray,
    distance_m: np.ndarray,
    power_sum_w: np.ndarray,
    handovers: np.ndarray,
    hover_slots: np.ndarray,
    first_visit: np.ndarray,
    distance_to_home_m: np.ndarray,
    aadm: AadmScore,
) -> Summaries:
    """:class:`Summaries` from each mission's reductions of its slots (all (B,) but
    ``first_visit`` (B, N), :func:`first_visit_slots`): what :func:`summaries` computes with
    numpy and the compiled loop while it runs (:mod:`skymule.sim.summary_kernels`).

    ``downloaded_bit``, ``distance_m`` and ``power_sum_w`` are sums over the slots run;
    ``hover_slots`` counts the slots the UAV held position in.
    """
    total_buffer = buffers_bit.sum(axis=1)
    has_buffer = total_buffer > 0
    safe_buffer = np.where(has_buffer, total_buffer, 1.0)
    return Summaries(
        slots=n_run.copy(),
        slot_s=slot_s.copy(),
        buffers_bit=buffers_bit.copy(),
        total_downloaded_bit=downloaded_bit,
        per_sensor_downloaded_bit=buffers_bit - left_bit,
        completion=np.where(has_buffer, downloaded_bit / safe_buffer, 1.0),
        handovers=handovers,
        hover_time_s=hover_slots * slot_s,
        distance_m=distance_m,
        energy_j=power_sum_w * slot_s,
        visit_order=order_from_first(first_visit, n_run),
        distance_to_home_m=distance_to_home_m,
        aadm=aadm,
    )


def summary_dicts(
    summary: Summaries,
    sensor_names: Sequence[tuple[str, ...]],
    policies: Sequence[str],
    scenario_names: Sequence[str],
) -> list[dict[str, Any]]:
    """One ``summary.json`` dictionary per mission (Mbit and kJ at this edge)."""
    mission_time = (summary.slots * summary.slot_s).tolist()
    slots = summary.slots.tolist()
    slot_s = summary.slot_s.tolist()
    total = (summary.total_downloaded_bit / BITS_PER_MBIT).tolist()
    total_buffer = (summary.buffers_bit.sum(axis=1) / BITS_PER_MBIT).tolist()
    per_sensor = (summary.per_sensor_downloaded_bit / BITS_PER_MBIT).tolist()
    buffers = (summary.buffers_bit / BITS_PER_MBIT).tolist()
    completion = summary.completion.tolist()
    handovers = summary.handovers.tolist()
    hover = summary.hover_time_s.tolist()
    distance = summary.distance_m.tolist()
    energy = (summary.energy_j / 1e3).tolist()
    order = summary.visit_order.tolist()
    landed = (summary.distance_to_home_m <= LANDING_TOLERANCE_M).tolist()
    to_home = summary.distance_to_home_m.tolist()
    aadm = summary.aadm
    t1, s1, s2 = aadm.t1_s.tolist(), aadm.s1.tolist(), aadm.s2.tolist()
    complete, score = aadm.complete.tolist(), aadm.score.tolist()
    # built column-wise (one zip over the columns, one dict display per mission): the dicts
    # cost as much as everything else in a compiled batch's summaries
    n_sensors = summary.buffers_bit.shape[1]
    if any(len(names) != n_sensors for names in sensor_names):  # once, not a strict zip each
        raise ValueError(f"summary_dicts: every mission needs {n_sensors} sensor names")
    per_sensor_dicts = [
        dict(zip(n, v, strict=False)) for n, v in zip(sensor_names, per_sensor, strict=True)
    ]
    buffer_dicts = [
        dict(zip(n, v, strict=False)) for n, v in zip(sensor_names, buffers, strict=True)
    ]
    visits = [[n[i] for i in o if i != NO_SENSOR] for n, o in zip(sensor_names, order, strict=True)]
    columns = zip(
        scenario_names, policies, mission_time, slots, slot_s, total, total_buffer,
        per_sensor_dicts, buffer_dicts, completion, handovers, hover, distance, energy, visits,
        landed, to_home, score, t1, s1, s2, complete,
        strict=True,
    )  # fmt: skip
    return [
        {
            "scenario": c[0],
            "policy": c[1],
            "mission_time_s": c[2],
            "slots": c[3],
            "slot_s": c[4],
            "total_downloaded_mbit": c[5],
            "total_buffer_mbit": c[6],
            "per_sensor_downloaded_mbit": c[7],
            "per_sensor_buffer_mbit": c[8],
            "completion": c[9],
            "handovers": c[10],
            "hover_time_s": c[11],
            "distance_m": c[12],
            "energy_kj": c[13],
            "visit_order": c[14],
            "landed_within_5m": c[15],
            "distance_to_home_m": c[16],
            "aadm_score": c[17],
            "aadm_t1_s": c[18],
            "aadm_s1": c[19],
            "aadm_s2": c[20],
            "aadm_complete": c[21],
        }
        for c in columns
    ]


def summarize(log: MissionLog, scenario_name: str) -> dict[str, Any]:
    """The run summary written to ``summary.json``: :func:`summaries` of one mission."""
    (row,) = summary_dicts(
        summaries(flights_from_log(log)), [log.sensor_names], [log.policy], [scenario_name]
    )
    return row


# --- per-slot values and single-mission conveniences (slots.csv, tests) ----------------------


def step_lengths_m(log: MissionLog) -> np.ndarray:
    """(T',) distance flown during each slot [m] (from r_t to r_{t+1})."""
    return slot_steps_and_power(flights_from_log(log))[0][0]


def speed_mps(log: MissionLog) -> np.ndarray:
    """(T',) speed flown during each slot [m/s]."""
    return step_lengths_m(log) / log.slot_s


def power_w(log: MissionLog) -> np.ndarray:
    """(T',) rotary-wing propulsion power in each slot [W] (Zeng, Xu & Zhang 2019, eq. 12)."""
    return slot_steps_and_power(flights_from_log(log))[1][0]


def handovers(served: np.ndarray) -> int:
    """Times the served sensor changed, over the slots in which some sensor was served."""
    return int(handover_counts(np.asarray(served).reshape(-1, 1))[0])


def completion_time_s(log: MissionLog) -> float | None:
    """End of the slot in which the last buffered bit was downloaded [s]; None if never."""
    done = float(completion_times_s(flights_from_log(log))[0])
    return None if np.isnan(done) else done


def aadm_score(log: MissionLog) -> float:
    """The AADM challenge score of one mission (:func:`skymule.aadm.score.aadm_scores`)."""
    return float(summaries(flights_from_log(log)).aadm.score[0])
