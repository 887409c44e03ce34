"""The batched engine: many fixed-trajectory missions at once, vectorised over missions x sensors.

:func:`run_batch` loops over slots only; every step is a numpy operation over the B missions
of the batch. It applies the slot contract through the same functions as the reference engine
(:func:`skymule.sim.engine.run_fixed`) and the reference policies (:mod:`skymule.sim.contract`:
served bits, the Greedy and HGAD choices, HGAD's hover state machine), and the test suite
compares the two value for value.

Missions that share a :class:`~skymule.flight.paths.Track` object (and rate table) share its
samples: tracks are stored once, (U, K_max, N), and every mission points at one of them
(stacking: :mod:`skymule.sim.batch_stack`).

Missions with per-slot fading (``Mission.fading_db``) run here too: their SNR and rate are
recomputed each slot from the track SNR plus that slot's fading, as the reference engine does.

Policies covered: :data:`BATCH_POLICIES` (``greedy`` and ``hgad``); other policies and
autonomous missions run through the reference engine (see :mod:`skymule.experiments.run`).

Two outputs: :func:`run_fixed_batch` gives one :class:`~skymule.sim.log.MissionLog` per mission
(for tests and users); :func:`summarize_fixed_batch` gives the ``metrics.summarize`` dictionaries
straight from the batched arrays, with no per-mission log, which is what sweeps use: from the
numpy loop, ``metrics.summaries`` of :func:`batch_flights`; from the compiled loop, each
mission's reductions as it ends (:mod:`skymule.sim.compiled_summaries`), equal value for value.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from skymule.errors import SkymuleError
from skymule.metrics import Flights, summaries, summary_dicts
from skymule.scenario import PolicySpec
from skymule.sim import contract
from skymule.sim.batch_fading import apply_fading
from skymule.sim.batch_faults import apply_faults
from skymule.sim.batch_stack import BATCH_POLICIES as BATCH_POLICIES
from skymule.sim.batch_stack import Batch as Batch
from skymule.sim.batch_stack import PolicyParams as PolicyParams
from skymule.sim.batch_stack import batchable as batchable
from skymule.sim.batch_stack import in_batches, mission_geometry
from skymule.sim.batch_stack import policy_params as policy_params
from skymule.sim.batch_stack import stack_missions as stack_missions
from skymule.sim.contract import NO_SENSOR
from skymule.sim.engine import track_log
from skymule.sim.log import MissionLog
from skymule.world import Mission


@dataclass(frozen=True)
class BatchResult:
    """What happened in every mission of a batch, slot by slot (T_max = max n_slots).

    Row b holds mission b; only its first ``n_run[b]`` slots happened.

    Attributes:
        served: (B, T_max) served sensor, or NO_SENSOR.
        downloaded_bit: (B, T_max) bits downloaded in each slot.
        hovering: (B, T_max) True where the UAV held its position after the slot.
        sample: (B, T_max) track sample the UAV was at during each slot.
        n_run: (B,) slots each mission ran (a recorded trace may end a mission early).
        remaining_bit: (B, T_max, N) buffers after each slot's download [bit] (None when
            the run was asked not to keep them: summaries need only ``left_bit``).
        end_sample: (B,) track sample after the last slot.
        left_bit: (B, N) buffers after the last slot [bit].
        chosen: (B, T_max) the sensor each policy chose when some mission has faults (then
            ``served`` is NO_SENSOR where a fault blocked it), else None.
    """

    served: np.ndarray
    downloaded_bit: np.ndarray
    hovering: np.ndarray
    sample: np.ndarray
    n_run: np.ndarray
    remaining_bit: np.ndarray | None
    end_sample: np.ndarray
    left_bit: np.ndarray
    chosen: np.ndarray | None = None


Engine = Literal["auto", "numpy", "compiled"]
"""Which slot loop runs a batch: ``numpy`` (the reference), ``compiled`` (numba, the ``fast``
extra; :mod:`skymule.sim.compiled`) or ``auto`` (compiled when numba is installed and
:func:`skymule.sim.compiled.can_run` the batch: no per-slot fading, no SNR error on a
non-step rate table; else numpy). Both give the same result, value for value."""


def run_batch(batch: Batch, engine: Engine = "auto", keep_remaining: bool = True) -> BatchResult:
    """Run every mission of ``batch`` through the slot loop ``engine`` chose.

    ``keep_remaining=False``: no (B, T, N) buffer log (``remaining_bit`` None), which
    summaries do not need.
    """
    if chosen_engine(batch, engine) == "compiled":
        return run_compiled(batch, keep_remaining)
    return run_numpy(batch, keep_remaining)


def chosen_engine(batch: Batch, engine: Engine) -> Literal["numpy", "compiled"]:
    """The slot loop ``engine`` means for ``batch``; a one-line error if it cannot run it."""
    from skymule.sim import compiled

    if engine not in ("auto", "numpy", "compiled"):
        raise SkymuleError(f"engine = {engine!r}; allowed: auto, numpy, compiled")
    if engine == "numpy":
        return "numpy"
    why = compiled.can_run(batch)
    if engine == "compiled" and why is not None:
        raise SkymuleError(f"engine = 'compiled' cannot run this batch: {why}")
    return "numpy" if why is not None else "compiled"


def run_compiled(batch: Batch, keep_remaining: bool = True) -> BatchResult:
    """The batch through :func:`skymule.sim.compiled.slot_loop`, compiled (``can_run``).

    ``keep_remaining=False``: no (B, T, N) buffer log (``remaining_bit`` None).
    """
    from skymule.sim import compiled

    n_missions, n_sensors = batch.buffers_bit.shape
    t_max = int(batch.n_slots.max())
    faults, chosen = compiled.loop_faults(batch)
    result = BatchResult(
        served=np.full((n_missions, t_max), NO_SENSOR, np.int64),
        downloaded_bit=np.zeros((n_missions, t_max)),
        hovering=np.zeros((n_missions, t_max), bool),
        sample=np.zeros((n_missions, t_max), np.int64),
        n_run=np.zeros(n_missions, np.int64),
        remaining_bit=np.zeros((n_missions, t_max, n_sensors)) if keep_remaining else None,
        end_sample=np.zeros(n_missions, np.int64),
        left_bit=np.zeros((n_missions, n_sensors)),
        chosen=chosen,
    )
    compiled.compiled_loop()(
        *compiled.loop_inputs(batch), True, keep_remaining,
        result.served, result.downloaded_bit, result.hovering, result.sample,
        np.zeros((0, 0, 0)) if result.remaining_bit is None else result.remaining_bit,
        result.n_run, result.end_sample, result.left_bit, False, *compiled.no_totals(n_sensors),
        faults, chosen,
    )  # fmt: skip
    return result


def run_numpy(batch: Batch, keep_remaining: bool = True) -> BatchResult:
    """Run every mission of ``batch``; one numpy step per slot over all missions.

    ``keep_remaining=False``: no (B, T, N) buffer log (``remaining_bit`` None).

    Inside, arrays are sensor-major (N, B): per-slot reductions over sensors are then N
    elementwise steps over missions, which is what makes small N fast.
    """
    n_missions, n_sensors = batch.buffers_bit.shape
    k_rows = batch.rate_bps.shape[1]
    t_max = int(batch.n_slots.max())
    columns = np.arange(n_missions)
    # slot at which each mission's download window closes (the AADM controller's 500 s)
    window = batch.window_slots
    first_close = int(window.min()) if window.size else 0
    # one (2N, U*K) table [rate ; snr seen]: a single column gather per slot; a trace that
    # ran out points one sample past its end, which is padding (the mission is over)
    table = np.ascontiguousarray(
        np.concatenate([batch.rate_bps, batch.snr_seen_db], axis=2).reshape(-1, 2 * n_sensors).T
    )
    base_row = batch.track_id * k_rows
    n_samples = batch.n_samples[batch.track_id]
    last_sample = n_samples - 1
    # a planned path holds at its last sample; a trace may step one past it (the end)
    limit = np.where(batch.hold_at_end[batch.track_id], last_sample, n_samples)
    peak = np.ascontiguousarray(batch.peak_rate_bps[batch.track_id].T).ravel()
    threshold = np.ascontiguousarray(batch.threshold_bps.T).ravel()
    n_slots = batch.n_slots
    dt = batch.slot_s
    is_hgad = batch.hgad
    any_hgad = bool(is_hgad.any())
    any_greedy = not bool(is_hgad.all())
    any_fading = batch.fading_index.size > 0
    any_faults = batch.faults.any

    remaining = np.ascontiguousarray(batch.buffers_bit.astype(float).T)
    remaining_flat = remaining.reshape(-1)
    sample = np.zeros(n_missions, np.int64)
    state = contract.HoverState.start(n_sensors, n_missions)
    # slot-major logs: each slot writes one contiguous block
    served_log = np.full((t_max, n_missions), NO_SENSOR, np.int64)
    downloaded_log = np.zeros((t_max, n_missions))
    remaining_log = np.zeros((t_max, n_sensors, n_missions) if keep_remaining else (0, 0, 0))
    hovering_log = np.zeros((t_max, n_missions), bool)
    sample_log = np.zeros((t_max, n_missions), np.int64)
    n_run = np.zeros(n_missions, np.int64)
    chosen_log = np.full((t_max, n_missions), NO_SENSOR, np.int64) if any_faults else None
    no_hover = np.zeros(n_missions, bool)  # Greedy's hover flags (never written to)
    all_missions = np.ones(n_missions, bool)
    # a planned path holds at its last sample, so its missions run until their last slot
    holds = (batch.hold_at_end & (batch.n_samples > 0))[batch.track_id].all()
    every_active = int(n_slots.min()) if holds else 0

    for slot in range(t_max):
        if slot < every_active:  # no mission can have ended yet: skip the per-slot masks
            active, all_active = all_missions, True
        else:
            active = (slot < n_slots) & (sample < n_samples)
            all_active = bool(active.all())
            if not active.any():
                break
        observed = table.take(base_row + sample, axis=1)
        rate = observed[:n_sensors]
        snr = observed[n_sensors:]
        if any_fading:
            apply_fading(
                batch.fading_index, batch.fading_db[slot], batch.rate_model, batch.rate_models,
                rate, snr,
            )  # fmt: skip
        if any_faults:  # the policy sees the faulty SNR; `deliver` is what serving yields
            rate, snr, deliver, ok = apply_faults(batch.faults, slot, rate, snr)
        has_data = contract.servable(rate, remaining)
        if any_hgad and any_greedy:
            choice = np.where(
                is_hgad,
                contract.hgad_choice(rate, snr, has_data),
                contract.greedy_choice(snr, has_data),
            )
        elif any_hgad:
            choice = contract.hgad_choice(rate, snr, has_data)
        else:
            choice = contract.greedy_choice(snr, has_data)
        sensor = contract.hover_sensor_or(state, choice) if any_hgad else choice
        if not all_active:
            sensor[~active] = NO_SENSOR
        cell = contract.cells(sensor, columns)
        left = remaining_flat.take(cell)
        rate_served = rate.reshape(-1).take(cell)
        bits = contract.served_bits(rate_served, left, dt)
        bits[sensor < 0] = 0.0
        left_after = left - bits  # what the policy expects after this slot
        served, left_taken = sensor, left_after  # ... and what the buffers hold after it
        closed = slot >= window if slot >= first_close else None
        if closed is not None and closed.any():  # the window has closed: nothing is delivered
            served = np.where(closed, NO_SENSOR, sensor)
            bits = np.where(closed, 0.0, bits)
            left_taken = left - bits
        if chosen_log is not None:  # a fault blocks the choice: 0 bits, nothing served
            chosen_log[slot] = served
            served = np.where(ok.reshape(-1).take(cell), served, NO_SENSOR)
            true_bits = contract.served_bits(deliver.reshape(-1).take(cell), left, dt)
            bits = np.where(served >= 0, true_bits, 0.0)
            left_taken = left - bits
        remaining_flat[cell] = left_taken
        if any_hgad:
            hover_flag = contract.hgad_update(
                state,
                sensor=sensor,
                cell=cell,
                rate_bps=rate,
                rate_served_bps=rate_served,
                left_after_bit=left_after,
                threshold_bps=threshold,
                peak_rate_bps=peak,
                max_hover_s=batch.max_hover_s,
                slot_s=dt,
                enabled=is_hgad,
                active=active,
            )
        else:
            hover_flag = no_hover
        served_log[slot] = served
        downloaded_log[slot] = bits
        if keep_remaining:
            remaining_log[slot] = remaining
        hovering_log[slot] = hover_flag
        sample_log[slot] = sample
        n_run += active
        sample += ~hover_flag if all_active else active & ~hover_flag
        np.minimum(sample, limit, out=sample)

    return BatchResult(
        served=served_log.T,
        downloaded_bit=downloaded_log.T,
        hovering=hovering_log.T,
        sample=sample_log.T,
        n_run=n_run,
        remaining_bit=remaining_log.transpose(2, 0, 1) if keep_remaining else None,
        end_sample=np.minimum(sample, last_sample),
        left_bit=np.ascontiguousarray(remaining.T),
        chosen=None if chosen_log is None else chosen_log.T,
    )


def mission_log(
    batch: Batch, result: BatchResult, b: int, mission: Mission, policy: str
) -> MissionLog:
    """Mission b's :class:`MissionLog`, field for field as ``engine.run_fixed`` makes it."""
    n = int(result.n_run[b])
    u = int(batch.track_id[b])
    assert result.remaining_bit is not None, "run_batch(..., keep_remaining=True) for logs"
    return track_log(
        mission,
        policy,
        result.sample[b, :n],
        int(result.end_sample[b]),
        batch.rate_bps[u],
        served=result.served[b, :n].copy(),
        downloaded_bit=result.downloaded_bit[b, :n].copy(),
        remaining_bit=result.remaining_bit[b, :n].copy(),
        hovering=result.hovering[b, :n].copy(),
        affected=None if mission.faults is None else np.array(mission.faults.affected[:n]),
        chosen=None
        if mission.faults is None or result.chosen is None
        else result.chosen[b, :n].copy(),
    )


