"""The batched engine: many fixed-trajectory missions at once, vectorised over missions x sensors.

:func:`run_batch` loops over slots only; every step is a numpy operation over the B missions
of the batch. It obeys the slot contract exactly as the reference engine
(:func:`skymule.engine.run_fixed`) and the reference policies do, including their tie rules
and HGAD's state machine (cooldown, hover budget, trigger), and the test suite compares the two
value for value.

Missions that share a :class:`~skymule.flight.paths.Track` object (and rate table) share its
samples: tracks are stored once, (U, K_max, N), and every mission points at one of them.

Policies covered: :data:`BATCH_POLICIES` (``greedy`` and ``hgad``); other policies and
autonomous missions run through the reference engine (see :mod:`skymule.experiments.run`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from skymule.engine import NO_SENSOR, MissionLog
from skymule.errors import SkymuleError
from skymule.scenario import PolicySpec
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
    return (
        mission.track is not None
        and spec.name in BATCH_POLICIES
        and getattr(mission, "fading_db", None) is None
    )


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
    track_id = np.empty(len(missions), np.int64)
    for b, mission in enumerate(missions):
        if mission.track is None:
            raise SkymuleError("the batched engine needs fixed trajectories (trajectory.mode)")
        key = (id(mission.track), id(mission.rate_table), mission.bandwidth_hz)
        if key not in keys:
            keys[key] = len(unique)
            unique.append(mission)
        track_id[b] = keys[key]
    # one padding row past the longest track: where a used-up trace points
    k_max = max(m.track.n_samples for m in unique) + 1  # type: ignore[union-attr]
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
    return Batch(
        track_id=track_id,
        rate_bps=rate,
        snr_db=snr,
        snr_seen_db=snr_seen,
        position_m=position,
        peak_rate_bps=peak,
        n_samples=np.array([m.track.n_samples for m in unique], np.int64),  # type: ignore[union-attr]
        hold_at_end=np.array([m.track.hold_at_end for m in unique], bool),  # type: ignore[union-attr]
        n_slots=np.array([m.n_slots for m in missions], np.int64),
        slot_s=np.array([m.slot_s for m in missions], float),
        buffers_bit=np.array([m.buffers_bit for m in missions], float).reshape(-1, n),
        hgad=np.array([p.hgad for p in params], bool),
        threshold_bps=np.stack([t * peak[u] for t, u in zip(thresholds, track_id, strict=True)]),
        max_hover_s=np.array([p.max_hover_s for p in params], float),
    )


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
    return MissionLog(
        policy=policy,
        sensor_names=mission.sensor_names,
        slot_s=mission.slot_s,
        buffers_bit=mission.buffers_bit.copy(),
        position_m=batch.position_m[u][index],
        end_position_m=batch.position_m[u, result.end_sample[b]].copy(),
        snr_db=batch.snr_db[u][index],
        rate_bps=batch.rate_bps[u][index],
        served=result.served[b, :n].copy(),
        downloaded_bit=result.downloaded_bit[b, :n].copy(),
        remaining_bit=result.remaining_bit[b, :n].copy(),
        hovering=result.hovering[b, :n].copy(),
    )


def run_fixed_batch(
    missions: Sequence[Mission], specs: Sequence[PolicySpec], batch_size: int = 1000
) -> list[MissionLog]:
    """Logs of fixed-trajectory missions (one policy spec each), in input order.

    Equal to ``[engine.run_fixed(m, make_policy(s)) for m, s in zip(missions, specs)]``.
    Missions are grouped by sensor count and run ``batch_size`` at a time (memory grows as
    batch_size x T_max x N).
    """
    logs: list[MissionLog | None] = [None] * len(missions)
    groups: dict[int, list[int]] = {}
    for index, mission in enumerate(missions):
        groups.setdefault(mission.n_sensors, []).append(index)
    for indices in groups.values():
        for start in range(0, len(indices), batch_size):
            part = indices[start : start + batch_size]
            batch = stack_missions([missions[i] for i in part], [specs[i] for i in part])
            result = run_batch(batch)
            for b, i in enumerate(part):
                logs[i] = mission_log(batch, result, b, missions[i], specs[i].name)
    return [log for log in logs if log is not None]
