"""Signal sources: where the SNR comes from.

A signal source has one method, ``snr_db(positions_m)``: UAV positions (P, 3) in local
metres -> SNR in dB, shape (P, N sensors); NaN means no sample (no link). A propagation model
is one source; a recorded flight is replayed as a :class:`~skymule.flight.paths.Track` whose
SNR was measured rather than computed, so policies compare on identical draws either way.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from skymule.radio.pathloss import PATHLOSS_MODELS, ModelParams, PathLossModel
from skymule.scenario import RadioSpec


class SignalSource(Protocol):
    """Positions (P, 3) [m] -> SNR (P, N) [dB]."""

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class LinkBudget:
    """SNR_dB = P_tx + G_tx - PL + G_rx - N_0 (all dB/dBm)."""

    tx_power_dbm: float
    tx_gain_dbi: float
    rx_gain_dbi: float
    noise_dbm: float

    def snr_db(self, loss_db: np.ndarray) -> np.ndarray:
        return self.tx_power_dbm + self.tx_gain_dbi - loss_db + self.rx_gain_dbi - self.noise_dbm


@dataclass(frozen=True)
class ModelSource:
    """SNR from a path-loss model and a link budget, for sensors at ``sensor_m`` (N, 3)."""

    pathloss: PathLossModel
    budget: LinkBudget
    sensor_m: np.ndarray

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        positions = np.atleast_2d(np.asarray(positions_m, float))
        return self.budget.snr_db(self.pathloss.loss_db(positions, self.sensor_m))


def build_pathloss(radio: RadioSpec) -> PathLossModel:
    """The path-loss model ``[radio] model`` names, with its ``[radio.params]``."""
    kind = PATHLOSS_MODELS.get(radio.model)
    params = radio.model_params()
    assert isinstance(params, ModelParams)
    return kind.build(radio.frequency_hz, params)


def model_source(radio: RadioSpec, sensor_m: np.ndarray) -> ModelSource:
    """The model signal source a scenario's ``[radio]`` section describes."""
    budget = LinkBudget(radio.tx_power_dbm, radio.tx_gain_dbi, radio.rx_gain_dbi, radio.noise_dbm)
    return ModelSource(build_pathloss(radio), budget, np.asarray(sensor_m, float))