def _batches(missions: Sequence[Mission], batch_size: int) -> Iterator[list[int]]:
    """Indices of ``missions`` in batches of one sensor count, at most ``batch_size`` each."""
    groups: dict[int, list[int]] = {}
    for index, mission in enumerate(missions):
        groups.setdefault(mission.n_sensors, []).append(index)
    return in_batches(groups.values(), batch_size)


def run_fixed_batch(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    batch_size: int = 1000,
    engine: Engine = "auto",
) -> list[MissionLog]:
    """Logs of fixed-trajectory missions (one policy spec each), in input order.

    Equal to ``[engine.run_fixed(m, make_policy(s)) for m, s in zip(missions, specs)]``.
    Missions are grouped by sensor count and run ``batch_size`` at a time (memory grows as
    batch_size x T_max x N).
    """
    logs: list[MissionLog | None] = [None] * len(missions)
    for part in _batches(missions, batch_size):
        batch = stack_missions([missions[i] for i in part], [specs[i] for i in part])
        result = run_batch(batch, engine)
        for b, i in enumerate(part):
            logs[i] = mission_log(batch, result, b, missions[i], specs[i].name)
    return [log for log in logs if log is not None]


def batch_flights(batch: Batch, result: BatchResult, missions: Sequence[Mission]) -> Flights:
    """The batch's arrays as :class:`~skymule.metrics.Flights` (tracks shared, no copies of
    positions per mission), with each mission's home, hover points and visit radius."""
    home, hover, radius, window = mission_geometry(missions, batch.buffers_bit.shape[1])
    return Flights(
        n_run=result.n_run,
        slot_s=batch.slot_s,
        buffers_bit=batch.buffers_bit,
        left_bit=result.left_bit,
        served=result.served,
        downloaded_bit=result.downloaded_bit,
        hovering=result.hovering,
        track_position_m=batch.position_m,
        track_samples=batch.n_samples,
        track_id=batch.track_id,
        sample=result.sample,
        end_sample=result.end_sample,
        home_m=home,
        hover_points_m=hover,
        visit_radius_m=radius,
        aadm_window_s=window,
    )


