"""Radio maps fitted to recorded flights: log-distance trend + kriged residual field.

Per sensor i, with d the 3-D UAV-antenna distance [m] and SNR measured at UAV positions x_k:

1. Trend: SNR(d) = A - 10 n log10(d / 1 m), A [dB] and exponent n by ordinary least squares
   on the valid samples (the log-distance model, Rappaport 2nd ed. eq. 4.68, fitted as in
   empirical path-loss studies).
2. Residual r_k = SNR_k - trend(d_k), modelled as a zero-mean Gaussian field with exponential
   covariance sigma^2 exp(-h / L) (Gudmundson 1991) plus a nugget tau^2 (measurement noise,
   fast fading). sigma^2, L, tau^2 are estimated from the empirical semivariogram
   gamma(h) = mean over pairs at lag ~h of (r_j - r_k)^2 / 2 (Matheron; Cressie, *Statistics
   for Spatial Data*, 1993, eq. 2.4.2), fitted to tau^2 + sigma^2 (1 - exp(-h / L)) by
   pair-count-weighted least squares (Cressie 1985) over a grid of L.
3. Prediction at x: trend(d(x)) + k(x)^T (K + tau^2 I)^{-1} r, the simple-kriging / Gaussian-
   process posterior mean (Rasmussen & Williams, *Gaussian Processes for Machine Learning*,
   2006, eq. 2.25), k and K from the exponential covariance. It reproduces the measurements
   where the UAV flew (up to the nugget) and falls back to the fitted trend far from them.
   Bulk queries split the kernel into an exact near part (zero beyond 2 L) and a smooth far
   part splined from a grid (:func:`krige_split`, within 0.01 dB of the dense sum, tested).

Missing samples (NaN; -99 in digital-twin exports) and deep drops (below ``drop_below_db``,
real but unpredictable link losses) are excluded and counted. At most ``MAX_KRIGING_POINTS``
samples per sensor (evenly thinned in time) enter the kriging system. Fit quality: in-sample
RMSE and K-fold cross-validated RMSE with each fold one contiguous segment of every trace
(trend and kriging weights refitted without the held-out segment; variogram parameters kept).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
import scipy.ndimage
import scipy.optimize
import scipy.spatial
import scipy.spatial.distance

from skymule.errors import ScenarioError, SkymuleError
from skymule.geo import LocalFrame
from skymule.radio.pathloss import MIN_DISTANCE_M

DEEP_DROP_DB = -40.0
"""SNR samples below this [dB] are deep drops (link losses): excluded from fits and scores."""

MIN_FIT_SAMPLES = 20
"""A sensor needs at least this many valid samples to fit its map."""

MAX_KRIGING_POINTS = 1000
"""Largest number of samples per sensor in the kriging system (thinned evenly beyond it)."""

CV_FOLDS = 5
"""Cross-validation folds (contiguous segments of each trace)."""

QUERY_CHUNK = 2_000_000
"""Largest kernel block (query points x training points) evaluated at once."""

SPLIT_CHUNK = 200_000
"""Largest kernel block of the split path (kept cache-sized: large temporaries cost more)."""

SPLIT_MIN_QUERIES = 5_000
"""Query sets at least this large take the split path of :func:`krige` (smaller: dense)."""

SPLIT_NEAR_RANGES = 2.0
"""Near-field radius of the split path, in correlation distances L."""

SPLIT_STEP_RANGES = 0.25
"""Far-field grid step of the split path, in correlation distances L."""

SPLIT_FAR_RANGES = 20.0
"""Queries this many L beyond the samples' bounding box get no kriged residual."""

SPLIT_CELL_RANGES = 0.7
"""Side of the query cubes of the near field, in correlation distances L."""

SPLIT_PAD = 4
"""Grid nodes beyond the queries' bounding box on each side (spline boundary)."""

SPLIT_MAX_NODE_RATIO = 4
"""The split path is taken when the grid has at most P / this many nodes."""

SPLIT_TOLERANCE_DB = 0.01
"""Tested bound on |split - dense| [dB] for the kriged residual (see tests/test_radiomap.py)."""

