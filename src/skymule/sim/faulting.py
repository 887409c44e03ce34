"""How a mission's fault draws act on one slot, shared by the fixed and autonomous engines.

``docs/faults.md`` ("How the engines apply them") is the contract; this module is its code for
one mission and one slot. Engines call it only when ``mission.faults`` is not None, so a
fault-free mission never reaches it and keeps exactly its fault-free numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from skymule.faults.draws import FaultDraws
from skymule.sim.contract import NO_SENSOR


@dataclass(frozen=True)
class SlotFaults:
    """One slot under faults.

    Attributes:
        snr_seen_db: (N,) SNR the policy sees: true + error where deliverable, -inf elsewhere.
        deliver_bps: (N,) the TRUE rate where deliverable, 0 elsewhere: what a served sensor
            yields (the accounting never uses the seen SNR).
        position_error_m: (3,) error on the position the policy sees (GPS: x, y; z exact).
    """

    snr_seen_db: np.ndarray
    deliver_bps: np.ndarray
    position_error_m: np.ndarray


def slot_faults(
    draws: FaultDraws, deliverable: np.ndarray, slot: int, snr_db: np.ndarray, rate_bps: np.ndarray
) -> SlotFaults:
    """The faults of slot ``slot`` given its true SNR and rate (``deliverable`` = the mission's
    precomputed ``draws.deliverable()``, (T, N))."""
    ok = deliverable[slot]
    true_snr = np.nan_to_num(np.asarray(snr_db, float), nan=-np.inf)
    seen = np.where(ok, true_snr + draws.snr_error_db[slot], -np.inf)
    deliver = np.where(ok, rate_bps, 0.0)
    error = np.array([draws.gps_error_m[slot, 0], draws.gps_error_m[slot, 1], 0.0])
    for values in (seen, deliver, error):
        values.flags.writeable = False
    return SlotFaults(seen, deliver, error)


def delivered_sensor(deliverable: np.ndarray, slot: int, sensor: int) -> int:
    """``sensor`` if it could deliver in ``slot``, else NO_SENSOR (a fault blocked it: the log
    marks no sensor served in a slot that downloaded nothing because of a fault)."""
    if sensor == NO_SENSOR or bool(deliverable[slot, sensor]):
        return sensor
    return NO_SENSOR


def fault_fields(
    draws: FaultDraws | None, chosen: list[int], n_slots: int
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The log's ``affected`` and ``chosen`` for ``n_slots`` slots run (None, None without
    faults)."""
    if draws is None:
        return None, None
    return np.array(draws.affected[:n_slots]), np.asarray(chosen, int)
