"""Per-slot fading in the batched engine: stacking each mission's fading, applying a slot's.

Missions with ``Mission.fading_db`` have their SNR and rate recomputed each slot from the
track SNR plus that slot's fading.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from skymule.radio.rates import RateTable, rate_bps
from skymule.world import Mission


def stack_fading(
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


def apply_fading(
    fading_index: np.ndarray,
    fading_db: np.ndarray,
    rate_model: np.ndarray,
    rate_models: tuple[tuple[RateTable, float], ...],
    rate: np.ndarray,
    snr: np.ndarray,
) -> None:
    """Add one slot's fading (N, F) to the SNR (N, B) of fading missions; recompute their rate.

    In place, as ``engine.run_fixed``: SNR seen + fading [dB], then the mission's rate table.
    """
    cols = fading_index
    faded = snr[:, cols] + fading_db
    snr[:, cols] = faded
    for model, (table, bandwidth_hz) in enumerate(rate_models):
        pick = rate_model == model
        rate[:, cols[pick]] = rate_bps(table, faded[:, pick], bandwidth_hz)
