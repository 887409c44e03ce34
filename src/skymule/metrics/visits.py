"""The order in which each mission first visited its sensors (``visit_order`` in summaries).

Vectorised over the missions of a :class:`~skymule.metrics.flights.Flights`; part of the metrics
(:mod:`skymule.metrics.summary` calls it), kept apart for the size of that module.
"""

from __future__ import annotations

import numpy as np

from skymule.metrics.flights import NO_SENSOR, Flights, unique_rows


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
