"""Summaries of a batch straight from the compiled slot loop, with no per-slot log.

``summarize_fixed_batch(..., engine="compiled")`` (and ``"auto"`` when numba is installed)
lands here. The compiled loop (:func:`skymule.sim.compiled.slot_loop`) reduces each mission's
slots as soon as the mission ends (:func:`skymule.sim.summary_kernels.mission_totals`), so
the (B, T) logs that ``metrics.summaries`` reads back are never written; what is left is
per-mission arithmetic, shared with the reference through
:func:`skymule.metrics.summaries_from_totals`. The result equals
``metrics.summaries(batch_flights(...))`` (the numpy path) to a relative 1e-12 (its sums run
in another order), counts and flags exactly.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

import skymule.metrics.summary as metrics
from skymule.metrics import visits
from skymule.metrics.flights import Flights
from skymule.rules import contract
from skymule.rules.score import COMPLETE_RTOL, aadm_from_progress
from skymule.sim import compiled, summary_kernels
from skymule.sim.columns import mission_geometry

if TYPE_CHECKING:
    from skymule.sim.fixed import FixedEngine


def summary_tables(
    track_position_m: np.ndarray,
    track_samples: np.ndarray,
    track_id: np.ndarray,
    slot_s: np.ndarray,
    hover_points_m: np.ndarray,
    visit_radius_m: np.ndarray,
    buffers_bit: np.ndarray,
    window_s: np.ndarray,
    width: int,
    near_rows: np.ndarray | None = None,
) -> summary_kernels.SummaryTables:
    """The lookup tables of the reductions (``metrics``'s own table functions) for missions
    on tracks ``track_position_m`` (U, K, 3) whose padded slot arrays are ``width`` long.

    The first track samples near each sensor are looked up for missions ``near_rows`` only
    (None: all); the others, whose first visits come from their targets, get "never"."""
    steps, power, pair = metrics.power_tables(track_position_m, track_samples, track_id, slot_s)
    if near_rows is None:
        near, group = visits.near_samples(
            track_position_m, track_samples, track_id, hover_points_m, visit_radius_m
        )
    else:
        near, group = _near_of_rows(
            near_rows, track_position_m, track_samples, track_id, hover_points_m, visit_radius_m
        )
    # aadm_scores pads arrays with no slot to one; it masks slots per mission only when some
    # window closes before the last slot of the padded arrays
    width = max(width, 1)
    inside = contract.window_slots(window_s, slot_s)
    per_slot = bool((inside < width).any())
    return summary_kernels.SummaryTables(
        steps_m=steps,
        power_w=power,
        pair=pair,
        near=near,
        group=group,
        aadm_threshold_bit=buffers_bit.sum(axis=1) * (1.0 - COMPLETE_RTOL),
        aadm_window_slots=np.broadcast_to(inside, window_s.shape).astype(float),
        aadm_per_slot=per_slot,
        width=width,
    )


def _near_of_rows(
    rows: np.ndarray,
    track_position_m: np.ndarray,
    track_samples: np.ndarray,
    track_id: np.ndarray,
    hover_points_m: np.ndarray,
    visit_radius_m: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """``metrics.near_samples`` of missions ``rows``, plus a last row of K (never near) that
    every other mission points at: near_samples loops over its distinct rows in Python, and
    an autonomous batch has one track per mission."""
    n_missions, n_sensors = hover_points_m.shape[:2]
    near = np.zeros((0, n_sensors), np.int64)
    group = np.zeros(0, np.int64)
    if rows.size:
        near, group = visits.near_samples(
            track_position_m, track_samples, track_id[rows], hover_points_m[rows],
            visit_radius_m[rows],
        )  # fmt: skip
    never = np.full((1, n_sensors), track_position_m.shape[1], np.int64)
    groups = np.full(n_missions, near.shape[0], np.int64)
    groups[rows] = group
    return np.concatenate([near, never]), groups


def target_tables(flights: Flights) -> summary_kernels.TargetTables:
    """What :func:`~skymule.sim.summary_kernels.first_target_arrivals` looks up, with
    ``visits.first_visit_slots``'s choice of rows: with targets, the missions that ran some
    slots and know some hover point (none without targets)."""
    n_missions = flights.n_run.shape[0]
    if flights.target is None:
        return summary_kernels.TargetTables(
            target=np.zeros((0, 0), np.int64),
            by_target=np.zeros(n_missions, np.bool_),
            position_m=np.zeros((0, 0, 3)),
            track_id=np.zeros(0, np.int64),
            end_sample=np.zeros(0, np.int64),
            hover_points_m=np.zeros((0, 0, 2)),
            visit_radius_m=np.zeros(0),
        )
    known = np.isfinite(flights.hover_points_m).any(axis=(1, 2))
    return summary_kernels.TargetTables(
        target=np.ascontiguousarray(flights.target, np.int64),
        by_target=(flights.n_run > 0) & known,
        position_m=np.ascontiguousarray(flights.track_position_m, float),
        track_id=np.ascontiguousarray(flights.track_id, np.int64),
        end_sample=np.ascontiguousarray(flights.end_sample, np.int64),
        hover_points_m=np.ascontiguousarray(flights.hover_points_m, float),
        visit_radius_m=np.ascontiguousarray(flights.visit_radius_m, float),
    )


def summaries_from_slot_totals(
    totals: summary_kernels.SlotTotals,
    *,
    n_run: np.ndarray,
    slot_s: np.ndarray,
    buffers_bit: np.ndarray,
    left_bit: np.ndarray,
    end_m: np.ndarray,
    home_m: np.ndarray,
    window_s: np.ndarray,
) -> metrics.Summaries:
    """:class:`~skymule.metrics.Summaries` from the reductions and each mission's ends (end
    position ``end_m`` (B, 3) [m], buffers left)."""
    return metrics.summaries_from_totals(
        n_run=n_run,
        slot_s=slot_s,
        buffers_bit=buffers_bit,
        left_bit=left_bit,
        downloaded_bit=totals.downloaded_bit,
        distance_m=totals.distance_m,
        power_sum_w=totals.power_sum_w,
        handovers=totals.handovers,
        hover_slots=totals.hover_slots,
        first_visit=totals.first_visit,
        distance_to_home_m=metrics.horizontal_distance_m(end_m, home_m),
        aadm=aadm_from_progress(
            buffers_bit.sum(axis=1),
            np.maximum(n_run, 0) * slot_s,
            slot_s,
            window_s,
            totals.aadm_bit,
            totals.aadm_first,
        ),
    )


def compiled_summaries(engine: FixedEngine, rule: Any, loop: Any = None) -> metrics.Summaries:
    """``metrics.summaries`` of a fresh fixed ``engine``'s flights under a policy's compiled
    rule (``fixed.compiled_reason`` None), from the compiled loop's per-mission
    reductions: no per-slot log is written. ``loop`` as in ``fixed.run_compiled``."""
    from skymule.sim.fixed import compiled_faults, compiled_inputs

    missions = engine.missions
    tables_in = engine.tables
    n_missions, n_sensors = len(missions), engine.n_sensors
    home, hover, radius, window = mission_geometry(missions, n_sensors)
    buffers = np.array([m.buffers_bit for m in missions], float).reshape(-1, n_sensors)
    tables = summary_tables(
        tables_in.position_m, tables_in.n_samples, tables_in.track_id, engine.slot_s, hover,
        radius, buffers, window, int(engine.n_slots.max()),
    )  # fmt: skip
    totals = summary_kernels.new_totals(n_missions, n_sensors)
    n_run = np.zeros(n_missions, np.int64)
    end_sample = np.zeros(n_missions, np.int64)
    left = np.zeros((n_missions, n_sensors))
    (compiled.compiled_loop() if loop is None else loop)(
        *compiled_inputs(engine, rule), False, False, *compiled.no_logs(),
        n_run, end_sample, left, True, tables, totals, compiled_faults(engine), None,
    )  # fmt: skip
    return summaries_from_slot_totals(
        totals,
        n_run=n_run,
        slot_s=engine.slot_s,
        buffers_bit=buffers,
        left_bit=left,
        end_m=tables_in.position_m[tables_in.track_id, end_sample],
        home_m=home,
        window_s=window,
    )


def flights_summaries(flights: Flights, use_numba: bool = True) -> metrics.Summaries:
    """``metrics.summaries(flights)`` by the kernels, one pass over the slot arrays (compiled
    unless ``use_numba`` is False: then plain Python, as the tests run it).

    For fixed-trajectory flights, e.g. the numpy loop's logs of a batch with fading or
    faults, which the compiled loop does not run, and for autonomous ones (with targets: the
    batched autonomous engine's), whose first visits follow the targets.
    """
    n_missions, n_sensors = flights.buffers_bit.shape
    window = flights.score_windows_s()
    targets = target_tables(flights)
    near_rows = None if flights.target is None else np.flatnonzero(~targets.by_target)
    tables = summary_tables(
        flights.track_position_m, flights.track_samples, flights.track_id, flights.slot_s,
        flights.hover_points_m, flights.visit_radius_m, flights.buffers_bit, window,
        flights.downloaded_bit.shape[1], near_rows,
    )  # fmt: skip
    totals = summary_kernels.new_totals(n_missions, n_sensors)
    reduce = compiled.compiled_reduce() if use_numba else summary_kernels.reduce_rows
    reduce(
        np.ascontiguousarray(flights.served), np.ascontiguousarray(flights.downloaded_bit),
        np.ascontiguousarray(flights.hovering), np.ascontiguousarray(flights.sample),
        flights.n_run, flights.slot_s, tables, totals, targets,
    )  # fmt: skip
    return summaries_from_slot_totals(
        totals,
        n_run=flights.n_run,
        slot_s=flights.slot_s,
        buffers_bit=flights.buffers_bit,
        left_bit=flights.left_bit,
        end_m=flights.track_position_m[flights.track_id, flights.end_sample],
        home_m=flights.home_m,
        window_s=window,
    )
