"""Faults in the batched engine: stacking each mission's fault draws, applying a slot's.

The same rules as the reference engine (``docs/faults.md``; :mod:`skymule.sim.faulting`):
the policy sees ``snr + error`` where the link delivers and -inf where not (its rate from the
mission's rate table); a served sensor yields the TRUE rate where deliverable, else 0 bits.
Missions without faults are untouched. A wind (which changes progress along the track) is not
batched: such missions are not :func:`~skymule.sim.batch.batchable`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from skymule.radio.rates import RateTable, rate_bps
from skymule.world import Mission


@dataclass(frozen=True)
class BatchFaults:
    """The G fault missions of a batch.

    Attributes:
        index: (G,) their positions in the batch.
        deliverable: (T_max, N, G) True where a served sensor delivers (False past the end).
        snr_error_db: (T_max, N, G) error on the SNR the policy sees [dB].
        rate_model: (G,) index of each one's rate model in ``rate_models``.
        rate_models: (rate table, bandwidth [Hz]) pairs.
    """

    index: np.ndarray
    deliverable: np.ndarray
    snr_error_db: np.ndarray
    rate_model: np.ndarray
    rate_models: tuple[tuple[RateTable, float], ...]

    @property
    def any(self) -> bool:
        return self.index.size > 0


def stack_faults(missions: Sequence[Mission], n_sensors: int) -> BatchFaults:
    """The fault missions' draws, padded to the longest mission."""
    index = [b for b, m in enumerate(missions) if m.faults is not None]
    t_max = max(m.n_slots for m in missions)
    deliverable = np.zeros((t_max, n_sensors, len(index)), bool)
    error = np.zeros((t_max, n_sensors, len(index)))
    models: dict[tuple[int, float], int] = {}
    tables: list[tuple[RateTable, float]] = []
    rate_model = np.empty(len(index), np.int64)
    for g, b in enumerate(index):
        mission = missions[b]
        draws = mission.faults
        assert draws is not None
        deliverable[: mission.n_slots, :, g] = draws.deliverable()
        error[: mission.n_slots, :, g] = draws.snr_error_db
        key = (id(mission.rate_table), mission.bandwidth_hz)
        if key not in models:
            models[key] = len(tables)
            tables.append((mission.rate_table, mission.bandwidth_hz))
        rate_model[g] = models[key]
    return BatchFaults(np.asarray(index, np.int64), deliverable, error, rate_model, tuple(tables))


def apply_faults(
    faults: BatchFaults, slot: int, rate: np.ndarray, snr: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One slot: (rate seen, SNR seen, rate delivered, deliverable), each (N, B).

    ``rate`` / ``snr`` (N, B) are the true values (fading included); they are not changed.
    """
    cols = faults.index
    ok_g = faults.deliverable[slot]
    seen_snr, seen_rate, deliver = snr.copy(), rate.copy(), rate.copy()
    seen = np.where(ok_g, snr[:, cols] + faults.snr_error_db[slot], -np.inf)
    seen_snr[:, cols] = seen
    for model, (table, bandwidth_hz) in enumerate(faults.rate_models):
        pick = faults.rate_model == model
        seen_rate[:, cols[pick]] = rate_bps(table, seen[:, pick], bandwidth_hz)
    deliver[:, cols] = np.where(ok_g, rate[:, cols], 0.0)
    ok = np.ones(rate.shape, bool)
    ok[:, cols] = ok_g
    return seen_rate, seen_snr, deliver, ok