MAP_FORMAT = "skymule-radiomap"
MAP_VERSION = 1


@dataclass(frozen=True)
class Variogram:
    """Exponential covariance sigma^2 exp(-h / L) plus nugget tau^2 (all dB^2, L in m)."""

    sill_db2: float
    range_m: float
    nugget_db2: float

    def covariance(self, distance_m: np.ndarray) -> np.ndarray:
        return self.sill_db2 * np.exp(-np.asarray(distance_m) / self.range_m)

    def semivariance(self, lag_m: np.ndarray) -> np.ndarray:
        return self.nugget_db2 + self.sill_db2 * (1.0 - np.exp(-np.asarray(lag_m) / self.range_m))


@dataclass(frozen=True, eq=False)
class SensorMap:
    """The fitted map of one sensor (SNR in dB at UAV positions in the map's frame).

    Attributes:
        name: sensor name.
        position_m: (3,) antenna position [m].
        intercept_db: A, the trend's SNR at 1 m [dB].
        exponent: n, the path-loss exponent.
        variogram: residual field parameters.
        train_m: (S, 3) kriging sample positions [m].
        weights: (S,) kriging weights (K + tau^2 I)^{-1} r [dB].
        stats: fit quality and sample counts (see :func:`fit_sensor_map`).
    """

    name: str
    position_m: np.ndarray
    intercept_db: float
    exponent: float
    variogram: Variogram
    train_m: np.ndarray
    weights: np.ndarray
    stats: dict[str, float] = field(default_factory=dict)

    def trend_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P,) log-distance trend [dB] at positions (P, 3)."""
        return trend_db(positions_m, self.position_m, self.intercept_db, self.exponent)

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P,) predicted SNR [dB] at positions (P, 3): trend + kriged residual."""
        positions = np.atleast_2d(np.asarray(positions_m, float))
        return self.trend_db(positions) + krige(
            positions, self.train_m, self.weights, self.variogram
        )


def distance_m(positions_m: np.ndarray, sensor_m: np.ndarray) -> np.ndarray:
    """(P,) 3-D distances [m], clipped below at MIN_DISTANCE_M."""
    d = np.linalg.norm(np.asarray(positions_m, float) - np.asarray(sensor_m, float), axis=-1)
    return np.maximum(d, MIN_DISTANCE_M)


def trend_db(
    positions_m: np.ndarray, sensor_m: np.ndarray, intercept_db: float, exponent: float
) -> np.ndarray:
    """(P,) SNR trend A - 10 n log10(d) [dB]."""
    return intercept_db - 10.0 * exponent * np.log10(distance_m(positions_m, sensor_m))


def fit_trend(distance: np.ndarray, snr_db: np.ndarray) -> tuple[float, float]:
    """Least-squares (A, n) of SNR = A - 10 n log10(d) (distances [m], SNR [dB], shape (S,))."""
    design = np.column_stack([np.ones_like(distance), -10.0 * np.log10(distance)])
    (intercept, exponent), *_ = np.linalg.lstsq(design, snr_db, rcond=None)
    return float(intercept), float(exponent)


def pairwise_m(a_m: np.ndarray, b_m: np.ndarray) -> np.ndarray:
    """(A, B) Euclidean distances [m] between points (A, 3) and (B, 3)."""
    sq = (a_m**2).sum(1)[:, None] + (b_m**2).sum(1)[None, :] - 2.0 * a_m @ b_m.T
    return np.sqrt(np.maximum(sq, 0.0))


def krige(
    positions_m: np.ndarray, train_m: np.ndarray, weights: np.ndarray, variogram: Variogram
) -> np.ndarray:
    """(P,) kriged residual k(x)^T w [dB] at positions (P, 3).

    Bulk queries take the split path (:func:`krige_split`: exact near field + interpolated
    smooth far field, within ``SPLIT_TOLERANCE_DB`` of :func:`krige_dense`); small or widely
    scattered query sets take the dense reference path.
    """
    positions_m = np.atleast_2d(np.asarray(positions_m, float))
    if train_m.shape[0] == 0:
        return np.zeros(positions_m.shape[0])
    if positions_m.shape[0] >= SPLIT_MIN_QUERIES:
        split = krige_split(positions_m, train_m, weights, variogram)
        if split is not None:
            return split
    return krige_dense(positions_m, train_m, weights, variogram)


