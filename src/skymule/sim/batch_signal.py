"""SNR and rates at B UAV positions at once, for missions with different sensors and sources.

The autonomous engine (:mod:`skymule.sim.autonomous`) needs, every slot, what
``mission.source.snr_db`` and ``mission.rate_bps`` give each mission at its UAV's position.
Missions of one batch may have their own sensors and signal sources:

* model sources (:class:`~skymule.radio.sources.ModelSource`) whose path-loss model depends
  only on the UAV-sensor offset and heights (every registered model) are evaluated together,
  one call per (model, link budget, altitude): each sensor is moved by minus its mission's UAV
  position, so that one UAV at (0, 0, altitude) sees every mission's sensors where its own UAV
  does. The differences are the same floats (x - u = -(u - x) exactly), so the SNR is too;
* any other source (shadowing, radio maps) is asked once per distinct source object, with the
  positions of the missions that share it.

Rates follow the same way, one call per distinct (rate table, bandwidth).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from skymule.radio.pathloss import Aerial3GPP, AlHourani, FreeSpace, LogDistance, TwoRay
from skymule.radio.rates import rate_bps
from skymule.radio.sources import ModelSource
from skymule.world import Mission

#: Path-loss models that depend on the UAV-sensor offset and the two heights only.
OFFSET_MODELS = (FreeSpace, LogDistance, TwoRay, AlHourani, Aerial3GPP)


def _groups(keys: Sequence[object]) -> list[np.ndarray]:
    """Column indices of equal keys, in order of first appearance."""
    index: dict[object, list[int]] = {}
    for column, key in enumerate(keys):
        index.setdefault(key, []).append(column)
    return [np.asarray(cols, np.int64) for cols in index.values()]


class BatchSignal:
    """What the UAVs of B missions observe at their positions.

    Missions are columns, in the order given; the first A columns are the active ones.
    Missions with fewer than N sensors are padded (their extra rows are never read): model
    sources see copies of the first sensor there, other sources NaN (no link).
    """

    def __init__(self, missions: Sequence[Mission], n_sensors: int) -> None:
        self._altitude = np.array([m.altitude_m for m in missions], float)
        # (N, B, 3) sensor antennas for the offset groups
        self._sensor_m = np.empty((n_sensors, len(missions), 3))
        for b, mission in enumerate(missions):
            self._sensor_m[:, b] = mission.sensor_m[0]
            self._sensor_m[: mission.n_sensors, b] = mission.sensor_m
        offset_keys: list[object] = []
        other_keys: list[object] = []
        for mission in missions:
            source = mission.source
            if type(source) is ModelSource and type(source.pathloss) in OFFSET_MODELS:
                offset_keys.append((source.pathloss, source.budget, mission.altitude_m))
                other_keys.append(None)
            else:
                offset_keys.append(None)
                other_keys.append(id(source))
        self._offset = [g for g in _groups(offset_keys) if offset_keys[g[0]] is not None]
        self._other = [g for g in _groups(other_keys) if other_keys[g[0]] is not None]
        self._missions = missions
        self._rate_groups = _groups([(id(m.rate_table), m.bandwidth_hz) for m in missions])
        self._n_sensors = n_sensors
        # (T_max, N, F) per-slot fading of the F missions that have it (0 when padded)
        self._fading_cols = np.flatnonzero([m.fading_db is not None for m in missions])
        t_max = max(m.n_slots for m in missions)
        self._fading_db = np.zeros((t_max, n_sensors, self._fading_cols.size))
        self._fading_slots = np.zeros(self._fading_cols.size, np.int64)  # slots drawn, each
        for f, col in enumerate(self._fading_cols.tolist()):
            gains = missions[col].fading_db
            assert gains is not None
            self._fading_db[: gains.shape[0], : gains.shape[1], f] = gains
            self._fading_slots[f] = gains.shape[0]

    def snr_db(
        self,
        position_m: np.ndarray,
        slot: int | np.ndarray | None,
        running: np.ndarray | None = None,
    ) -> np.ndarray:
        """(N, A) SNR [dB] each of the first A missions sees at its position (A, 2) in slot
        ``slot``, per-slot fading included (``slot=None``: without fading; NaN: no link).

        ``slot`` may be an (A,) integer array, each mission's own slot (missions stepped
        independently); a mission at or past its last slot then sees no fading (the
        observation after its last slot). ``running`` (A,): only those missions (NaN
        elsewhere).
        """
        active = position_m.shape[0]
        snr = np.full((self._n_sensors, active), np.nan)
        offset = self._offset if running is None else [g[running[g]] for g in self._offset]
        other = self._other if running is None else [g[running[g]] for g in self._other]
        for cols in offset:
            cols = cols[cols < active]
            if not cols.size:
                continue
            mission = self._missions[int(cols[0])]
            source = mission.source
            assert isinstance(source, ModelSource)
            sensors = self._sensor_m[:, cols].copy()
            sensors[..., 0] -= position_m[cols, 0]
            sensors[..., 1] -= position_m[cols, 1]
            uav = np.array([[0.0, 0.0, mission.altitude_m]])
            loss = source.pathloss.loss_db(uav, sensors.reshape(-1, 3))
            snr[:, cols] = source.budget.snr_db(loss).reshape(self._n_sensors, cols.size)
        for cols in other:
            cols = cols[cols < active]
            if not cols.size:
                continue
            source = self._missions[int(cols[0])].source
            assert source is not None
            here = np.column_stack([position_m[cols], self._altitude[cols]])
            snr[: self._missions[int(cols[0])].n_sensors, cols] = source.snr_db(here).T
        faded = self._fading_cols < active
        if slot is None or not faded.any():
            return snr
        cols = self._fading_cols[faded]
        if np.ndim(slot) == 0:
            snr[:, cols] = snr[:, cols] + self._fading_db[slot][:, faded]
            return snr
        slots = np.asarray(slot, np.int64)[cols]
        now = slots < self._fading_slots[faded]
        cols, which = cols[now], np.flatnonzero(faded)[now]
        # two advanced indices around a slice: the (F', N) gains of each column's own slot
        snr[:, cols] = snr[:, cols] + self._fading_db[slots[now], :, which].T
        return snr

    def rate_bps(self, snr_db: np.ndarray) -> np.ndarray:
        """(N, A) rates [bit/s] for the SNR (N, A) of the first A missions."""
        active = snr_db.shape[1]
        rate = np.empty_like(snr_db)
        for cols in self._rate_groups:
            cols = cols[cols < active]
            if cols.size:
                mission = self._missions[int(cols[0])]
                rate[:, cols] = rate_bps(mission.rate_table, snr_db[:, cols], mission.bandwidth_hz)
        return rate

    def peak_rate_bps(self, hover_m: np.ndarray) -> np.ndarray:
        """(N, B) R*_i of every mission: the rate from sensor i at its own hover point
        ``hover_m`` (N, B, 2) (NaN: unknown, rate 0), without fading (paper Alg. 2)."""
        peak = np.zeros(hover_m.shape[:2])
        for sensor in range(hover_m.shape[0]):
            snr = self.snr_db(np.nan_to_num(hover_m[sensor], nan=0.0), None)
            peak[sensor] = self.rate_bps(snr)[sensor]
        peak[~np.all(np.isfinite(hover_m), axis=2)] = 0.0
        return peak
