"""Mission metrics: one implementation over padded arrays of B missions.

Every summary number (``summary.json``, sweep rows, comparison tables) comes from
:func:`summaries` over a :class:`Flights`: the batched engine builds one from its arrays
without any per-mission log, and :func:`summarize` is the one-mission case, built from a
:class:`~skymule.metrics.flights.MissionLog`. The AADM score comes from its one
implementation, :func:`skymule.aadm.score.aadm_scores`, called here for every summary.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.energy import propulsion_power_w
from skymule.metrics.flights import NO_SENSOR, Flights, MissionLog, unique_rows
from skymule.metrics.visits import first_visit_slots, order_from_first
from skymule.rules.score import AadmScore, aadm_scores
from skymule.units import BITS_PER_MBIT

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
def per_sensor_column(key: str, sensor: str) -> str:
    """The flat column of one sensor's entry of a per-sensor summary dict, the same in every
    table skymule writes (sweep ``results.parquet``, ``comparison.csv``): the summary.json
    path, ``per_sensor_downloaded_mbit.LW1``."""
    return f"{key}.{sensor}"


LANDING_TOLERANCE_M = 5.0


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
    square = np.subtract(position_m[:, 1:], position_m[:, :-1], dtype=float)
    square *= square
    # np.linalg.norm(offset, axis=2) float for float: numpy adds the three squares as
    # (x² + y²) + z²; written out, without norm's reduction over a length-3 axis (4x the time)
    steps[:, :-1] = np.sqrt((square[..., 0] + square[..., 1]) + square[..., 2])
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
            flights.score_windows_s(),
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


def summary_rows(flights: Flights, scenario_names: Sequence[str]) -> list[dict[str, Any]]:
    """One ``summary.json`` dictionary per flight of ``flights`` (:func:`summaries`)."""
    rows = summary_dicts(
        summaries(flights),
        list(flights.sensor_names),
        list(flights.policy) if flights.policy else [""] * flights.size,
        scenario_names,
    )
    return with_battery(flights, rows)


def with_battery(flights: Flights, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``rows`` with ``battery_used_kj`` for the flights that had a battery fault: the
    battery's own account (power at the airspeed), which energy_kj (from the track, as if
    the air were calm) is not under a wind or after a landing."""
    used = flights.battery_used_j
    if used is None:
        return rows
    for b, row in enumerate(rows):
        kept = used[b, : flights.n_run[b]]
        if not np.isnan(used[b]).all():
            row["battery_used_kj"] = float(kept[-1]) / 1e3 if kept.size else 0.0
    return rows


def summarize(log: MissionLog, scenario_name: str) -> dict[str, Any]:
    """The run summary written to ``summary.json``: :func:`summaries` of one flight."""
    flights = log.flights if log.flights.size == 1 else log.flights.select([log.index])
    (row,) = summary_rows(flights, [scenario_name])
    return row


# --- per-slot values and single-mission conveniences (slots.csv, tests) ----------------------


def _one(log: MissionLog) -> tuple[Flights, int]:
    return log.flights, log.index


def step_lengths_m(log: MissionLog) -> np.ndarray:
    """(T',) distance flown during each slot [m] (from r_t to r_{t+1})."""
    flights, b = _one(log)
    return slot_steps_and_power(flights)[0][b, : log.n_slots]


def speed_mps(log: MissionLog) -> np.ndarray:
    """(T',) speed flown during each slot [m/s]."""
    return step_lengths_m(log) / log.slot_s


def power_w(log: MissionLog) -> np.ndarray:
    """(T',) rotary-wing propulsion power in each slot [W] (Zeng, Xu & Zhang 2019, eq. 12)."""
    flights, b = _one(log)
    return slot_steps_and_power(flights)[1][b, : log.n_slots]


def handovers(served: np.ndarray) -> int:
    """Times the served sensor changed, over the slots in which some sensor was served."""
    return int(handover_counts(np.asarray(served).reshape(-1, 1))[0])


def completion_time_s(log: MissionLog) -> float | None:
    """End of the slot in which the last buffered bit was downloaded [s]; None if never."""
    flights, b = _one(log)
    done = float(completion_times_s(flights)[b])
    return None if np.isnan(done) else done


def aadm_score(log: MissionLog) -> float:
    """The AADM challenge score of one mission (:func:`skymule.aadm.score.aadm_scores`)."""
    flights, b = _one(log)
    return float(summaries(flights).aadm.score[b])