def summarize_fixed_batch(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    scenario_names: Sequence[str],
    batch_size: int = 1000,
    engine: Engine = "auto",
) -> list[dict[str, Any]]:
    """``metrics.summarize`` dictionaries of fixed-trajectory missions, in input order.

    Equal to ``[summarize(run_fixed(m, make_policy(s)), name) ...]``, but no
    :class:`~skymule.sim.log.MissionLog` is built: the summaries come from the batch arrays
    (``engine="numpy"``: ``metrics.summaries`` of the numpy loop's logs, the reference;
    compiled loop: each mission reduced as it ends, no per-slot log at all; ``auto`` on a
    batch the compiled loop does not run: one compiled pass over the numpy loop's logs, see
    :mod:`skymule.sim.compiled_summaries`). Every way gives the same values.
    """
    from skymule.sim import compiled
    from skymule.sim.compiled_summaries import compiled_summaries, flights_summaries

    rows: list[dict[str, Any] | None] = [None] * len(missions)
    for part in _batches(missions, batch_size):
        chosen = [missions[i] for i in part]
        batch = stack_missions(chosen, [specs[i] for i in part])
        if chosen_engine(batch, engine) == "compiled":
            summary = compiled_summaries(batch, chosen)
        else:
            flights = batch_flights(batch, run_numpy(batch, keep_remaining=False), chosen)
            # auto with numba (a batch with fading or faults): one compiled pass over the logs
            fast = engine == "auto" and compiled.available()
            summary = flights_summaries(flights) if fast else summaries(flights)
        dicts = summary_dicts(
            summary,
            [m.sensor_names for m in chosen],
            [specs[i].name for i in part],
            [scenario_names[i] for i in part],
        )
        for i, row in zip(part, dicts, strict=True):
            rows[i] = row
    return [row for row in rows if row is not None]
