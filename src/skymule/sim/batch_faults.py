"""Faults in the batched engine: stacking each mission's fault draws, applying a slot's.

The rules of ``docs/faults.md``: the policy sees ``snr + error`` where the link delivers and
-inf where not (its rate from the mission's rate table); a served sensor yields the TRUE rate
where deliverable, else 0 bits.
Missions without faults are untouched; a wind (progress along the track, the way home) is
the engines' own (:mod:`skymule.sim.faulted_motion`). :func:`kernel_faults`
lays the same draws out for the compiled loop (:func:`skymule.sim.kernels.fault_view`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from skymule.faults.draws import FaultDraws
from skymule.radio.rates import RateTable, StepTable, rate_bps
from skymule.sim.kernels import KernelFaults

if TYPE_CHECKING:
    from skymule.world import Mission


@dataclass(frozen=True)
class BatchFaults:
    """The G fault missions of a batch.

    Attributes:
        index: (G,) their positions in the batch.
        deliverable: (G, T_max, N) True where a served sensor delivers (False past the end).
        snr_error_db: (G, T_max, N) error on the SNR the policy sees [dB].
        (Mission-major: each mission's draws are copied in one block; the numpy loop reads a
        slot's (N, G) as a strided view, the compiled loop a mission's rows as they are.)
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
    deliverable = np.zeros((len(index), t_max, n_sensors), bool)
    error = np.zeros((len(index), t_max, n_sensors))
    models: dict[tuple[int, float], int] = {}
    tables: list[tuple[RateTable, float]] = []
    rate_model = np.empty(len(index), np.int64)
    by_length: dict[int, list[int]] = {}
    for g, b in enumerate(index):
        mission = missions[b]
        by_length.setdefault(mission.n_slots, []).append(g)
        key = (id(mission.rate_table), mission.bandwidth_hz)
        if key not in models:
            models[key] = len(tables)
            tables.append((mission.rate_table, mission.bandwidth_hz))
        rate_model[g] = models[key]
    # missions of one length as one stacked FaultDraws: FaultDraws.deliverable() (the rule)
    # once per length, not once per mission
    for n_slots, rows in by_length.items():
        draws = [missions[index[g]].faults for g in rows]
        stacked = FaultDraws(
            outage=np.stack([d.outage for d in draws if d is not None]),
            burst_loss=np.stack([d.burst_loss for d in draws if d is not None]),
            snr_error_db=np.stack([d.snr_error_db for d in draws if d is not None]),
            poll_missed=np.stack([d.poll_missed for d in draws if d is not None]),
            gps_error_m=np.broadcast_to(np.zeros(2), (len(rows), n_slots, 2)),  # not used here
        )
        deliverable[rows, :n_slots] = stacked.deliverable()
        error[rows, :n_slots] = stacked.snr_error_db
    return BatchFaults(np.asarray(index, np.int64), deliverable, error, rate_model, tuple(tables))


def apply_faults(
    faults: BatchFaults, slot: int | np.ndarray, rate: np.ndarray, snr: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One slot: (rate seen, SNR seen, rate delivered, deliverable), each (N, B).

    ``rate`` / ``snr`` (N, B) are the true values (fading included); they are not changed.
    ``slot``: the slot of every mission, or (B,) each mission's own (clipped to its draws).
    """
    cols = faults.index
    if np.ndim(slot) == 0:
        ok_g = faults.deliverable[:, slot].T
        error = faults.snr_error_db[:, slot].T
    else:
        rows = np.arange(cols.size)
        at = np.minimum(np.asarray(slot)[cols], faults.deliverable.shape[1] - 1)
        ok_g, error = faults.deliverable[rows, at].T, faults.snr_error_db[rows, at].T
    seen_snr, seen_rate, deliver = snr.copy(), rate.copy(), rate.copy()
    seen = np.where(ok_g, snr[:, cols] + error, -np.inf)
    seen_snr[:, cols] = seen
    for model, (table, bandwidth_hz) in enumerate(faults.rate_models):
        pick = faults.rate_model == model
        seen_rate[:, cols[pick]] = rate_bps(table, seen[:, pick], bandwidth_hz)
    deliver[:, cols] = np.where(ok_g, rate[:, cols], 0.0)
    ok = np.ones(rate.shape, bool)
    ok[:, cols] = ok_g
    return seen_rate, seen_snr, deliver, ok


def kernel_faults(faults: BatchFaults, n_missions: int) -> KernelFaults | None:
    """``faults`` for the compiled loop, or None if it cannot apply them: an SNR error on a
    rate table that is not a step table (a Shannon rate per slot would need numba's
    ``log2``/``pow``, which need not match numpy's to the last bit)."""
    fault_of = np.full(n_missions, -1, np.int64)
    fault_of[faults.index] = np.arange(faults.index.size)
    uses_error = (faults.snr_error_db != 0).any(axis=(1, 2))
    width = max(
        [len(t.thresholds_db) for t, _ in faults.rate_models if isinstance(t, StepTable)] or [0]
    )
    thresholds = np.full((len(faults.rate_models), width), np.inf)
    efficiency = np.zeros((len(faults.rate_models), width + 1))
    for m, (table, _) in enumerate(faults.rate_models):
        if isinstance(table, StepTable):
            thresholds[m, : len(table.thresholds_db)] = table.thresholds_db
            efficiency[m, 1 : len(table.efficiencies) + 1] = table.efficiencies
        elif uses_error[faults.rate_model == m].any():
            return None
    return KernelFaults(
        fault_of=fault_of,
        deliverable=faults.deliverable,
        snr_error_db=faults.snr_error_db,
        uses_error=uses_error,
        model=faults.rate_model,
        thresholds_db=thresholds,
        efficiency=efficiency,
        bandwidth_hz=np.array([bandwidth for _, bandwidth in faults.rate_models], float),
    )


def add_gps_error(
    missions: Sequence[Mission], rows: Sequence[int], slot: np.ndarray, position_m: np.ndarray
) -> None:
    """Add GPS errors to the positions UAVs report: mission ``rows[i]``'s error of its slot
    ``slot[rows[i]]`` onto ``position_m`` (B, 3) in place (x, y; none past its draws)."""
    for b in rows:
        draws = missions[b].faults
        assert draws is not None
        t = int(slot[b])
        if t < draws.gps_error_m.shape[0]:
            position_m[b, :2] += draws.gps_error_m[t]
