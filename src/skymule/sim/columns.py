"""B flights as columns: what both engines share.

A batch is B flights, one per column: one mission each, or the K UAVs of a fleet mission in
K contiguous columns sharing one set of buffers. Here: the per-flight constants the engines
read (:func:`window_slots`), the checks of a batched action (:func:`check_actions`), the
fleet layout (:func:`fleet_columns`), read-only arrays for policies (:func:`frozen`) and the
run record both write (:func:`flights_record`).
"""

from __future__ import annotations

from collections.abc import Sequence
from operator import attrgetter
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.metrics.flights import Flights
from skymule.policies.base import BatchAction
from skymule.rules.contract import NO_SENSOR
from skymule.world import Mission


def frozen(values: np.ndarray) -> np.ndarray:
    """A read-only view of ``values``, which is frozen too (so the view cannot be made
    writeable again): what the engine hands a policy and never writes afterwards."""
    values.flags.writeable = False
    return values.view()


def window_slots(missions: Sequence[Mission]) -> np.ndarray:
    """(B,) slot from which nothing is served (the download window closed); n_slots where
    there is no window."""
    return np.array(
        [m.n_slots if m.window_slots is None else m.window_slots for m in missions], np.int64
    )


def check_actions(action: BatchAction, n_flights: int, n_sensors: int, who: str) -> np.ndarray:
    """(B,) the served sensor of a batched action (NO_SENSOR for none); SkymuleError naming
    the first bad value and what is allowed."""
    serve = np.asarray(action.serve)  # no copy for an array
    if serve.shape != (n_flights,) or serve.dtype.kind not in "iu":
        raise SkymuleError(
            f"policy {who!r} returned serve of shape {serve.shape} and dtype {serve.dtype}; "
            f"allowed: integers of shape ({n_flights},), -1 for none"
        )
    if serve.min() < NO_SENSOR or serve.max() >= n_sensors:
        bad = (serve < NO_SENSOR) | (serve >= n_sensors)
        raise SkymuleError(
            f"policy {who!r} chose sensor {int(serve[np.argmax(bad)])}; allowed: "
            f"0..{n_sensors - 1} or -1 (none)"
        )
    return serve.astype(np.int64, copy=False)


def check_flags(values: np.ndarray | None, n_flights: int, field: str, who: str) -> np.ndarray:
    """(B,) bool flags of a batched action (all False for None)."""
    if values is None:
        return np.zeros(n_flights, bool)
    flags = values if isinstance(values, np.ndarray) else np.asarray(values)
    if flags.shape != (n_flights,) or flags.dtype != bool:
        raise SkymuleError(
            f"policy {who!r} returned {field} of shape {flags.shape} and dtype {flags.dtype}; "
            f"allowed: booleans of shape ({n_flights},)"
        )
    return flags


def fleet_columns(fleet: np.ndarray | None, n_flights: int) -> tuple[np.ndarray, int]:
    """(B,) the buffer set (fleet mission) of each column and the UAVs per fleet mission K.

    Columns of one fleet mission are contiguous and every fleet mission has K UAVs."""
    if fleet is None:
        return np.arange(n_flights), 1
    fleet = np.asarray(fleet, np.int64)
    size = int(np.bincount(fleet).max())
    if (
        fleet.shape != (n_flights,)
        or n_flights % size
        or np.any(fleet != np.repeat(np.arange(n_flights // size), size))
    ):
        raise ValueError("fleet columns must be contiguous, K UAVs per fleet mission")
    return fleet, size


def affected_slots(faults: Sequence[Any], width: int) -> np.ndarray | None:
    """(B, T) slots a per-slot fault touched, or None when no flight has faults."""
    if all(f is None for f in faults):
        return None
    out = np.zeros((len(faults), width), bool)
    for b, draws in enumerate(faults):
        if draws is not None:
            touched = draws.affected[:width]
            out[b, : touched.shape[0]] = touched
    return out


def flights_record(missions: Sequence[Mission], policies: Sequence[str], **arrays: Any) -> Flights:
    """A :class:`Flights` record of ``missions`` (one per column) from the engine's arrays,
    with each mission's home, hover points, visit radius and AADM window."""
    n_sensors = missions[0].n_sensors
    home, hover, radius, window = mission_geometry(missions, n_sensors)
    faulty = np.array([m.faults is not None for m in missions], bool)
    return Flights(
        faulty=faulty if faulty.any() else None,
        slot_s=np.array([m.slot_s for m in missions], float),
        buffers_bit=np.array([m.buffers_bit for m in missions], float).reshape(-1, n_sensors),
        home_m=home,
        hover_points_m=hover,
        visit_radius_m=radius,
        aadm_window_s=window,
        policy=tuple(policies),
        sensor_names=tuple(m.sensor_names for m in missions),
        **arrays,
    )


def mission_geometry(
    missions: Sequence[Mission], n_sensors: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What the summaries need of each mission besides its slots: home (B, 2) [m] (NaN: none),
    hover points (B, N, 2) [m] (NaN: unknown), visit radius (B,) [m], AADM window (B,) [s]."""
    home = _rows_by_object(list(map(attrgetter("home_m"), missions)), (2,))
    hover = _rows_by_object(list(map(attrgetter("hover_points_m"), missions)), (n_sensors, 2))
    radius = np.array([m.visit_radius_m for m in missions], float)
    window = np.array([m.score_window_s for m in missions], float)
    return home, hover, radius, window


def _rows_by_object(values: Sequence[np.ndarray | None], shape: tuple[int, ...]) -> np.ndarray:
    """(B, *shape) array of ``values`` (None: NaN), each distinct array object copied once:
    missions built from one geometry share these arrays. Grouped by object over an array of
    their ids (no Python per mission: a sweep's batch is thousands of missions)."""
    ids = np.fromiter(map(id, values), np.int64, len(values))
    _, first, which = np.unique(ids, return_index=True, return_inverse=True)
    distinct = np.full((len(first), *shape), np.nan)
    for row, index in enumerate(first.tolist()):
        value = values[index]
        if value is not None:
            distinct[row] = value
    return distinct[which.reshape(-1)]
