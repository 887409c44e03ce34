"""The fixed-trajectory engine: B flights on planned paths or recorded traces, slot by slot.

Every flight is a column: one mission, or one UAV of a fleet mission (its UAVs share one
set of buffers, ``docs/fleet.md``). Each slot t (``docs/contract.md``):

1. every UAV is at its track sample and observes SNR, rate and buffers there (per-slot
   fading added; under faults the policy sees the faulty SNR and position, ``docs/faults.md``);
2. the policy decides for all columns at once (:class:`~skymule.policies.base.BatchAction`);
3. the download window closes what starts after it; UAVs of a fleet that chose the same
   sensor are settled by :func:`contract.fleet_served`; a fault blocks delivery;
4. the served sensors deliver y = min(R dt, Q) at the true rate (:func:`contract.served_bits`);
5. a UAV that does not hover advances one track sample (a wind may hold it short of the next
   one), holding at the end of a planned path; a recorded trace ends the flight when used up.

:class:`FixedEngine` is the state machine (``observe`` / ``step``); :func:`run_fixed` drives
it with a batched policy. A policy with a compiled twin (:attr:`slot_rule`, Greedy and HGAD)
runs in the compiled loop of :mod:`skymule.sim.compiled` when numba is installed and the
batch allows it: the same rules, value for value.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from operator import attrgetter
from typing import Any

import numpy as np

from skymule.errors import SkymuleError
from skymule.flight.paths import Track
from skymule.metrics.flights import Flights
from skymule.policies.base import BatchAction, BatchObservation, BatchPolicy, MissionContext
from skymule.radio.rates import rate_bps
from skymule.rules import contract
from skymule.rules.contract import NO_SENSOR
from skymule.sim import compiled
from skymule.sim.batch_fading import apply_fading, stack_fading
from skymule.sim.batch_faults import BatchFaults, add_gps_error, apply_faults, stack_faults
from skymule.sim.columns import (
    affected_slots,
    check_actions,
    check_flags,
    fleet_columns,
    flights_record,
    frozen,
    window_slots,
)
from skymule.world import Mission


@dataclass(frozen=True)
class TrackTables:
    """B flights' tracks stacked (U distinct tracks and rate tables, K_max samples, N sensors).

    Attributes:
        track_id: (B,) each flight's track.
        rate_bps: (U, K_max + 1, N) rate at each track sample [bit/s] (0 in padding; a used-up
            trace points one sample past its end, into the padding).
        snr_db: (U, K_max + 1, N) track SNR [dB] (NaN: no sample, and padding).
        snr_seen_db: (U, K_max + 1, N) SNR as policies see it (NaN -> -inf) [dB].
        position_m: (U, K_max + 1, 3) sample positions [m] (0 in padding).
        peak_rate_bps: (U, N) largest rate per sensor over each track [bit/s].
        n_samples: (U,) track lengths K.
        hold_at_end: (U,) True: hold at the last sample; False: a trace that runs out.
    """

    track_id: np.ndarray
    rate_bps: np.ndarray
    snr_db: np.ndarray
    snr_seen_db: np.ndarray
    position_m: np.ndarray
    peak_rate_bps: np.ndarray
    n_samples: np.ndarray
    hold_at_end: np.ndarray


def stack_tracks(missions: Sequence[Mission]) -> TrackTables:
    """Each distinct (track, rate table, bandwidth) of ``missions`` once, every flight pointing
    at one (missions of a sweep share one built track)."""
    n = missions[0].n_sensors
    found = list(map(attrgetter("track"), missions))
    if None in found:
        raise SkymuleError("the fixed-trajectory engine needs trajectory.mode = 'fixed'")
    # (track, rate table, bandwidth) of each flight as an array row, grouped by numpy: no
    # Python per flight (a sweep's batch is thousands of flights over a few tracks)
    size = len(missions)
    keys = np.empty((size, 3), np.int64)
    keys[:, 0] = np.fromiter(map(id, found), np.int64, size)
    keys[:, 1] = np.fromiter(map(id, map(attrgetter("rate_table"), missions)), np.int64, size)
    keys[:, 2] = np.fromiter(map(attrgetter("bandwidth_hz"), missions), float, size).view(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # tracks in order of first appearance, as flights name them
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    track_id = rank[inverse.reshape(-1)]
    unique: list[Mission] = [missions[i] for i in first[order].tolist()]
    tracks: list[Track] = [m.track for m in unique if m.track is not None]
    k_max = max(t.n_samples for t in tracks) + 1
    rate = np.zeros((len(unique), k_max, n))
    snr = np.full((len(unique), k_max, n), np.nan)
    position = np.zeros((len(unique), k_max, 3))
    peak = np.zeros((len(unique), n))
    for u, (mission, track) in enumerate(zip(unique, tracks, strict=True)):
        k = track.n_samples
        rate[u, :k] = mission.rate_bps(track.snr_db)
        snr[u, :k] = track.snr_db
        position[u, :k] = track.position_m
        peak[u] = rate[u, :k].max(axis=0) if k else 0.0
    for values in (rate, snr, position, peak):
        values.flags.writeable = False
    seen = contract.seen_snr_db(snr)
    seen.flags.writeable = False
    return TrackTables(
        track_id=track_id,
        rate_bps=rate,
        snr_db=snr,
        snr_seen_db=seen,
        position_m=position,
        peak_rate_bps=peak,
        n_samples=np.array([t.n_samples for t in tracks], np.int64),
        hold_at_end=np.array([t.hold_at_end for t in tracks], bool),
    )


class FixedEngine:
    """B fixed-trajectory flights in progress (module docstring for the rules).

    Call :meth:`observe`, then :meth:`step` with the policy's action, until :attr:`done`;
    then :meth:`record`. Missions are only read.

    Args:
        missions: one Mission per column, all with the same sensors (count).
        fleet: (B,) the fleet mission of each column (contiguous, K UAVs each): its UAVs share
            buffers (those of the first column's Mission); None: one UAV per mission.
        detail: keep the per-slot buffers (and SNR/rates in the record) for run folders.
    """

    def __init__(
        self,
        missions: Sequence[Mission],
        fleet: np.ndarray | None = None,
        detail: bool = True,
    ) -> None:
        if not missions:
            raise ValueError("the engine needs at least one mission")
        if len({m.n_sensors for m in missions}) != 1:
            raise ValueError("one batch needs one sensor count")
        self.missions = tuple(missions)
        self.detail = detail
        self.tables = stack_tracks(missions)
        n_flights, n_sensors = len(missions), missions[0].n_sensors
        self.n_sensors = n_sensors
        self.group, self.uavs = fleet_columns(fleet, n_flights)
        self.n_slots = np.array([m.n_slots for m in missions], np.int64)
        self.slot_s = np.array([m.slot_s for m in missions], float)
        self.window = window_slots(missions)
        self._first_close = int(self.window.min())
        self._t_max = int(self.n_slots.max())
        tables = self.tables
        # one (2N, U*(K+1)) table [rate ; snr seen]: one column gather per slot
        k_rows = tables.rate_bps.shape[1]
        self._table = np.ascontiguousarray(
            np.concatenate([tables.rate_bps, tables.snr_seen_db], axis=2)
            .reshape(-1, 2 * n_sensors)
            .T
        )
        self._positions = tables.position_m.reshape(-1, 3)
        self._base_row = tables.track_id * k_rows
        self._track_samples = tables.n_samples[tables.track_id]
        holds = tables.hold_at_end[tables.track_id]
        # a planned path holds at its last sample; a trace may step one past it (the end)
        self._limit = np.where(holds, self._track_samples - 1, self._track_samples)
        # with every track a held path, no flight can end before its last slot
        self._every_active = int(self.n_slots.min()) if holds.all() else 0
        self.fading_index, self.fading_db, self.rate_model, self.rate_models = stack_fading(
            missions, n_sensors
        )
        self.faults: BatchFaults = stack_faults(missions, n_sensors)
        self._gps_rows = [b for b, m in enumerate(missions) if m.faults is not None]
        self._wind_rows = [
            b for b, m in enumerate(missions) if m.faults is not None and m.faults.wind is not None
        ]
        lead = self.group[:: self.uavs]
        self._buffers = np.array([missions[c].buffers_bit for c in lead], float).reshape(
            -1, n_sensors
        )
        # state
        self.slot = 0
        self.sample = np.zeros(n_flights, np.int64)
        self._progress = np.zeros(n_flights)  # wind: share of the next sample reached
        self.remaining = np.ascontiguousarray(self._buffers.T)  # (N, G) shared per fleet
        self.n_run = np.zeros(n_flights, np.int64)
        # mission-major logs (B, T): a slot writes one column, and the record needs no transpose
        t_max, shape = self._t_max, (n_flights, self._t_max)
        self._served = np.full(shape, NO_SENSOR, np.int64)
        self._downloaded = np.zeros(shape)
        self._hovering = np.zeros(shape, bool)
        self._sample_log = np.zeros(shape, np.int64)
        needs_chosen = self.faults.any or self.uavs > 1
        self._chosen = np.full(shape, NO_SENSOR, np.int64) if needs_chosen else None
        self._lost = np.zeros(shape, bool) if self.uavs > 1 else None
        self._remaining_log = np.zeros((n_flights, t_max, n_sensors)) if detail else None
        self._all = np.ones(n_flights, bool)
        self._all.flags.writeable = False
        self._columns = np.arange(n_flights)
        self._active = self._active_now()
        self._deliver: np.ndarray = np.zeros((n_sensors, n_flights))
        self._ok: np.ndarray | None = None
        self._observed = False

    # --- what policies know ----------------------------------------------------------------

    def contexts(self) -> Sequence[MissionContext]:
        """Each column's :class:`MissionContext` (made when read; the track's rates shared
        between columns on one track)."""
        from skymule.sim.context import Contexts, fixed_context

        tables = self.tables

        def make(b: int) -> MissionContext:
            u = int(tables.track_id[b])
            k = int(tables.n_samples[u])
            return fixed_context(self.missions[b], tables.rate_bps[u, :k], tables.peak_rate_bps[u])

        columns = {
            "slot_s": self.slot_s,
            "n_slots": self.n_slots,
            "peak_rate_bps": tables.peak_rate_bps[tables.track_id],
            "buffers_bit": np.array([m.buffers_bit for m in self.missions], float),
        }
        return Contexts(len(self.missions), make, columns)

    @property
    def done(self) -> bool:
        """True once every flight is over."""
        return self.slot >= self._t_max or not self._active.any()

    @property
    def active(self) -> np.ndarray:
        """(B,) True where the flight is still running (at the current slot)."""
        return self._active.copy()

    def _active_now(self) -> np.ndarray:
        if self.slot < self._every_active:
            return self._all
        return (self.slot < self.n_slots) & (self.sample < self._track_samples)

    def observe(self) -> BatchObservation:
        """What every UAV sees at the start of the current slot."""
        slot, n = self.slot, self.n_sensors
        observed = self._table.take(self._base_row + self.sample, axis=1)
        rate, snr = observed[:n], observed[n:]
        if self.fading_index.size:
            apply_fading(
                self.fading_index, self.fading_db[slot], self.rate_model, self.rate_models,
                rate, snr,
            )  # fmt: skip
        deliver = rate
        position = self._positions.take(self._base_row + self.sample, axis=0)
        if self.faults.any:  # the policy sees the faulty SNR; `deliver` is what serving yields
            rate, snr, deliver, self._ok = apply_faults(self.faults, slot, rate, snr)
            add_gps_error(self.missions, self._gps_rows, np.full(len(position), slot), position)
        self._deliver = deliver
        remaining = self.remaining if self.uavs == 1 else self.remaining[:, self.group]
        self._observed = True
        return BatchObservation(
            slot=frozen(np.full(len(self.missions), slot, np.int64)),
            active=self._active.view() if self._active is self._all else frozen(self._active),
            position_m=frozen(position),
            snr_db=frozen(snr).T,
            rate_bps=frozen(rate).T,
            remaining_bit=frozen(remaining.copy()).T,
        )

    # --- what happens ----------------------------------------------------------------------

    def step(self, action: BatchAction, who: str = "policy") -> np.ndarray:
        """Apply ``action`` to the slot last observed; (B,) bits each flight downloaded."""
        if not self._observed:
            raise SkymuleError("step() before observe(): the engine has no slot to apply")
        self._observed = False
        slot, active = self.slot, self._active
        n_flights = len(self.missions)
        sensor = check_actions(action, n_flights, self.n_sensors, who)
        hover = check_flags(action.hover, n_flights, "hover", who)
        if active is not self._all:
            hover = hover & active
            sensor = np.where(active, sensor, NO_SENSOR)
        if slot >= self._first_close:  # the download window has closed for some
            sensor = np.where(slot < self.window, sensor, NO_SENSOR)
        chosen = sensor
        sensor, bits, lost = contract.serve_slot(
            sensor, self._deliver, self._ok, self.remaining, self.group, self.uavs, self.slot_s
        )
        if self._lost is not None and lost is not None:
            self._lost[:, slot] = lost
        self._served[:, slot] = sensor
        self._downloaded[:, slot] = bits
        self._hovering[:, slot] = hover
        self._sample_log[:, slot] = self.sample
        if self._chosen is not None:
            self._chosen[:, slot] = chosen
        if self._remaining_log is not None:
            self._remaining_log[:, slot] = (
                self.remaining if self.uavs == 1 else self.remaining[:, self.group]
            ).T
        self.n_run += active
        moving = ~hover if active is self._all else active & ~hover
        for b in self._wind_rows:
            if moving[b]:
                moving[b] = self._wind_reaches_next_sample(b)
        self.sample += moving
        np.minimum(self.sample, self._limit, out=self.sample)
        self.slot += 1
        self._active = self._active_now()
        return bits

    def _wind_reaches_next_sample(self, b: int) -> bool:
        """False while a wind keeps flight b short of its next track sample.

        Progress advances by achieved/commanded of a sample per slot (``docs/faults.md``);
        the UAV holds the current sample until a whole sample is reached.
        """
        mission = self.missions[b]
        assert mission.faults is not None and mission.faults.wind is not None
        track = mission.track
        assert track is not None
        here, nxt = int(self.sample[b]), int(self.sample[b]) + 1
        if nxt >= track.n_samples:
            return True
        commanded = track.position_m[nxt, :2] - track.position_m[here, :2]
        length = float(np.hypot(*commanded))
        if length == 0.0:
            return True
        slot_s = mission.slot_s
        airspeed = max(mission.max_speed_mps, length / slot_s)
        achieved = mission.faults.wind.achieved_step_m(commanded, slot_s, airspeed)
        self._progress[b] += float(np.hypot(*achieved)) / length
        if self._progress[b] < 1.0 - 1e-9:
            return False
        self._progress[b] = max(self._progress[b] - 1.0, 0.0)
        return True

    # --- what happened ---------------------------------------------------------------------

    def record(self, policies: Sequence[str]) -> Flights:
        """The run record of the slots run so far (``policies``: each column's name)."""
        tables = self.tables
        width = int(self.n_run.max()) if self.n_run.size else 0
        sample = np.ascontiguousarray(self._sample_log[:, :width])
        snr = rate = remaining = None
        if self.detail:
            assert self._remaining_log is not None
            remaining = self._remaining_log[:, :width]
            snr, rate = self._detail_signal(sample, width)
        faulty = [m.faults for m in self.missions]
        track_position = tables.position_m
        track_samples, track_id = tables.n_samples, tables.track_id
        end_sample = np.minimum(self.sample, self._track_samples - 1)
        if self._wind_rows:
            track_position, track_samples, track_id, sample, end_sample = self._own_tracks(
                sample, end_sample, width
            )
        return flights_record(
            self.missions,
            policies,
            n_run=self.n_run.copy(),
            left_bit=np.ascontiguousarray(
                (self.remaining if self.uavs == 1 else self.remaining[:, self.group]).T
            ),
            served=np.ascontiguousarray(self._served[:, :width]),
            downloaded_bit=np.ascontiguousarray(self._downloaded[:, :width]),
            hovering=np.ascontiguousarray(self._hovering[:, :width]),
            track_position_m=track_position,
            track_samples=track_samples,
            track_id=track_id,
            sample=sample,
            end_sample=end_sample,
            snr_db=snr,
            rate_bps=rate,
            remaining_bit=remaining,
            chosen=None if self._chosen is None else np.ascontiguousarray(self._chosen[:, :width]),
            affected=affected_slots(faulty, width),
            fleet=None if self.uavs == 1 else self.group.copy(),
            lost=None if self._lost is None else np.ascontiguousarray(self._lost[:, :width]),
        )

    def _own_tracks(
        self, sample: np.ndarray, end_sample: np.ndarray, width: int
    ) -> tuple[np.ndarray, ...]:
        """Track arrays where each flight under a wind flies a track of its own (its position
        in each slot, then its end): a wind may hold it at a sample without hovering, which
        one step per moving slot along the shared track would not show."""
        tables = self.tables
        rows = np.asarray(self._wind_rows, np.int64)
        k = max(tables.position_m.shape[1], width + 1)
        shared = tables.position_m.shape[0]
        position = np.zeros((shared + rows.size, k, 3))
        position[:shared, : tables.position_m.shape[1]] = tables.position_m
        track_id = tables.track_id.copy()
        samples = np.concatenate([tables.n_samples, self.n_run[rows] + 1])
        sample = sample.copy()
        end_sample = end_sample.copy()
        for w, b in enumerate(rows.tolist()):
            n, u = int(self.n_run[b]), int(tables.track_id[b])
            position[shared + w, :n] = tables.position_m[u, sample[b, :n]]
            position[shared + w, n] = tables.position_m[u, end_sample[b]]
            track_id[b] = shared + w
            sample[b] = np.minimum(np.arange(sample.shape[1]), n)
            end_sample[b] = n
        return position, samples, track_id, sample, end_sample

    def _detail_signal(self, sample: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
        """(B, T, N) SNR and rates observed in each slot run (true values, fading added)."""
        tables = self.tables
        track = tables.track_id[:, None]
        snr = tables.snr_db[track, sample]
        rate = tables.rate_bps[track, sample]
        for f, b in enumerate(self.fading_index.tolist()):
            mission = self.missions[b]
            faded = snr[b] + self.fading_db[:width, :, f]
            snr[b] = faded
            rate[b] = mission.rate_bps(faded)
        return snr, rate


def run_fixed(
    missions: Sequence[Mission],
    policy: BatchPolicy,
    *,
    fleet: np.ndarray | None = None,
    detail: bool = True,
    engine_choice: str = "auto",
) -> Flights:
    """Run B fixed-trajectory flights under one batched policy; their record.

    ``engine_choice``: ``"numpy"`` (the slot loop calling ``policy.act``), ``"compiled"``
    (the policy's compiled twin, :func:`compiled_reason` says when it cannot) or ``"auto"``
    (compiled where it can run, else numpy). Both give the same record, value for value.
    """
    from skymule.policies.batched import policy_names

    engine = FixedEngine(missions, fleet, detail)
    policy.reset(engine.contexts())
    names = policy_names(policy, len(missions))
    compiled.check_engine(engine_choice)
    if engine_choice != "numpy":
        rule = getattr(policy, "slot_rule", lambda: None)()
        why = compiled_reason(engine, rule)
        if why is None:
            return run_compiled(engine, rule, names)
        if engine_choice == "compiled":
            raise SkymuleError(f"engine = 'compiled' cannot run this batch: {why}")
    while not engine.done:
        engine.step(policy.act(engine.observe()), policy.name)
    return engine.record(names)


__all__ = ["FixedEngine", "rate_bps", "run_fixed"]


# --- the compiled fast path ----------------------------------------------------------------


def compiled_reason(engine: FixedEngine, rule: Any) -> str | None:
    """Why the compiled loop cannot run ``engine``'s flights under ``rule`` (None: it can)."""
    from skymule.sim.batch_faults import kernel_faults

    if rule is None:
        return "the policy has no compiled twin (only greedy and hgad do)"
    if not compiled.available():
        return "numba is not installed"
    if engine.fading_index.size:
        return "missions with per-slot fading"
    if engine.uavs > 1:
        return "several UAVs share buffers"
    if engine._wind_rows:
        return "a wind fault"
    if engine.faults.any and kernel_faults(engine.faults, len(engine.missions)) is None:
        return "an SNR error on a rate table other than a step table"
    return None


def compiled_inputs(engine: FixedEngine, rule: Any) -> tuple[Any, ...]:
    """The arguments of :func:`skymule.sim.compiled.slot_loop` that describe the flights and
    the policy's rule (before the flags and outputs)."""
    tables = engine.tables
    samples = engine._track_samples
    return (
        tables.rate_bps, tables.snr_seen_db, tables.track_id, samples, engine._limit,
        samples - 1, engine.n_slots, engine.window, engine.slot_s,
        np.ascontiguousarray(engine._buffers, float), np.ascontiguousarray(rule.hgad, bool),
        np.ascontiguousarray(rule.threshold_bps, float),
        np.ascontiguousarray(rule.peak_rate_bps, float),
        np.ascontiguousarray(rule.max_hover_s, float),
    )  # fmt: skip


def compiled_faults(engine: FixedEngine) -> Any:
    """The flights' fault draws as the compiled loop reads them (None: no faults)."""
    from skymule.sim.batch_faults import kernel_faults

    return kernel_faults(engine.faults, len(engine.missions)) if engine.faults.any else None


def run_compiled(
    engine: FixedEngine, rule: Any, policies: Sequence[str], loop: Any = None
) -> Flights:
    """Every slot of a fresh ``engine`` in the compiled loop (``compiled_reason`` None): the
    rule of ``rule`` compiled, writing the engine's own logs, so :meth:`FixedEngine.record`
    gives the same record as the numpy slot loop. ``loop``: the loop to run (default
    :func:`~skymule.sim.compiled.compiled_loop`; the tests also run
    :func:`~skymule.sim.compiled.slot_loop` as plain Python, with or without numba)."""
    n_flights, n_sensors = len(engine.missions), engine.n_sensors
    remaining = engine._remaining_log if engine.detail else np.zeros((0, 0, 0))
    end_sample = np.zeros(n_flights, np.int64)
    left = np.zeros((n_flights, n_sensors))
    faults = compiled_faults(engine)
    (compiled.compiled_loop() if loop is None else loop)(
        *compiled_inputs(engine, rule), True, engine.detail, engine._served, engine._downloaded,
        engine._hovering, engine._sample_log, remaining, engine.n_run, end_sample, left, False,
        *compiled.no_totals(n_sensors), faults, engine._chosen,
    )  # fmt: skip
    engine.sample[:] = end_sample
    engine.remaining[:] = left.T
    return engine.record(policies)
