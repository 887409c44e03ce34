"""Spatially consistent log-normal shadowing (Gudmundson correlation), seeded.

Shadowing is a zero-mean Gaussian field S_i(x, y) in dB per sensor i with standard deviation
sigma and autocorrelation rho(d) = exp(-d / d_corr) between two UAV positions d metres apart
(Gudmundson, "Correlation model for shadow fading in mobile radio systems", Electronics
Letters 27(23), 1991, eq. 6). Fields of different sensors are independent; the field depends on
the UAV's horizontal position only (not its height).

How the field is made: one fixed realisation per sensor on a regular periodic grid, drawn once
per run by circulant embedding (spectral synthesis with the FFT: Dietrich & Newsam, SIAM J.
Sci. Comput. 18(4), 1997; Wood & Chan, J. Comput. Graph. Stat. 3(4), 1994), then read at any
position by bilinear interpolation, wrapping periodically outside the grid. The same (x, y)
therefore always gets the same shadowing within a run, on a fixed path or an autonomous one.

Accuracy: the grid spacing is d_corr / 16 and the period at least the region plus 10 d_corr,
so two points of the region closer than 10 d_corr have exactly the exponential covariance at
grid nodes (farther ones: correlation < exp(-10)); bilinear interpolation lowers the variance
between nodes by at most 5 % (cell centre: (4 + 8 e^{-1/16} + 4 e^{-sqrt(2)/16}) / 16 = 0.948).
The grid is capped at 2048 x 2048 nodes; beyond that the spacing grows with the region.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from skymule.radio.sources import SignalSource

GRID_POINTS_PER_DECORRELATION = 16
"""Grid spacing is d_corr divided by this."""

PERIOD_MARGIN_DECORRELATIONS = 10.0
"""The grid's period is at least the region's extent plus this many d_corr."""

MAX_GRID_NODES = 2048
"""Largest grid side (nodes); the spacing grows beyond it."""


@dataclass(frozen=True, eq=False)
class ShadowingField:
    """Per-sensor shadowing fields on one periodic grid.

    Attributes:
        origin_m: (2,) x/y of grid node (0, 0) [m].
        spacing_m: grid spacing [m].
        values_db: (N, n, n) shadowing [dB] of each of N sensors at node (ix, iy) ->
            values_db[:, ix, iy]; periodic in both indices.
    """

    origin_m: np.ndarray
    spacing_m: float
    values_db: np.ndarray

    def at(self, xy_m: np.ndarray) -> np.ndarray:
        """Shadowing [dB], shape (P, N), at horizontal positions (P, 2) [m] (bilinear, periodic)."""
        xy = (np.asarray(xy_m, float)[:, :2] - self.origin_m) / self.spacing_m
        n = self.values_db.shape[1]
        base = np.floor(xy)
        frac = xy - base
        i0 = base[:, 0].astype(np.int64) % n
        j0 = base[:, 1].astype(np.int64) % n
        i1 = (i0 + 1) % n
        j1 = (j0 + 1) % n
        fx = frac[:, 0][:, None]
        fy = frac[:, 1][:, None]
        v = self.values_db
        # v[:, i, j] gathers (N, P); transpose to (P, N)
        return (
            (1 - fx) * (1 - fy) * v[:, i0, j0].T
            + fx * (1 - fy) * v[:, i1, j0].T
            + (1 - fx) * fy * v[:, i0, j1].T
            + fx * fy * v[:, i1, j1].T
        )


def grid_for_region(
    extent_m: float, decorrelation_m: float, max_nodes: int = MAX_GRID_NODES
) -> tuple[int, float]:
    """(nodes per side n, spacing [m]) of a periodic grid covering ``extent_m`` with margin."""
    spacing = decorrelation_m / GRID_POINTS_PER_DECORRELATION
    period = extent_m + PERIOD_MARGIN_DECORRELATIONS * decorrelation_m
    nodes = int(2 ** np.ceil(np.log2(max(period / spacing, 16.0))))
    if nodes > max_nodes:
        return max_nodes, period / max_nodes
    return nodes, spacing


def exponential_field_db(
    rng: np.random.Generator,
    n_fields: int,
    nodes: int,
    spacing_m: float,
    std_db: float,
    decorrelation_m: float,
) -> np.ndarray:
    """(n_fields, n, n) independent float32 Gaussian fields [dB], covariance std^2 exp(-d / d_corr).

    Circulant embedding on the n x n torus: eigenvalues lam = FFT2(c) of the periodic
    (minimum-image) covariance c; Y = FFT2(sqrt(lam / n^2) (e1 + i e2)) with e1, e2 standard
    normal has real and imaginary parts that are two independent fields with covariance c
    (Dietrich & Newsam 1997, Sec. 2). Small negative eigenvalues are clipped to zero.
    """
    import scipy.fft  # ~0.1 s to import: only scenarios with shadowing draw a field

    offsets = np.minimum(np.arange(nodes), nodes - np.arange(nodes)) * spacing_m
    distance = np.hypot(offsets[:, None], offsets[None, :])
    covariance = std_db**2 * np.exp(-distance / decorrelation_m)
    eigen = np.maximum(scipy.fft.fft2(covariance, workers=-1).real, 0.0)
    scale = np.sqrt(eigen / nodes**2).astype(np.float32)
    fields = []
    shape = (nodes, nodes)
    for _ in range((n_fields + 1) // 2):
        noise = rng.standard_normal(shape, dtype=np.float32) * scale
        noise = noise + 1j * (rng.standard_normal(shape, dtype=np.float32) * scale)
        pair = scipy.fft.fft2(noise, workers=-1)
        fields.extend([pair.real, pair.imag])
    return np.stack(fields[:n_fields])


def shadowing_field(
    rng: np.random.Generator,
    n_sensors: int,
    std_db: float,
    decorrelation_m: float,
    region_xy_m: np.ndarray,
) -> ShadowingField:
    """Draw one shadowing field per sensor covering the points ``region_xy_m`` (K, 2) [m]."""
    region = np.asarray(region_xy_m, float)[:, :2]
    low = region.min(axis=0)
    extent = float(np.max(region.max(axis=0) - low))
    nodes, spacing = grid_for_region(extent, decorrelation_m)
    margin = 0.5 * (nodes * spacing - extent)
    values = exponential_field_db(rng, n_sensors, nodes, spacing, std_db, decorrelation_m)
    return ShadowingField(origin_m=low - margin, spacing_m=spacing, values_db=values)


@dataclass(frozen=True)
class ShadowedSource:
    """A signal source with shadowing: SNR = base SNR - S_i(x, y) [dB], shape (P, N)."""

    base: SignalSource
    field: ShadowingField

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        positions = np.atleast_2d(np.asarray(positions_m, float))
        return self.base.snr_db(positions) - self.field.at(positions[:, :2])
