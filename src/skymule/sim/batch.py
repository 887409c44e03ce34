"""The batched engine: many fixed-trajectory missions at once, vectorised over missions x sensors.

:func:`run_batch` loops over slots only; every step is a numpy operation over the B missions
of the batch. It obeys the slot contract exactly as the reference engine
(:func:`skymule.sim.engine.run_fixed`) and the reference policies do, including their tie rules
and HGAD's state machine (cooldown, hover budget, trigger), and the test suite compares the two
value for value.

Missions that share a :class:`~skymule.flight.paths.Track` object (and rate table) share its
samples: tracks are stored once, (U, K_max, N), and every mission points at one of them.

Missions with per-slot fading (``Mission.fading_db``) run here too: their SNR and rate are
recomputed each slot from the track SNR plus that slot's fading, as the reference engine does.

Policies covered: :data:`BATCH_POLICIES` (``greedy`` and ``hgad``); other policies and
autonomous missions run through the reference engine (see :mod:`skymule.experiments.run`).

Two outputs: :func:`run_fixed_batch` gives one :class:`~skymule.sim.engine.MissionLog` per mission
(for tests and users); :func:`summarize_fixed_batch` gives the ``metrics.summarize`` dictionaries
straight from the batched arrays (:func:`summarize_batch`), with no per-mission log, which is
what sweeps use.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from skymule.energy import propulsion_power_w
from skymule.errors import SkymuleError
from skymule.flight.paths import Track
from skymule.metrics import (
    AADM_LANDING_TOLERANCE_M,
    AADM_PENALTY_PER_M,
    AADM_REFERENCE_S,
    BITS_PER_MBIT,
)
from skymule.radio.rates import RateTable, rate_bps
from skymule.scenario import PolicySpec
from skymule.sim.engine import NO_SENSOR, MissionLog
from skymule.world import Mission

HOVER_EPS_S = 1e-12
"""A hover ends once its budget is at or below this [s] (as in ``policies/hgad.py``)."""


@dataclass(frozen=True)
class PolicyParams:
    """Per-mission policy parameters the batched loop understands.

    Attributes:
        hgad: True for HGAD, False for Greedy.
        hover_threshold: HGAD trigger fraction of the peak rate (unused for Greedy).
        max_hover_s: HGAD longest hover [s] (unused for Greedy).
    """

    hgad: bool
    hover_threshold: float = 1.0
    max_hover_s: float = 0.0


BATCH_POLICIES: dict[str, Callable[[PolicySpec], PolicyParams]] = {
    "greedy": lambda spec: PolicyParams(hgad=False),
    "hgad": lambda spec: PolicyParams(True, spec.hover_threshold, spec.max_hover_s),
}
"""Policies with a batched implementation: name -> parameters from the ``[policy]`` section."""


def batchable(mission: Mission, spec: PolicySpec) -> bool:
    """True if ``mission`` under ``spec`` can run in the batched engine."""
    return mission.track is not None and spec.name in BATCH_POLICIES


@dataclass(frozen=True)
class Batch:
    """B missions stacked for the slot loop (U distinct tracks, K_max samples, N sensors).

    Attributes:
        track_id: (B,) index of each mission's track in the track arrays.
        rate_bps: (U, K_max + 1, N) rate at each track sample [bit/s] (0 in padding).
        snr_db: (U, K_max, N) track SNR [dB] (NaN: no sample).
        snr_seen_db: (U, K_max, N) SNR as policies see it (NaN -> -inf) [dB].
        position_m: (U, K_max, 3) sample positions [m].
        peak_rate_bps: (U, N) largest rate per sensor over each track [bit/s].
        n_samples: (U,) track lengths K.
        hold_at_end: (U,) True: hold at the last sample; False: a trace that runs out.
        n_slots: (B,) slots per mission T.
        slot_s: (B,) slot length [s].
        buffers_bit: (B, N) initial buffers [bit].
        hgad: (B,) True for HGAD missions, False for Greedy.
        threshold_bps: (B, N) HGAD trigger thresholds gamma_i [bit/s].
        max_hover_s: (B,) HGAD longest hover [s].
        fading_index: (F,) the missions with per-slot fading (F may be 0).
        fading_db: (T_max, N, F) their fading [dB] added to the SNR seen in slot t (0 past
            a mission's last slot).
        rate_model: (F,) index of each fading mission's rate model in ``rate_models``.
        rate_models: (rate table, bandwidth [Hz]) pairs turning faded SNR into rate.
    """

    track_id: np.ndarray
    rate_bps: np.ndarray
    snr_db: np.ndarray
    snr_seen_db: np.ndarray
    position_m: np.ndarray
    peak_rate_bps: np.ndarray
    n_samples: np.ndarray
    hold_at_end: np.ndarray
    n_slots: np.ndarray
    slot_s: np.ndarray
    buffers_bit: np.ndarray
    hgad: np.ndarray
    threshold_bps: np.ndarray
    max_hover_s: np.ndarray
    fading_index: np.ndarray
    fading_db: np.ndarray
    rate_model: np.ndarray
    rate_models: tuple[tuple[RateTable, float], ...]

    @property
    def size(self) -> int:
        return int(self.track_id.shape[0])


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
        remaining_bit: (B, T_max, N) buffers after each slot's download [bit].
        end_sample: (B,) track sample after the last slot.
    """

    served: np.ndarray
    downloaded_bit: np.ndarray
    hovering: np.ndarray
    sample: np.ndarray
    n_run: np.ndarray
    remaining_bit: np.ndarray
    end_sample: np.ndarray


def policy_params(spec: PolicySpec) -> PolicyParams:
    factory = BATCH_POLICIES.get(spec.name)
    if factory is None:
        raise SkymuleError(
            f"policy.name = {spec.name!r} has no batched engine; "
            f"allowed: {', '.join(sorted(BATCH_POLICIES))}"
        )
    return factory(spec)


def stack_missions(missions: Sequence[Mission], specs: Sequence[PolicySpec]) -> Batch:
    """Stack fixed-trajectory missions with the same number of sensors into a :class:`Batch`."""
    if not missions:
        raise ValueError("stack_missions needs at least one mission")
    n_sensors = {m.n_sensors for m in missions}
    if len(n_sensors) != 1:
        raise ValueError(f"a batch needs one sensor count, got {sorted(n_sensors)}")
    n = n_sensors.pop()
    keys: dict[tuple[int, int, float], int] = {}
    unique: list[Mission] = []
    tracks: list[Track] = []  # unique[u].track
    track_id = np.empty(len(missions), np.int64)
    for b, mission in enumerate(missions):
        if mission.track is None:
            raise SkymuleError("the batched engine needs fixed trajectories (trajectory.mode)")
        key = (id(mission.track), id(mission.rate_table), mission.bandwidth_hz)
        if key not in keys:
            keys[key] = len(unique)
            unique.append(mission)
            tracks.append(mission.track)
        track_id[b] = keys[key]
    # one padding row past the longest track: where a used-up trace points
    k_max = max(t.n_samples for t in tracks) + 1
    rate = np.zeros((len(unique), k_max, n))
    snr = np.full((len(unique), k_max, n), np.nan)
    snr_seen = np.full((len(unique), k_max, n), -np.inf)
    position = np.zeros((len(unique), k_max, 3))
    peak = np.zeros((len(unique), n))
    for u, mission in enumerate(unique):
        track = mission.track
        assert track is not None
        k = track.n_samples
        rate[u, :k] = mission.rate_bps(track.snr_db)
        snr[u, :k] = track.snr_db
        snr_seen[u, :k] = np.nan_to_num(track.snr_db, nan=-np.inf)
        position[u, :k] = track.position_m
        peak[u] = mission.peak_rate_bps()
    params = [policy_params(spec) for spec in specs]
    thresholds = np.array([p.hover_threshold for p in params])
    fading_index, fading, rate_model, rate_models = _stack_fading(missions, n)
    return Batch(
        track_id=track_id,
        rate_bps=rate,
        snr_db=snr,
        snr_seen_db=snr_seen,
        position_m=position,
        peak_rate_bps=peak,
        n_samples=np.array([t.n_samples for t in tracks], np.int64),
        hold_at_end=np.array([t.hold_at_end for t in tracks], bool),
        n_slots=np.array([m.n_slots for m in missions], np.int64),
        slot_s=np.array([m.slot_s for m in missions], float),
        buffers_bit=np.array([m.buffers_bit for m in missions], float).reshape(-1, n),
        hgad=np.array([p.hgad for p in params], bool),
        threshold_bps=np.stack([t * peak[u] for t, u in zip(thresholds, track_id, strict=True)]),
        max_hover_s=np.array([p.max_hover_s for p in params], float),
        fading_index=fading_index,
        fading_db=fading,
        rate_model=rate_model,
        rate_models=rate_models,
    )


def _stack_fading(
    missions: Sequence[Mission], n_sensors: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[tuple[RateTable, float], ...]]:
    """The fading missions' indices (F,), fading (T_max, N, F) [dB], rate models (F,) + list.

    Fading of mission f is its ``fading_db`` (T, N), zero-padded to T_max slots.
    """
    index = [b for b, m in enumerate(missions) if m.fading_db is not None]
    t_max = max(m.n_slots for m in missions)
    fading = np.zeros((t_max, n_sensors, len(index)))
    models: dict[tuple[int, float], int] = {}
    tables: list[tuple[RateTable, float]] = []
    rate_model = np.empty(len(index), np.int64)
    for f, b in enumerate(index):
        mission = missions[b]
        gains = np.asarray(mission.fading_db, float)
        if gains.shape != (mission.n_slots, n_sensors):
            raise ValueError(
                f"fading_db has shape {gains.shape}; need (n_slots, N) = "
                f"({mission.n_slots}, {n_sensors})"
            )
        fading[: mission.n_slots, :, f] = gains
        key = (id(mission.rate_table), mission.bandwidth_hz)
        if key not in models:
            models[key] = len(tables)
            tables.append((mission.rate_table, mission.bandwidth_hz))
        rate_model[f] = models[key]
    return np.asarray(index, np.int64), fading, rate_model, tuple(tables)


def _apply_fading(batch: Batch, slot: int, rate: np.ndarray, snr: np.ndarray) -> None:
    """Add slot ``slot``'s fading to the SNR (N, B) of fading missions; recompute their rate.

    In place, as ``engine.run_fixed``: SNR seen + fading [dB], then the mission's rate table.
    """
    cols = batch.fading_index
    faded = snr[:, cols] + batch.fading_db[slot]
    snr[:, cols] = faded
    for model, (table, bandwidth_hz) in enumerate(batch.rate_models):
        pick = batch.rate_model == model
        rate[:, cols[pick]] = rate_bps(table, faded[:, pick], bandwidth_hz)


def _first_max(values: np.ndarray) -> np.ndarray:
    """(B,) first index of the maximum down each column of ``values`` (N, B), as np.argmax.

    Sensor-major layout: reductions over the short sensor axis run as N elementwise steps.
    """
    best = values == values.max(axis=0)
    return _first_true(best)


def _first_true(mask: np.ndarray) -> np.ndarray:
    """(B,) index of the first True down each column of ``mask`` (N, B); 0 if none."""
    index = np.zeros(mask.shape[1], np.int64)
    for sensor in range(mask.shape[0] - 1, 0, -1):
        index[mask[sensor]] = sensor
    index[mask[0]] = 0
    return index


def _greedy_choice(snr: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) argmax SNR over sensors with data (ties: lowest index), as ``greedy_choice``."""
    return _first_max(np.where(has_data, snr, -np.inf))


def _hgad_choice(rate: np.ndarray, snr: np.ndarray, has_data: np.ndarray) -> np.ndarray:
    """(B,) argmax rate over sensors with data; ties: higher SNR, then lowest index."""
    masked_rate = np.where(has_data, rate, -np.inf)
    best = masked_rate == masked_rate.max(axis=0)
    masked_snr = np.where(best, snr, -np.inf)
    best &= masked_snr == masked_snr.max(axis=0)
    return _first_true(best)


def run_batch(batch: Batch) -> BatchResult:
    """Run every mission of ``batch``; one numpy step per slot over all missions.

    Inside, arrays are sensor-major (N, B): per-slot reductions over sensors are then N
    elementwise steps over missions, which is what makes small N fast.
    """
    n_missions, n_sensors = batch.buffers_bit.shape
    k_rows = batch.rate_bps.shape[1]
    t_max = int(batch.n_slots.max())
    rows = np.arange(n_missions)
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
    threshold = np.ascontiguousarray(batch.threshold_bps.T)
    threshold_flat = threshold.ravel()
    n_slots = batch.n_slots
    dt = batch.slot_s
    is_hgad = batch.hgad
    any_hgad = bool(is_hgad.any())
    any_greedy = not bool(is_hgad.all())
    any_fading = batch.fading_index.size > 0

    remaining = np.ascontiguousarray(batch.buffers_bit.astype(float).T)
    remaining_flat = remaining.reshape(-1)
    sample = np.zeros(n_missions, np.int64)
    hover_sensor = np.full(n_missions, NO_SENSOR, np.int64)
    hovering = np.zeros(n_missions, bool)
    budget = np.zeros(n_missions)
    cooling = np.zeros(n_sensors * n_missions, bool)
    # slot-major logs: each slot writes one contiguous block
    served_log = np.full((t_max, n_missions), NO_SENSOR, np.int64)
    downloaded_log = np.zeros((t_max, n_missions))
    remaining_log = np.zeros((t_max, n_sensors, n_missions))
    hovering_log = np.zeros((t_max, n_missions), bool)
    sample_log = np.zeros((t_max, n_missions), np.int64)
    n_run = np.zeros(n_missions, np.int64)

    for slot in range(t_max):
        active = (slot < n_slots) & (sample < n_samples)
        if not active.any():
            break
        observed = table.take(base_row + sample, axis=1)
        rate = observed[:n_sensors]
        snr = observed[n_sensors:]
        if any_fading:
            _apply_fading(batch, slot, rate, snr)
        has_data = remaining > 0
        if any_hgad and any_greedy:
            choice = np.where(
                is_hgad, _hgad_choice(rate, snr, has_data), _greedy_choice(snr, has_data)
            )
        elif any_hgad:
            choice = _hgad_choice(rate, snr, has_data)
        else:
            choice = _greedy_choice(snr, has_data)
        choice[~has_data.any(axis=0)] = NO_SENSOR
        sensor = np.where(hovering, hover_sensor, choice)
        sensor[~active] = NO_SENSOR
        serving = sensor >= 0
        cell = np.maximum(sensor, 0) * n_missions + rows
        rate_s = rate.ravel().take(cell)
        left = remaining_flat.take(cell)
        bits = np.minimum(rate_s * dt, left)
        bits[~serving] = 0.0
        left_after = left - bits
        remaining_flat[cell] = left_after
        hover_flag = hovering & active
        if any_hgad:
            # start of slot: sensors below their threshold stop cooling down
            cooling &= ~(rate < threshold).ravel()
            # hovering: count dt off the budget; end after this slot when spent or emptied
            budget = np.where(hover_flag, budget - dt, budget)
            ends = hover_flag & ((budget <= HOVER_EPS_S) | (left_after <= 0))
            cooling[cell[ends]] = True
            hover_sensor[ends] = NO_SENSOR
            # not hovering: trigger a hover on the served sensor
            peak_s = peak.take(cell)
            trigger = (
                is_hgad
                & ~hover_flag
                & serving
                & (rate_s > 0)
                & (peak_s > 0)
                & (rate_s >= threshold_flat.take(cell))
                & (left_after > 0)
                & ~cooling.take(cell)
            )
            if trigger.any():
                chosen = np.flatnonzero(trigger)
                budget[chosen] = np.minimum(
                    left_after[chosen] / peak_s[chosen], batch.max_hover_s[chosen]
                )
                hover_sensor[chosen] = sensor[chosen]
                hover_flag = hover_flag | trigger
            hovering = hover_sensor >= 0
        served_log[slot] = sensor
        downloaded_log[slot] = bits
        remaining_log[slot] = remaining
        hovering_log[slot] = hover_flag
        sample_log[slot] = sample
        n_run += active
        sample[active & ~hover_flag] += 1
        np.minimum(sample, limit, out=sample)

    return BatchResult(
        served=served_log.T,
        downloaded_bit=downloaded_log.T,
        hovering=hovering_log.T,
        sample=sample_log.T,
        n_run=n_run,
        remaining_bit=remaining_log.transpose(2, 0, 1),
        end_sample=np.minimum(sample, last_sample),
    )


def mission_log(
    batch: Batch, result: BatchResult, b: int, mission: Mission, policy: str
) -> MissionLog:
    """Mission b's :class:`MissionLog`, field for field as ``engine.run_fixed`` makes it."""
    n = int(result.n_run[b])
    u = int(batch.track_id[b])
    index = result.sample[b, :n]
    snr_log, rate_log = batch.snr_db[u][index], batch.rate_bps[u][index]
    if mission.fading_db is not None:
        snr_log = snr_log + mission.fading_db[:n]
        rate_log = mission.rate_bps(snr_log)
    return MissionLog(
        policy=policy,
        sensor_names=mission.sensor_names,
        slot_s=mission.slot_s,
        buffers_bit=mission.buffers_bit.copy(),
        position_m=batch.position_m[u][index],
        end_position_m=batch.position_m[u, result.end_sample[b]].copy(),
        snr_db=snr_log,
        rate_bps=rate_log,
        served=result.served[b, :n].copy(),
        downloaded_bit=result.downloaded_bit[b, :n].copy(),
        remaining_bit=result.remaining_bit[b, :n].copy(),
        hovering=result.hovering[b, :n].copy(),
    )


def _batches(missions: Sequence[Mission], batch_size: int) -> Iterator[list[int]]:
    """Indices of ``missions`` in batches of one sensor count, at most ``batch_size`` each."""
    groups: dict[int, list[int]] = {}
    for index, mission in enumerate(missions):
        groups.setdefault(mission.n_sensors, []).append(index)
    for indices in groups.values():
        for start in range(0, len(indices), batch_size):
            yield indices[start : start + batch_size]


def run_fixed_batch(
    missions: Sequence[Mission], specs: Sequence[PolicySpec], batch_size: int = 1000
) -> list[MissionLog]:
    """Logs of fixed-trajectory missions (one policy spec each), in input order.

    Equal to ``[engine.run_fixed(m, make_policy(s)) for m, s in zip(missions, specs)]``.
    Missions are grouped by sensor count and run ``batch_size`` at a time (memory grows as
    batch_size x T_max x N).
    """
    logs: list[MissionLog | None] = [None] * len(missions)
    for part in _batches(missions, batch_size):
        batch = stack_missions([missions[i] for i in part], [specs[i] for i in part])
        result = run_batch(batch)
        for b, i in enumerate(part):
            logs[i] = mission_log(batch, result, b, missions[i], specs[i].name)
    return [log for log in logs if log is not None]


# --- vectorised summaries: metrics.summarize for every mission of a batch at once ---------


@dataclass(frozen=True)
class Geometry:
    """Per-mission geometry the summary needs (``engine_autonomous.fixed_geometry_fields``).

    Attributes:
        home_m: (B, 2) home point [m] (NaN: no home).
        hover_points_m: (B, N, 2) point each sensor is served from [m] (NaN: unknown).
        visit_radius_m: (B,) a sensor counts as visited within this distance [m].
    """

    home_m: np.ndarray
    hover_points_m: np.ndarray
    visit_radius_m: np.ndarray


def geometry_arrays(fields: Sequence[Mapping[str, Any] | None], n_sensors: int) -> Geometry:
    """Stack ``fixed_geometry_fields`` dicts (None or missing keys: as a bare run_fixed log)."""
    b = len(fields)
    home = np.full((b, 2), np.nan)
    hover = np.full((b, n_sensors, 2), np.nan)
    radius = np.full(b, 50.0)  # MissionLog.visit_radius_m default
    for row, field in enumerate(fields):
        field = field or {}
        if field.get("home_m") is not None:
            home[row] = field["home_m"]
        if field.get("hover_points_m") is not None:
            hover[row] = field["hover_points_m"]
        radius[row] = field.get("visit_radius_m", 50.0)
    return Geometry(home, hover, radius)


@dataclass(frozen=True)
class BatchSummary:
    """``metrics.summarize`` of every mission of a batch, as arrays (SI units, B missions).

    Attributes:
        slots: (B,) slots run T'.
        slot_s: (B,) slot length [s].
        mission_time_s: (B,) T' * slot_s [s].
        buffers_bit: (B, N) initial buffers [bit].
        total_buffer_bit: (B,) sum of the buffers [bit].
        total_downloaded_bit: (B,) bits downloaded [bit].
        per_sensor_downloaded_bit: (B, N) bits downloaded from each sensor [bit].
        completion: (B,) downloaded / buffered (1 with nothing buffered).
        handovers: (B,) changes of served sensor over the slots that served one.
        hover_time_s: (B,) time spent hovering [s].
        distance_m: (B,) distance flown [m].
        energy_j: (B,) propulsion energy [J].
        visit_order: (B, N) sensor indices in first-visit order, padded with NO_SENSOR.
        distance_to_home_m: (B,) horizontal end-to-home distance [m] (NaN: no home).
        aadm_score: (B,) AADM challenge score.
    """

    slots: np.ndarray
    slot_s: np.ndarray
    mission_time_s: np.ndarray
    buffers_bit: np.ndarray
    total_buffer_bit: np.ndarray
    total_downloaded_bit: np.ndarray
    per_sensor_downloaded_bit: np.ndarray
    completion: np.ndarray
    handovers: np.ndarray
    hover_time_s: np.ndarray
    distance_m: np.ndarray
    energy_j: np.ndarray
    visit_order: np.ndarray
    distance_to_home_m: np.ndarray
    aadm_score: np.ndarray


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
    """(B,) ``metrics.handovers`` of each mission from ``served`` (T, B), slot-major.

    Changes of served sensor over the slots that served one (NO_SENSOR slots skipped).
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
    """(U, K_max) distance from track sample k to k + 1 [m]; 0 at and past the last sample.

    A slot that does not hover moves the UAV exactly one such step (none at the end).
    """
    n_tracks, k_max = position_m.shape[:2]
    steps = np.zeros((n_tracks, k_max))
    steps[:, :-1] = np.linalg.norm(position_m[:, 1:] - position_m[:, :-1], axis=2)
    steps[np.arange(steps.shape[1]) >= n_samples[:, None] - 1] = 0.0
    return steps


def flight_totals(batch: Batch, result: BatchResult) -> tuple[np.ndarray, np.ndarray]:
    """(B,) distance flown [m] and (B,) propulsion energy [J], as ``metrics`` sums them.

    Per slot: step length (0 when hovering) and P(step / slot_s) [W], looked up in tables per
    distinct (track, slot length) with one extra column for a hover; then exact row sums.
    """
    pairs, pair = unique_rows(np.column_stack([batch.track_id, batch.slot_s]))
    k_max = batch.position_m.shape[1]
    steps = np.zeros((pairs.shape[0], k_max + 1))  # column k_max: a hover slot (0 m)
    steps[:, :k_max] = track_steps_m(batch.position_m, batch.n_samples)[pairs[:, 0].astype(int)]
    power = propulsion_power_w(steps / pairs[:, 1:2])
    # slot-major (T, B) lookups, then mission-major rows for the sums
    column = np.where(result.hovering.T, k_max, result.sample.T)
    index = np.ascontiguousarray((column + pair * (k_max + 1)).T)
    distance = row_sums(steps.take(index), result.n_run)
    energy = row_sums(power.take(index), result.n_run) * batch.slot_s
    return distance, energy


def completion_time_s(batch: Batch, result: BatchResult, left_bit: np.ndarray) -> np.ndarray:
    """(B,) ``metrics.completion_time_s`` [s]: NaN where the buffers were never all emptied.

    ``left_bit`` (B, N) is what the buffers held after the last slot. Buffers only shrink, by
    downloads, so a mission that ends empty emptied in its last slot with a positive download.
    """
    slots = np.arange(result.downloaded_bit.shape[1])[:, None]
    last = np.where(result.downloaded_bit.T > 0, slots, -1).max(axis=0, initial=-1)
    emptied = ~(left_bit > 0).any(axis=1) & (last >= 0)
    done = np.where(emptied, (last + 1) * batch.slot_s, np.nan)
    return np.where(batch.buffers_bit.any(axis=1), done, 0.0)


def visit_order(batch: Batch, result: BatchResult, geometry: Geometry) -> np.ndarray:
    """(B, N) ``metrics.visit_order`` (fixed runs) as sensor indices, padded with NO_SENSOR.

    A mission that hovered while serving visits sensor i at the first such slot serving i;
    otherwise at the first slot its position is within the visit radius of i's hover point.
    """
    n_run = result.n_run
    served = result.served.T
    hovered = result.hovering.T & (served != NO_SENSOR)
    first = _first_hover_slots(served, hovered, n_run, batch.buffers_bit.shape[1])
    by_place = ~hovered.any(axis=0)
    if by_place.any():
        first[by_place] = _first_slot_near(batch, result, geometry, np.flatnonzero(by_place))
    order = np.argsort(first, axis=1, kind="stable")
    reached = np.take_along_axis(first, order, axis=1) < n_run[:, None]
    return np.where(reached, order, NO_SENSOR)


def _first_hover_slots(
    served: np.ndarray, hovered: np.ndarray, n_run: np.ndarray, n_sensors: int
) -> np.ndarray:
    """(B, N) first slot each mission hovered serving each sensor (else n_run).

    ``served`` and ``hovered`` are slot-major (T, B); only the first slot of each hover run
    is looked at, and ``np.nonzero`` lists those in slot order.
    """
    start = hovered.copy()
    start[1:] &= ~(hovered[:-1] & (served[1:] == served[:-1]))
    slot, mission = np.nonzero(start)
    keys, at = np.unique(mission * n_sensors + served[slot, mission], return_index=True)
    first = np.repeat(n_run[:, None], n_sensors, axis=1)
    first.reshape(-1)[keys] = slot[at]
    return first


def _first_slot_near(
    batch: Batch, result: BatchResult, geometry: Geometry, index: np.ndarray
) -> np.ndarray:
    """(R, N) first slot missions ``index`` (R,) were within the visit radius of each
    sensor's hover point (horizontally), or n_run if never.

    The UAV walks its track from sample 0 one sample at a time, so that slot is the first one
    at the first track sample k near the hover point: the number of slots spent before k.
    """
    n_run = result.n_run[index]
    k_max = batch.position_m.shape[1]
    # near[k, i] per distinct (track, hover points, radius); k_max: never near
    key = np.column_stack(
        [
            batch.track_id[index],
            geometry.hover_points_m[index].reshape(index.size, -1),
            geometry.visit_radius_m[index],
        ]
    )
    keys, group = unique_rows(key)
    first_near = np.empty((keys.shape[0], batch.buffers_bit.shape[1]), np.int64)
    for g, row in enumerate(keys):
        u = int(row[0])
        offset = batch.position_m[u, :, None, :2] - row[1:-1].reshape(1, -1, 2)
        near = np.hypot(offset[..., 0], offset[..., 1]) <= row[-1]  # NaN -> False
        near[batch.n_samples[u] :] = False
        first_near[g] = np.where(near.any(axis=0), near.argmax(axis=0), k_max)
    # slots spent before each sample k (bin k_max collects the slots after the mission)
    bins = k_max + 1
    ran = np.arange(result.sample.shape[1])[:, None] < n_run
    flat = np.where(ran, result.sample.T[:, index], k_max) + np.arange(index.size) * bins
    counts = np.bincount(flat.ravel(), minlength=index.size * bins).reshape(-1, bins)
    before = np.cumsum(counts, axis=1) - counts
    return np.take_along_axis(before, first_near[group], axis=1)


def summarize_batch(batch: Batch, result: BatchResult, geometry: Geometry) -> BatchSummary:
    """``metrics.summarize`` of every mission of ``batch`` from its arrays, vectorised.

    Exactly (bit for bit) what ``summarize`` gives for each mission's log with ``geometry``:
    sums over slots are taken in numpy's order for a 1-D array (:func:`row_sums`).
    """
    n_run = result.n_run
    slot_s = batch.slot_s
    buffers = batch.buffers_bit
    total_buffer = buffers.sum(axis=1)
    total = row_sums(result.downloaded_bit, n_run)
    left = np.where(
        n_run[:, None] > 0,
        result.remaining_bit[np.arange(n_run.size), np.maximum(n_run - 1, 0)],
        buffers,
    )
    end_m = batch.position_m[batch.track_id, result.end_sample]
    to_home = np.hypot(end_m[:, 0] - geometry.home_m[:, 0], end_m[:, 1] - geometry.home_m[:, 1])
    has_buffer = total_buffer > 0
    safe_buffer = np.where(has_buffer, total_buffer, 1.0)
    distance, energy = flight_totals(batch, result)
    return BatchSummary(
        slots=n_run.copy(),
        slot_s=slot_s.copy(),
        mission_time_s=n_run * slot_s,
        buffers_bit=buffers.copy(),
        total_buffer_bit=total_buffer,
        total_downloaded_bit=total,
        per_sensor_downloaded_bit=buffers - left,
        completion=np.where(has_buffer, total / safe_buffer, 1.0),
        handovers=handover_counts(result.served.T),
        hover_time_s=np.count_nonzero(result.hovering.T, axis=0) * slot_s,
        distance_m=distance,
        energy_j=energy,
        visit_order=visit_order(batch, result, geometry),
        distance_to_home_m=to_home,
        aadm_score=aadm_scores(
            np.where(has_buffer, 100.0 * total / safe_buffer, 100.0),
            completion_time_s(batch, result, left),
            to_home,
        ),
    )


def aadm_scores(percent: np.ndarray, done_s: np.ndarray, to_home_m: np.ndarray) -> np.ndarray:
    """(B,) ``metrics.aadm_score`` from percent downloaded, completion time [s] (NaN: never)
    and end-to-home distance [m] (NaN: no home), in the same order of operations."""
    bonus = np.where(np.isnan(done_s), 0.0, np.maximum(0.0, AADM_REFERENCE_S - done_s))
    score = np.where(np.isnan(done_s), percent, percent + bonus)
    over = AADM_PENALTY_PER_M * np.maximum(0.0, to_home_m - AADM_LANDING_TOLERANCE_M)
    return np.where(np.isfinite(to_home_m), score - over, score)


def summary_dicts(
    summary: BatchSummary,
    sensor_names: Sequence[tuple[str, ...]],
    policies: Sequence[str],
    scenario_names: Sequence[str],
) -> list[dict[str, Any]]:
    """One ``metrics.summarize`` dictionary per mission (same keys, order, values, types)."""
    mission_time = summary.mission_time_s.tolist()
    slots = summary.slots.tolist()
    slot_s = summary.slot_s.tolist()
    total = (summary.total_downloaded_bit / BITS_PER_MBIT).tolist()
    total_buffer = (summary.total_buffer_bit / BITS_PER_MBIT).tolist()
    per_sensor = (summary.per_sensor_downloaded_bit / BITS_PER_MBIT).tolist()
    buffers = (summary.buffers_bit / BITS_PER_MBIT).tolist()
    completion = summary.completion.tolist()
    handovers = summary.handovers.tolist()
    hover = summary.hover_time_s.tolist()
    distance = summary.distance_m.tolist()
    energy = (summary.energy_j / 1e3).tolist()
    order = summary.visit_order.tolist()
    landed = (summary.distance_to_home_m <= AADM_LANDING_TOLERANCE_M).tolist()
    to_home = summary.distance_to_home_m.tolist()
    score = summary.aadm_score.tolist()
    rows = []
    for b, names in enumerate(sensor_names):
        rows.append(
            {
                "scenario": scenario_names[b],
                "policy": policies[b],
                "mission_time_s": mission_time[b],
                "slots": slots[b],
                "slot_s": slot_s[b],
                "total_downloaded_mbit": total[b],
                "total_buffer_mbit": total_buffer[b],
                "per_sensor_downloaded_mbit": dict(zip(names, per_sensor[b], strict=True)),
                "per_sensor_buffer_mbit": dict(zip(names, buffers[b], strict=True)),
                "completion": completion[b],
                "handovers": handovers[b],
                "hover_time_s": hover[b],
                "distance_m": distance[b],
                "energy_kj": energy[b],
                "visit_order": [names[i] for i in order[b] if i != NO_SENSOR],
                "landed_at_home": landed[b],
                "distance_to_home_m": to_home[b],
                "aadm_score": score[b],
            }
        )
    return rows


def summarize_fixed_batch(
    missions: Sequence[Mission],
    specs: Sequence[PolicySpec],
    scenario_names: Sequence[str],
    geometry: Sequence[Mapping[str, Any] | None] | None = None,
    batch_size: int = 1000,
) -> list[dict[str, Any]]:
    """``metrics.summarize`` dictionaries of fixed-trajectory missions, in input order.

    Equal to ``[summarize(replace(run_fixed(m, make_policy(s)), **g), name) ...]`` with
    ``g`` the mission's ``geometry`` entry (``fixed_geometry_fields``; None: none), but no
    :class:`~skymule.sim.engine.MissionLog` is built: the summaries come from the batch arrays.
    """
    fields = list(geometry) if geometry is not None else [None] * len(missions)
    summaries: list[dict[str, Any] | None] = [None] * len(missions)
    for part in _batches(missions, batch_size):
        batch = stack_missions([missions[i] for i in part], [specs[i] for i in part])
        result = run_batch(batch)
        arrays = summarize_batch(
            batch, result, geometry_arrays([fields[i] for i in part], batch.buffers_bit.shape[1])
        )
        rows = summary_dicts(
            arrays,
            [missions[i].sensor_names for i in part],
            [specs[i].name for i in part],
            [scenario_names[i] for i in part],
        )
        for i, row in zip(part, rows, strict=True):
            summaries[i] = row
    return [row for row in summaries if row is not None]
