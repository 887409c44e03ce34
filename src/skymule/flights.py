"""What happened in B missions, as padded arrays: the input of :mod:`skymule.metrics`.

Positions are given as tracks plus sample indices: mission b is at
``track_position_m[track_id[b], sample[b, t]]`` during slot t and ends at sample
``end_sample[b]``; a non-hovering slot moves to the next sample (or holds at a track's last
one). A log is its own track: its positions followed by its end position, sample t in slot t.
This is what lets the batched engine share one track among many missions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.sim.log import MissionLog


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
        policy: (B,) policy name of each flight (empty when unknown).
        sensor_names: (N,) sensor names.
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
    sensor_names: tuple[str, ...] = ()
    snr_db: np.ndarray | None = None
    rate_bps: np.ndarray | None = None
    remaining_bit: np.ndarray | None = None
    chosen: np.ndarray | None = None
    affected: np.ndarray | None = None
    battery_used_j: np.ndarray | None = None
    fleet: np.ndarray | None = None
    lost: np.ndarray | None = None

    @property
    def size(self) -> int:
        """B, the number of flights."""
        return int(self.n_run.shape[0])

    def position_m(self, b: int) -> np.ndarray:
        """(T', 3) flight b's position at the start of each slot it ran [m]."""
        return self.track_position_m[self.track_id[b], self.sample[b, : self.n_run[b]]]

    def end_position_m(self, b: int) -> np.ndarray:
        """(3,) flight b's position after its last slot [m]."""
        return self.track_position_m[self.track_id[b], self.end_sample[b]]


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
