"""Path-loss models: distance (and geometry) -> loss in dB, vectorised.

Every model is a frozen dataclass with one method, ``loss_db(uav_m, sensor_m)``, taking UAV
positions of shape (P, 3) and sensor antenna positions of shape (N, 3) in local metres and
returning losses of shape (P, N) in dB. Models resolve by name through :data:`PATHLOSS_MODELS`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

SPEED_OF_LIGHT_MPS = 299_792_458.0
"""Speed of light in vacuum [m/s]."""

MIN_DISTANCE_M = 1.0
"""Distances are clipped below this [m] so that the far-field formulas stay finite."""


def distance_3d_m(uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """3-D distances [m], shape (P, N), from UAV positions (P, 3) to sensors (N, 3)."""
    uav = np.asarray(uav_m, float)[:, None, :]
    sensors = np.asarray(sensor_m, float)[None, :, :]
    return np.sqrt(np.sum((uav - sensors) ** 2, axis=-1))


def fspl_db(distance_m: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Free-space path loss [dB]: FSPL(d) = 20 log10(4 pi d f / c) (Friis)."""
    d = np.maximum(np.asarray(distance_m, float), MIN_DISTANCE_M)
    return 20.0 * np.log10(4.0 * np.pi * d * frequency_hz / SPEED_OF_LIGHT_MPS)


class PathLossModel(Protocol):
    """Anything that maps UAV positions (P, 3) and sensors (N, 3) to losses (P, N) in dB."""

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class FreeSpace:
    """Free-space (Friis) path loss over the 3-D UAV-sensor distance."""

    frequency_hz: float

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        return fspl_db(distance_3d_m(uav_m, sensor_m), self.frequency_hz)


@dataclass(frozen=True)
class LogDistance:
    """Log-distance path loss: PL(d) = PL(d0) + 10 n log10(d / d0).

    ``reference_loss_db`` is PL(d0); when None it is the free-space loss at ``d0``
    (Rappaport, *Wireless Communications*, 2nd ed., eq. 4.68).
    """

    frequency_hz: float
    exponent: float = 2.0
    reference_distance_m: float = 1.0
    reference_loss_db: float | None = None

    def loss_db(self, uav_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
        d0 = self.reference_distance_m
        pl0 = (
            float(fspl_db(np.asarray(d0), self.frequency_hz))
            if self.reference_loss_db is None
            else self.reference_loss_db
        )
        d = np.maximum(distance_3d_m(uav_m, sensor_m), MIN_DISTANCE_M)
        return pl0 + 10.0 * self.exponent * np.log10(d / d0)
