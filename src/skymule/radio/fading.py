"""Small-scale fading: a per-slot, per-sensor power gain in dB, drawn once per mission.

The complex channel gain h has unit mean power, E|h|^2 = 1, so fading moves the SNR around its
large-scale (path loss + shadowing) value without biasing its linear mean. The draws are made
once per mission from the scenario-seeded generator, shape (T slots, N sensors), so every
policy compared on a mission sees identical fading.

Rician with K factor K = (specular power) / (scattered power) (Rice 1944; Goldsmith,
*Wireless Communications*, 2005, eq. 3.37)::

    h = sqrt(K / (K + 1)) + sqrt(1 / (K + 1)) * (x + j y) / sqrt(2),   x, y ~ N(0, 1)

Rayleigh is the K = 0 case (|h|^2 exponential with mean 1).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from skymule.scenario import RadioSpec


def rician_power_db(rng: np.random.Generator, shape: tuple[int, ...], k_db: float) -> np.ndarray:
    """10 log10 |h|^2 [dB] of Rician fading with K factor ``k_db`` [dB], array of ``shape``."""
    k = 10.0 ** (k_db / 10.0)
    scattered = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2.0)
    h = np.sqrt(k / (k + 1.0)) + np.sqrt(1.0 / (k + 1.0)) * scattered
    return 10.0 * np.log10(np.maximum(np.abs(h) ** 2, 1e-12))


def _rician(radio: RadioSpec, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return rician_power_db(rng, shape, radio.rician_k_db)


def _rayleigh(radio: RadioSpec, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return rician_power_db(rng, shape, -np.inf)


FadingDraw = Callable[[RadioSpec, np.random.Generator, tuple[int, ...]], np.ndarray]

FADING_MODELS: dict[str, FadingDraw | None] = {
    "none": None,
    "rician": _rician,
    "rayleigh": _rayleigh,
}
"""``[radio] fading`` name -> draw(radio, rng, shape) -> dB gains, or None for no fading."""


def draw_fading_db(
    radio: RadioSpec, rng: np.random.Generator, n_slots: int, n_sensors: int
) -> np.ndarray | None:
    """(T, N) per-slot fading gains [dB] added to the SNR, or None when ``fading = "none"``."""
    draw = FADING_MODELS[radio.fading]
    return None if draw is None else draw(radio, rng, (n_slots, n_sensors))