def krige_dense(
    positions_m: np.ndarray, train_m: np.ndarray, weights: np.ndarray, variogram: Variogram
) -> np.ndarray:
    """(P,) kriged residual k(x)^T w [dB], every query against every sample (reference path).

    Evaluated in blocks of at most QUERY_CHUNK kernel entries (query points x samples).
    """
    if train_m.shape[0] == 0:
        return np.zeros(positions_m.shape[0])
    step = max(1, QUERY_CHUNK // train_m.shape[0])
    out = np.empty(positions_m.shape[0])
    for start in range(0, positions_m.shape[0], step):
        block = positions_m[start : start + step]
        out[start : start + step] = variogram.covariance(pairwise_m(block, train_m)) @ weights
    return out


def _far_coefficients(near: float) -> tuple[float, float, float, float]:
    """(c0, c1, c2, c3) of p(s) = sum c_k (s - a^2)^k, s = u^2, a = ``near``.

    f(u) = p(u^2) has f = p, f_1 = 2u p_1, f_2 = 2 p_1 + 4u^2 p_2, f_3 = 12u p_2 + 8u^3 p_3
    (subscripts: derivative orders); f_k(a) = (-1)^k e^-a for k = 0..3 gives the c_k below,
    so p matches exp(-u) to third order at u = a.
    """
    e = float(np.exp(-near))
    c1 = -e / (2.0 * near)
    c2 = (e - 2.0 * c1) / (8.0 * near**2)
    c3 = (-e - 24.0 * near * c2) / (48.0 * near**3)
    return e, c1, c2, c3


def far_kernel(u: np.ndarray, near: float) -> np.ndarray:
    """Smooth far part g(u) = exp(-u) - near_kernel(u) of the unit kernel, u = h / L >= 0.

    g = exp(-u) for u >= ``near``; inside, the cubic in s = u^2 of :func:`_far_coefficients`,
    so g is C^3 across u = ``near`` and smooth (a polynomial in |x - y|^2) near u = 0.
    """
    u = np.asarray(u, float)
    return np.exp(np.negative(u)) - near_kernel(u, near)


def near_kernel(u: np.ndarray, near: float) -> np.ndarray:
    """exp(-u) - p(u^2) for u < ``near``, else 0 (same shape as u >= 0): the near part.

    p is the cubic of :func:`_far_coefficients`; evaluated densely (in-place, no masking by
    index: cheaper than gathering the entries inside ``near``).
    """
    u = np.asarray(u, float)
    c0, c1, c2, c3 = _far_coefficients(near)
    ds = np.multiply(u, u)
    np.minimum(ds, near * near, out=ds)
    ds -= near * near
    poly = ds * c3  # Horner, in place: ((c3 ds + c2) ds + c1) ds + c0
    poly += c2
    poly *= ds
    poly += c1
    poly *= ds
    poly += c0
    out = np.exp(np.negative(u))
    out -= poly
    out *= u < near
    return out


def split_error_bound_db(weights: np.ndarray, variogram: Variogram) -> float:
    """Bound [dB] on the far-field part dropped for queries beyond SPLIT_FAR_RANGES * L.

    A query at distance >= c L from every sample gets |k(x)^T w| <= sigma^2 e^-c sum |w|.
    """
    return float(variogram.sill_db2 * np.exp(-SPLIT_FAR_RANGES) * np.abs(weights).sum())


def _grid_axes(lo: np.ndarray, hi: np.ndarray, step: float) -> list[np.ndarray]:
    """Node coordinates [m] per axis covering [lo, hi] (3,), SPLIT_PAD nodes beyond each end.

    An axis with (almost) no extent gets the single node lo.
    """
    axes = []
    for a, b in zip(lo, hi, strict=True):
        if b - a < 1e-9 * step:
            axes.append(np.array([a]))
        else:
            n = int(np.ceil((b - a) / step)) + 1
            axes.append(a + step * np.arange(-SPLIT_PAD, n + SPLIT_PAD))
    return axes


def _near_field(
    positions_m: np.ndarray, train_m: np.ndarray, weights: np.ndarray, variogram: Variogram
) -> np.ndarray:
    """(P,) near field [dB]: sum of sigma^2 near_kernel(h / L) w over samples within a*L.

    a = SPLIT_NEAR_RANGES. Queries (P, 3) are grouped in cubes of side SPLIT_CELL_RANGES * L;
    each cube is evaluated densely against the samples a KD-tree finds within a*L of it.
    """
    scale = variogram.range_m
    near = SPLIT_NEAR_RANGES
    tree = scipy.spatial.cKDTree(train_m)
    cells = np.floor((positions_m - positions_m.min(0)) / (SPLIT_CELL_RANGES * scale))
    cells = cells.astype(np.int64)
    dims = cells.max(0) + 1
    key = (cells[:, 0] * dims[1] + cells[:, 1]) * dims[2] + cells[:, 2]
    order = np.argsort(key, kind="stable")
    bounds = np.flatnonzero(np.diff(key[order])) + 1
    out = np.zeros(positions_m.shape[0])
    for idx in np.split(order, bounds):
        block = positions_m[idx]
        lo, hi = block.min(0), block.max(0)
        radius = near * scale + 0.5 * float(np.linalg.norm(hi - lo)) + 1e-9
        cand = tree.query_ball_point(0.5 * (lo + hi), radius)
        if cand:
            u = scipy.spatial.distance.cdist(block, train_m[cand])
            u *= 1.0 / scale
            out[idx] = near_kernel(u, near) @ weights[cand]
    return variogram.sill_db2 * out


def krige_split(
    positions_m: np.ndarray, train_m: np.ndarray, weights: np.ndarray, variogram: Variogram
) -> np.ndarray | None:
    """(P,) kriged residual [dB] by kernel splitting, or None where the dense path is cheaper.

    k = sigma^2 [near_kernel + far_kernel](h / L): the near part (zero beyond
    SPLIT_NEAR_RANGES * L) is summed exactly over nearby samples; the smooth far part is
    evaluated exactly on a grid of step SPLIT_STEP_RANGES * L over the queries and
    interpolated by cubic splines. Queries farther than SPLIT_FAR_RANGES * L from the
    samples' bounding box get 0 (error <= :func:`split_error_bound_db`). Agreement with
    :func:`krige_dense` is within SPLIT_TOLERANCE_DB (tested); None when the grid would have
    more than P / SPLIT_MAX_NODE_RATIO nodes.
    """
    scale = variogram.range_m
    reach = SPLIT_FAR_RANGES * scale
    inside = np.all(
        (positions_m >= train_m.min(0) - reach) & (positions_m <= train_m.max(0) + reach), axis=1
    )
    out = np.zeros(positions_m.shape[0])
    if not inside.any():
        return out
    query = positions_m[inside]
    step = SPLIT_STEP_RANGES * scale
    axes = _grid_axes(query.min(0), query.max(0), step)
    shape = tuple(a.size for a in axes)
    if np.prod(shape) * SPLIT_MAX_NODE_RATIO > positions_m.shape[0]:
        return None
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    far = np.empty(nodes.shape[0])
    chunk = max(1, SPLIT_CHUNK // train_m.shape[0])
    for start in range(0, nodes.shape[0], chunk):
        u = scipy.spatial.distance.cdist(nodes[start : start + chunk], train_m)
        u *= 1.0 / scale
        far[start : start + chunk] = far_kernel(u, SPLIT_NEAR_RANGES) @ weights
    coords = np.stack(
        [(query[:, d] - axes[d][0]) / step if axes[d].size > 1 else np.zeros(len(query))
         for d in range(3)]
    )  # fmt: skip
    far_at = scipy.ndimage.map_coordinates(
        far.reshape(shape), coords, order=3, mode="nearest", prefilter=True
    )
    out[inside] = variogram.sill_db2 * far_at + _near_field(query, train_m, weights, variogram)
    return out


def kriging_weights(
    train_m: np.ndarray, residual_db: np.ndarray, variogram: Variogram
) -> np.ndarray:
    """(S,) weights (K + tau^2 I)^{-1} r (Cholesky; a tiny jitter keeps K positive definite)."""
    k = variogram.covariance(pairwise_m(train_m, train_m))
    k[np.diag_indices_from(k)] += variogram.nugget_db2 + 1e-6 * variogram.sill_db2 + 1e-9
    return scipy.linalg.cho_solve(scipy.linalg.cho_factor(k, lower=True), residual_db)


def empirical_semivariogram(
    positions_m: np.ndarray, residual_db: np.ndarray, n_bins: int = 25
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lag centres [m], semivariance [dB^2], pair counts), lags up to half the largest distance."""
    d = pairwise_m(positions_m, positions_m)
    upper = np.triu_indices(len(residual_db), 1)
    lags = d[upper]
    half_sq = 0.5 * (residual_db[:, None] - residual_db[None, :])[upper] ** 2
    max_lag = 0.5 * lags.max() if lags.size else 1.0
    edges = np.linspace(0.0, max_lag, n_bins + 1)
    which = np.digitize(lags, edges) - 1
    keep = (which >= 0) & (which < n_bins)
    counts = np.bincount(which[keep], minlength=n_bins).astype(float)
    sums = np.bincount(which[keep], weights=half_sq[keep], minlength=n_bins)
    lag_sums = np.bincount(which[keep], weights=lags[keep], minlength=n_bins)
    ok = counts > 0
    return lag_sums[ok] / counts[ok], sums[ok] / counts[ok], counts[ok]


def fit_variogram(positions_m: np.ndarray, residual_db: np.ndarray) -> Variogram:
    """Exponential variogram with nugget, by weighted least squares over a grid of ranges."""
    lag, gamma, counts = empirical_semivariogram(positions_m, residual_db)
    total = float(np.var(residual_db))
    if lag.size < 2 or total <= 0:
        return Variogram(sill_db2=max(total, 1e-6), range_m=1.0, nugget_db2=0.0)
    w = np.sqrt(counts)
    best: tuple[float, Variogram] | None = None
    for range_m in np.geomspace(1.0, 5.0 * lag.max(), 120):
        design = np.column_stack([np.ones_like(lag), 1.0 - np.exp(-lag / range_m)])
        (nugget, sill), cost = scipy.optimize.nnls(design * w[:, None], gamma * w)
        if best is None or cost < best[0]:
            best = (cost, Variogram(float(sill), float(range_m), float(nugget)))
    assert best is not None
    vario = best[1]
    if vario.sill_db2 <= 0:  # pure nugget: no spatial structure
        return Variogram(sill_db2=1e-6, range_m=1.0, nugget_db2=max(vario.nugget_db2, 1e-6))
    return vario


def _thin(n: int, limit: int) -> np.ndarray:
    return (
        np.arange(n) if n <= limit else np.unique(np.linspace(0, n - 1, limit).round().astype(int))
    )


@dataclass(frozen=True)
class SensorSamples:
    """One sensor's measurements gathered from one or more traces.

    positions_m (S, 3), snr_db (S,) with NaN for missing samples, segment (S,) CV fold of each
    sample (contiguous segments of each trace).
    """

    positions_m: np.ndarray
    snr_db: np.ndarray
    segment: np.ndarray


def valid_mask(snr_db: np.ndarray, drop_below_db: float) -> tuple[np.ndarray, int, int]:
    """(usable mask, number missing, number of deep drops) of SNR samples."""
    missing = ~np.isfinite(snr_db)
    deep = ~missing & (snr_db < drop_below_db)
    return ~(missing | deep), int(missing.sum()), int(deep.sum())


def _fit_core(
    positions: np.ndarray, snr: np.ndarray, sensor_m: np.ndarray, variogram: Variogram | None
) -> tuple[float, float, Variogram, np.ndarray, np.ndarray]:
    intercept, exponent = fit_trend(distance_m(positions, sensor_m), snr)
    residual = snr - trend_db(positions, sensor_m, intercept, exponent)
    keep = _thin(len(snr), MAX_KRIGING_POINTS)
    if variogram is None:
        variogram = fit_variogram(positions[keep], residual[keep])
    weights = kriging_weights(positions[keep], residual[keep], variogram)
    return intercept, exponent, variogram, positions[keep], weights


def fit_sensor_map(
    name: str,
    sensor_m: np.ndarray,
    samples: SensorSamples,
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline_snr_db: np.ndarray | None = None,
    label: str = "traces",
) -> SensorMap:
    """Fit one sensor's map; ``stats`` holds counts, RMSE and cross-validated RMSE [dB].

    ``baseline_snr_db`` (S,) is a reference model's SNR at the samples (e.g. free space); its
    RMSE on the held-out segments is reported as ``cv_rmse_baseline_db``.
    """
    ok, n_missing, n_deep = valid_mask(samples.snr_db, drop_below_db)
    n_used = int(ok.sum())
    if n_used < MIN_FIT_SAMPLES:
        raise SkymuleError(
            f"{label}: sensor {name} has {n_used} valid SNR samples ({n_missing} missing, "
            f"{n_deep} deep drops below {drop_below_db:g} dB); fitting a radio map needs at "
            f"least {MIN_FIT_SAMPLES}"
        )
    positions, snr, segment = samples.positions_m[ok], samples.snr_db[ok], samples.segment[ok]
    sensor = np.asarray(sensor_m, float)
    intercept, exponent, vario, train, weights = _fit_core(positions, snr, sensor, None)
    fitted = SensorMap(name, sensor, intercept, exponent, vario, train, weights)
    errors: dict[str, list[np.ndarray]] = {"map": [], "trend": [], "baseline": []}
    for fold in np.unique(segment):
        test = segment == fold
        if test.all() or (~test).sum() < MIN_FIT_SAMPLES // 2:
            continue
        a, n, _, tr, w = _fit_core(positions[~test], snr[~test], sensor, vario)
        trend = trend_db(positions[test], sensor, a, n)
        errors["trend"].append(trend - snr[test])
        errors["map"].append(trend + krige(positions[test], tr, w, vario) - snr[test])
        if baseline_snr_db is not None:
            errors["baseline"].append(baseline_snr_db[ok][test] - snr[test])
    stats = {
        "n_used": float(n_used),
        "n_missing": float(n_missing),
        "n_deep_drops": float(n_deep),
        "rmse_db": _rmse(fitted.snr_db(positions) - snr),
        "rmse_trend_db": _rmse(fitted.trend_db(positions) - snr),
    }
    for key, values in errors.items():
        if values:
            stats[f"cv_rmse_{key}_db"] = _rmse(np.concatenate(values))
    return SensorMap(name, sensor, intercept, exponent, vario, train, weights, stats)


def _rmse(error: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(error)))) if error.size else float("nan")


@dataclass(frozen=True, eq=False)
class RadioMap:
    """Fitted maps of several sensors, in the local frame centred on ``origin`` (lat, lon)."""

    origin: tuple[float, float]
    sensors: tuple[SensorMap, ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.sensors)

    def sensor(self, name: str, label: str = "radio map") -> SensorMap:
        for sensor_map in self.sensors:
            if sensor_map.name.upper() == name.upper():
                return sensor_map
        raise ScenarioError(
            f"{label}: no map for sensor {name!r}; the map has {', '.join(self.names)}"
        )

    def source(self, names: Sequence[str], offset_m: np.ndarray | None = None) -> RadioMapSource:
        """A signal source for the named sensors, in that order."""
        offset = np.zeros(3) if offset_m is None else np.asarray(offset_m, float)
        return RadioMapSource(tuple(self.sensor(n) for n in names), offset)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": MAP_FORMAT,
            "version": MAP_VERSION,
            "origin": {"lat": self.origin[0], "lon": self.origin[1]},
            "sensors": [
                {
                    "name": s.name,
                    "position_m": s.position_m.tolist(),
                    "intercept_db": s.intercept_db,
                    "exponent": s.exponent,
                    "sill_db2": s.variogram.sill_db2,
                    "range_m": s.variogram.range_m,
                    "nugget_db2": s.variogram.nugget_db2,
                    "stats": s.stats,
                    "train_m": np.round(s.train_m, 3).tolist(),
                    "weights": s.weights.tolist(),
                }
                for s in self.sensors
            ],
        }

    def write(self, path: Path) -> None:
        path.write_text(json.dumps(self.to_dict()))


def read_radiomap(path: Path) -> RadioMap:
    """Read a map written by :meth:`RadioMap.write` (one-line SkymuleError if it is not one)."""
    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise SkymuleError(f"{path}: radio map file not found") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise SkymuleError(f"{path}: not a radio map JSON file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT:
        raise SkymuleError(
            f'{path}: not a skymule radio map (expected "format": "{MAP_FORMAT}"; '
            "make one with 'skymule fit-radiomap TRACE... --out map.json')"
        )
    try:
        sensors = tuple(
            SensorMap(
                name=s["name"],
                position_m=np.asarray(s["position_m"], float),
                intercept_db=float(s["intercept_db"]),
                exponent=float(s["exponent"]),
                variogram=Variogram(
                    float(s["sill_db2"]), float(s["range_m"]), float(s["nugget_db2"])
                ),
                train_m=np.asarray(s["train_m"], float).reshape(-1, 3),
                weights=np.asarray(s["weights"], float),
                stats={k: float(v) for k, v in s.get("stats", {}).items()},
            )
            for s in data["sensors"]
        )
        origin = (float(data["origin"]["lat"]), float(data["origin"]["lon"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise SkymuleError(f"{path}: radio map is incomplete or malformed ({exc!r})") from None
    return RadioMap(origin, sensors)


@dataclass(frozen=True, eq=False)
class RadioMapSource:
    """Signal source from a fitted map: positions (P, 3) -> SNR (P, N) [dB].

    ``offset_m`` (3,) is added to query positions to move them into the map's frame.
    """

    maps: tuple[SensorMap, ...]
    offset_m: np.ndarray

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        positions = np.atleast_2d(np.asarray(positions_m, float)) + self.offset_m
        return np.column_stack([m.snr_db(positions) for m in self.maps])


# ---------------------------------------------------------------------------
# From trace files
# ---------------------------------------------------------------------------


def load_samples(
    paths: Sequence[Path], names: Sequence[str], frame: LocalFrame, folds: int = CV_FOLDS
) -> list[SensorSamples]:
    """Per sensor (in ``names`` order), the samples of all traces (positions in ``frame``)."""
    from skymule.io.traces import positions_local, read_trace

    positions, snr, segment = [], [], []
    for path in paths:
        trace = read_trace(path, sensors=list(names))  # names a missing column in one line
        positions.append(positions_local(trace, frame.to_local))
        snr.append(trace.snr_db)
        segment.append(np.minimum(np.arange(trace.n_samples) * folds // trace.n_samples, folds - 1))
    all_pos, all_snr, all_seg = np.vstack(positions), np.vstack(snr), np.concatenate(segment)
    return [SensorSamples(all_pos, all_snr[:, j], all_seg) for j in range(len(names))]


def fit_radiomap(
    paths: Sequence[Path],
    names: Sequence[str],
    sensor_m: np.ndarray,
    frame: LocalFrame,
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline: Any = None,
) -> RadioMap:
    """Fit a map for each named sensor (antennas at ``sensor_m`` (N, 3)) to the traces.

    ``baseline`` is an optional signal source (e.g. free space) scored on the same
    cross-validation segments for comparison.
    """
    label = ", ".join(str(p) for p in paths)
    samples = load_samples(paths, names, frame)
    base = None if baseline is None else baseline.snr_db(samples[0].positions_m)
    maps = tuple(
        fit_sensor_map(
            name,
            sensor_m[j],
            samples[j],
            drop_below_db=drop_below_db,
            baseline_snr_db=None if base is None else base[:, j],
            label=label,
        )
        for j, name in enumerate(names)
    )
    return RadioMap((frame.origin_lat_deg, frame.origin_lon_deg), maps)


def frame_offset_m(map_origin: tuple[float, float], frame: LocalFrame) -> np.ndarray:
    """(3,) shift from ``frame`` coordinates to a map's frame (small-site translation)."""
    x_m, y_m = frame.to_local(map_origin[0], map_origin[1])
    return -np.array([float(x_m), float(y_m), 0.0])


def scenario_radiomap_source(
    scenario: Any, frame: LocalFrame, sensor_m: np.ndarray
) -> RadioMapSource:
    """The radio-map source of a scenario's ``[signal]`` section (fit traces or read a map)."""
    signal = scenario.signal
    names = signal.sensors_from_trace or [s.name for s in scenario.sensors]
    if len(names) != len(scenario.sensors):
        raise ScenarioError(
            f"signal.sensors_from_trace has {len(names)} names for {len(scenario.sensors)} "
            "sensors; give one trace column per sensor"
        )
    if signal.map:
        path = scenario.resolve_path(signal.map)
        fitted = read_radiomap(path)
        for name in names:
            fitted.sensor(name, label=f"signal.map = {str(path)!r}")
        return fitted.source(names, frame_offset_m(fitted.origin, frame))
    missing = [s.name for s in scenario.sensors if not s.has_position]
    if missing:
        raise ScenarioError(
            f"sensors {', '.join(missing)}: fitting a radio map needs each sensor's position"
        )
    paths = [scenario.resolve_path(p) for p in signal.traces]
    return fit_radiomap(paths, names, sensor_m, frame).source(names)


# ---------------------------------------------------------------------------
# Scoring a source against a recorded flight
# ---------------------------------------------------------------------------


def score_source(
    predicted_db: np.ndarray,
    measured_db: np.ndarray,
    names: Sequence[str],
    rate_bps: Any,
    drop_below_db: float = DEEP_DROP_DB,
) -> dict[str, dict[str, float]]:
    """Per-sensor RMSE and bias (predicted - measured) of SNR [dB] and rate [Mbit/s].

    Missing samples and deep drops of the measurement are left out and counted.
    """
    out: dict[str, dict[str, float]] = {
        k: {}
        for k in (
            "rmse_db",
            "bias_db",
            "rate_rmse_mbps",
            "rate_bias_mbps",
            "n_scored",
            "n_missing",
            "n_deep_drops",
        )
    }
    for j, name in enumerate(names):
        ok, n_missing, n_deep = valid_mask(measured_db[:, j], drop_below_db)
        error = predicted_db[ok, j] - measured_db[ok, j]
        rate_error = (rate_bps(predicted_db[ok, j]) - rate_bps(measured_db[ok, j])) / 1e6
        out["rmse_db"][name] = _rmse(error)
        out["bias_db"][name] = float(error.mean()) if error.size else float("nan")
        out["rate_rmse_mbps"][name] = _rmse(rate_error)
        out["rate_bias_mbps"][name] = float(rate_error.mean()) if error.size else float("nan")
        out["n_scored"][name] = int(ok.sum())
        out["n_missing"][name] = n_missing
        out["n_deep_drops"][name] = n_deep
    return out


def site_tower_positions_m(
    names: Sequence[str], frame: LocalFrame, site: str = "lake-wheeler"
) -> np.ndarray:
    """(N, 3) positions [m] of a built-in site's towers by name (one-line error if unknown)."""
    from skymule.geo import load_site

    towers = {p.name.upper(): p for p in load_site(site).towers}
    out = np.zeros((len(names), 3))
    for j, name in enumerate(names):
        tower = towers.get(name.upper())
        if tower is None:
            raise SkymuleError(
                f"sensor {name!r}: not a built-in {site} tower ({', '.join(sorted(towers))}); "
                "pass --scenario with the sensors' positions"
            )
        x_m, y_m = frame.to_local(tower.lat_deg, tower.lon_deg)
        out[j] = [float(x_m), float(y_m), float(tower.antenna_height_m or 0.0)]
    return out
