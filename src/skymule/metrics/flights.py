"""The run record: what happened in B flights (:class:`Flights`), and one flight of it
(:class:`MissionLog`, a read-only view). The engines write it; metrics, run folders and
figures read it.

Positions are given as tracks plus sample indices: mission b is at
``track_position_m[track_id[b], sample[b, t]]`` during slot t and ends at sample
``end_sample[b]``; a non-hovering slot moves to the next sample (or holds at a track's last
one). A log is its own track: its positions followed by its end position, sample t in slot t.
This is what lets the batched engine share one track among many missions.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from skymule.rules.contract import NO_SENSOR
from skymule.rules.defaults import AADM_WINDOW_S


@dataclass(frozen=True, eq=False)
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
        policy: (B,) policy name of each flight (empty when unknown).
        sensor_names: (B,) each flight's (N,) sensor names.
        snr_db: (B, T, N) SNR observed at the start of each slot [dB] (NaN: no sample), or
            None when the run kept no per-slot detail.
        rate_bps: (B, T, N) rate to each sensor [bit/s], or None (no detail).
        remaining_bit: (B, T, N) buffers after each slot's download [bit], or None.
        chosen: (B, T) the sensor the policy chose (``served`` is NO_SENSOR where a fault or
            another UAV kept it from delivering), or None for fault-free single-UAV runs
            (then equal to ``served``).
        affected: (B, T) True where a per-slot fault touched the slot, or None (no faults).
        battery_used_j: (B, T) propulsion energy the battery has paid after each slot [J],
            or None without a battery fault.
        fleet: (B,) the fleet mission each flight belongs to (its UAVs share buffers), or
            None: every flight is a mission of its own.
        lost: (B, T) True where a UAV chose a sensor another UAV won, or None (no fleet).
        faulty: (B,) True where the flight had per-slot fault draws (``[[faults]]``), or None
            when none had.

    A record is immutable: its arrays are read-only.
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
    policy: tuple[str, ...] = ()
    sensor_names: tuple[tuple[str, ...], ...] = ()
    snr_db: np.ndarray | None = None
    rate_bps: np.ndarray | None = None
    remaining_bit: np.ndarray | None = None
    chosen: np.ndarray | None = None
    affected: np.ndarray | None = None
    battery_used_j: np.ndarray | None = None
    fleet: np.ndarray | None = None
    lost: np.ndarray | None = None
    faulty: np.ndarray | None = None

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    def select(self, rows: np.ndarray | list[int]) -> Flights:
        """The record of flights ``rows`` only (tracks shared, per-flight arrays indexed)."""
        rows = np.asarray(rows, np.int64)
        changes: dict[str, object] = {}
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name in ("track_position_m", "track_samples"):
                continue
            if item.name in ("policy", "sensor_names"):
                changes[item.name] = tuple(value[r] for r in rows.tolist()) if value else ()
            elif isinstance(value, np.ndarray):
                changes[item.name] = value[rows]
        return replace(self, **changes)  # type: ignore[arg-type]

    @property
    def size(self) -> int:
        """B, the number of flights."""
        return int(self.n_run.shape[0])

    def score_windows_s(self) -> np.ndarray:
        """(B,) the download window the AADM score counts in [s] (the default where unset)."""
        if self.aadm_window_s is None:
            return np.full(self.size, AADM_WINDOW_S)
        return np.asarray(self.aadm_window_s, float)

    def mission(self, b: int) -> MissionLog:
        """Flight b as a :class:`MissionLog` (views, no copies)."""
        return MissionLog(self, b)

    def missions(self) -> tuple[MissionLog, ...]:
        """Every flight as a :class:`MissionLog`."""
        return tuple(MissionLog(self, b) for b in range(self.size))

    def position_m(self, b: int) -> np.ndarray:
        """(T', 3) flight b's position at the start of each slot it ran [m]."""
        return self.track_position_m[self.track_id[b], self.sample[b, : self.n_run[b]]]

    def end_position_m(self, b: int) -> np.ndarray:
        """(3,) flight b's position after its last slot [m]."""
        return self.track_position_m[self.track_id[b], self.end_sample[b]]


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


@dataclass(frozen=True, eq=False)
class MissionLog:
    """Flight ``index`` of ``flights`` (T' slots run; a trace may end a mission early).

    Attributes (all read-only, in SI units):
        policy: policy name.
        sensor_names: (N,) names.
        slot_s: slot length [s].
        buffers_bit: (N,) initial buffers [bit].
        position_m: (T', 3) UAV position at the start of each slot [m].
        end_position_m: (3,) UAV position after the last slot [m].
        snr_db: (T', N) SNR observed at the start of each slot [dB] (NaN: no sample).
        rate_bps: (T', N) rate to each sensor [bit/s].
        served: (T',) served sensor index, or NO_SENSOR.
        downloaded_bit: (T',) bits downloaded in each slot.
        remaining_bit: (T', N) buffers after each slot's download [bit].
        hovering: (T',) True where the UAV held its position after the slot by choice.
        home_m: (2,) home point [m], or None.
        hover_points_m: (N, 2) point each sensor is served from [m] (NaN: unknown), or None.
        visit_radius_m: a sensor counts as visited within this distance of its hover point [m].
        target: autonomous: (T',) sensor the policy was heading for, or NO_SENSOR; else None.
        aadm_window_s: the AADM download window the score counts downloads in [s].
        affected: (T',) True where a per-slot fault touched the slot, or None (no faults).
        chosen: (T',) the sensor the policy chose (``served`` is NO_SENSOR where a fault or
            another UAV kept it from delivering), or None for a fault-free single UAV.
        battery_used_j: (T',) propulsion energy the battery has paid after each slot [J], or
            None without a battery fault.
    """

    flights: Flights
    index: int = 0

    @property
    def n_slots(self) -> int:
        """T': how many slots the flight ran."""
        return int(self.flights.n_run[self.index])

    def _slots(self, values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else values[self.index, : self.n_slots]

    def _detail(self, values: np.ndarray | None, name: str) -> np.ndarray:
        if values is None:
            raise ValueError(f"{name}: the run kept no per-slot detail (detail=False)")
        return values[self.index, : self.n_slots]

    @property
    def policy(self) -> str:
        return self.flights.policy[self.index] if self.flights.policy else ""

    @property
    def sensor_names(self) -> tuple[str, ...]:
        return self.flights.sensor_names[self.index]

    @property
    def slot_s(self) -> float:
        return float(self.flights.slot_s[self.index])

    @property
    def buffers_bit(self) -> np.ndarray:
        return self.flights.buffers_bit[self.index]

    @property
    def left_bit(self) -> np.ndarray:
        """(N,) buffers after the last slot [bit]."""
        return self.flights.left_bit[self.index]

    @property
    def position_m(self) -> np.ndarray:
        return self.flights.position_m(self.index)

    @property
    def end_position_m(self) -> np.ndarray:
        return self.flights.end_position_m(self.index)

    @property
    def snr_db(self) -> np.ndarray:
        return self._detail(self.flights.snr_db, "snr_db")

    @property
    def rate_bps(self) -> np.ndarray:
        return self._detail(self.flights.rate_bps, "rate_bps")

    @property
    def remaining_bit(self) -> np.ndarray:
        return self._detail(self.flights.remaining_bit, "remaining_bit")

    @property
    def served(self) -> np.ndarray:
        return self.flights.served[self.index, : self.n_slots]

    @property
    def downloaded_bit(self) -> np.ndarray:
        return self.flights.downloaded_bit[self.index, : self.n_slots]

    @property
    def hovering(self) -> np.ndarray:
        return self.flights.hovering[self.index, : self.n_slots]

    @property
    def home_m(self) -> np.ndarray | None:
        home = self.flights.home_m[self.index]
        return None if np.isnan(home).all() else home

    @property
    def hover_points_m(self) -> np.ndarray | None:
        hover = self.flights.hover_points_m[self.index]
        return None if np.isnan(hover).all() else hover

    @property
    def visit_radius_m(self) -> float:
        return float(self.flights.visit_radius_m[self.index])

    @property
    def aadm_window_s(self) -> float:
        return float(self.flights.score_windows_s()[self.index])

    @property
    def target(self) -> np.ndarray | None:
        return self._slots(self.flights.target)

    @property
    def faulty(self) -> bool:
        """True where the flight had per-slot fault draws (``[[faults]]``)."""
        faulty = self.flights.faulty
        return faulty is not None and bool(faulty[self.index])

    @property
    def affected(self) -> np.ndarray | None:
        return self._slots(self.flights.affected) if self.faulty else None

    @property
    def chosen(self) -> np.ndarray | None:
        if self.flights.fleet is None and not self.faulty:
            return None
        return self._slots(self.flights.chosen)

    @property
    def battery_used_j(self) -> np.ndarray | None:
        used = self.flights.battery_used_j
        if used is None or np.isnan(used[self.index]).all():
            return None
        return used[self.index, : self.n_slots]


def flight_record(
    *,
    policy: str,
    sensor_names: tuple[str, ...],
    slot_s: float,
    buffers_bit: np.ndarray,
    position_m: np.ndarray,
    end_position_m: np.ndarray,
    served: np.ndarray,
    downloaded_bit: np.ndarray,
    hovering: np.ndarray,
    snr_db: np.ndarray | None = None,
    rate_bps: np.ndarray | None = None,
    remaining_bit: np.ndarray | None = None,
    home_m: np.ndarray | None = None,
    hover_points_m: np.ndarray | None = None,
    visit_radius_m: float = 50.0,
    target: np.ndarray | None = None,
    aadm_window_s: float = AADM_WINDOW_S,
    **extra: Any,
) -> Flights:
    """The record of one flight (B = 1) from its per-slot arrays: its path is its own track,
    sample t in slot t, the end position last."""
    n_sensors = len(sensor_names)
    n_slots = int(np.asarray(served).shape[0])
    buffers = np.asarray(buffers_bit, float).reshape(1, n_sensors)
    left = buffers[0]
    if remaining_bit is not None and n_slots:
        left = np.asarray(remaining_bit, float)[-1]

    def row(values: np.ndarray | None, shape: tuple[int, ...] = ()) -> np.ndarray | None:
        return None if values is None else np.asarray(values).reshape(1, n_slots, *shape)

    positions = np.asarray(position_m, float).reshape(-1, 3)
    track = np.vstack([positions, np.reshape(end_position_m, (1, 3))])
    return Flights(
        n_run=np.array([n_slots]),
        slot_s=np.array([slot_s], float),
        buffers_bit=buffers,
        left_bit=np.reshape(left, (1, n_sensors)),
        served=np.asarray(served, np.int64).reshape(1, n_slots),
        downloaded_bit=np.asarray(downloaded_bit, float).reshape(1, n_slots),
        hovering=np.asarray(hovering, bool).reshape(1, n_slots),
        track_position_m=track[None],
        track_samples=np.array([n_slots + 1]),
        track_id=np.zeros(1, np.int64),
        sample=np.arange(n_slots)[None, :],
        end_sample=np.array([n_slots]),
        home_m=np.full((1, 2), np.nan) if home_m is None else np.reshape(home_m, (1, 2)),
        hover_points_m=(
            np.full((1, n_sensors, 2), np.nan)
            if hover_points_m is None
            else np.reshape(hover_points_m, (1, n_sensors, 2))
        ),
        visit_radius_m=np.array([visit_radius_m], float),
        target=None if target is None else np.asarray(target, np.int64).reshape(1, n_slots),
        aadm_window_s=np.array([aadm_window_s], float),
        policy=(policy,),
        sensor_names=(tuple(sensor_names),),
        snr_db=row(snr_db, (n_sensors,)),
        rate_bps=row(rate_bps, (n_sensors,)),
        remaining_bit=row(remaining_bit, (n_sensors,)),
        **extra,
    )


__all__ = ["NO_SENSOR", "Flights", "MissionLog", "flight_record", "unique_rows"]
