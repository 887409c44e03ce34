"""Ordinary kriging of SNR residuals: variograms, dense and split-kernel predictors.

The residual of a fitted radio map (measured SNR minus the log-distance trend of
:mod:`skymule.radio.radiomap`) is modelled as a zero-mean Gaussian field with an exponential
variogram; :func:`krige` predicts it at new positions. Bulk queries split the kernel: exact
weights near each sample (KD-tree, within a few correlation ranges) plus a smooth far field
interpolated from a grid (:func:`krige_split`), tested against :func:`krige_dense`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.ndimage
import scipy.optimize
import scipy.spatial
import scipy.spatial.distance
from threadpoolctl import threadpool_limits

MAX_KRIGING_POINTS = 1000
"""Largest number of samples per sensor in the kriging system (thinned evenly beyond it)."""


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


SHORTEST_RANGE_M = 1.0
"""The shortest correlation range :func:`fit_variogram` tries [m]; a fit that ends there (or
with a sill of :data:`NO_SILL_DB2`) found no spatial structure to krige."""

NO_SILL_DB2 = 1e-6
"""The sill [dB^2] :func:`fit_variogram` gives a residual without spatial structure."""


def fit_variogram(positions_m: np.ndarray, residual_db: np.ndarray) -> Variogram:
    """Exponential variogram with nugget, by weighted least squares over a grid of ranges."""
    lag, gamma, counts = empirical_semivariogram(positions_m, residual_db)
    total = float(np.var(residual_db))
    if lag.size < 2 or total <= 0:
        return Variogram(sill_db2=max(total, NO_SILL_DB2), range_m=SHORTEST_RANGE_M, nugget_db2=0.0)
    w = np.sqrt(counts)
    best: tuple[float, Variogram] | None = None
    for range_m in np.geomspace(SHORTEST_RANGE_M, 5.0 * lag.max(), 120):
        design = np.column_stack([np.ones_like(lag), 1.0 - np.exp(-lag / range_m)])
        (nugget, sill), cost = scipy.optimize.nnls(design * w[:, None], gamma * w)
        if best is None or cost < best[0]:
            best = (cost, Variogram(float(sill), float(range_m), float(nugget)))
    assert best is not None
    vario = best[1]
    if vario.sill_db2 <= 0:  # pure nugget: no spatial structure
        nugget = max(vario.nugget_db2, NO_SILL_DB2)
        return Variogram(sill_db2=NO_SILL_DB2, range_m=SHORTEST_RANGE_M, nugget_db2=nugget)
    return vario


MAX_LIKELIHOOD_POINTS = 500
"""Samples (thinned evenly) in the marginal likelihood of :func:`fit_variogram_ml`."""


def log_marginal_likelihood(
    distances_m: np.ndarray, residual_db: np.ndarray, variogram: Variogram
) -> float:
    """log p(r) of residuals under the zero-mean Gaussian field (R&W 2006, eq. 2.30).

    ``distances_m`` (S, S) between the samples; covariance sigma^2 exp(-h / L) + tau^2 I.
    """
    k = variogram.covariance(distances_m)
    k[np.diag_indices_from(k)] += variogram.nugget_db2 + 1e-9
    try:
        factor = scipy.linalg.cho_factor(k, lower=True)
    except np.linalg.LinAlgError:
        return -np.inf
    alpha = scipy.linalg.cho_solve(factor, residual_db)
    log_det = 2.0 * np.log(np.diag(factor[0])).sum()
    return float(
        -0.5 * residual_db @ alpha - 0.5 * log_det - 0.5 * len(residual_db) * np.log(2 * np.pi)
    )


ML_RESTARTS = 2
"""Extra seeded random starts of the likelihood optimiser in :func:`fit_variogram_ml`."""


def fit_variogram_ml(
    positions_m: np.ndarray, residual_db: np.ndarray, start: Variogram
) -> Variogram:
    """Exponential covariance + nugget maximising the marginal likelihood (GP regression).

    scikit-learn's GaussianProcessRegressor optimises log (sigma^2, L, tau^2) of
    ConstantKernel x Matern(nu = 1/2) (the exponential kernel) + WhiteKernel by L-BFGS from
    ``start`` (e.g. the variogram fit) and ``ML_RESTARTS`` seeded random starts, on at most
    MAX_LIKELIHOOD_POINTS samples thinned evenly in time; the start is kept if it is as
    likely. (It replaced a hand-written Nelder-Mead search: on 12 tower-worlds of
    benchmarks/bench_sim2real.py it reached a higher likelihood and a lower held-out RMSE,
    docs/channels.md.)
    """
    import warnings

    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    keep = thin_indices(len(residual_db), MAX_LIKELIHOOD_POINTS)
    points, residual = positions_m[keep], residual_db[keep]
    scale = max(float(np.var(residual)), 1e-6)
    bounds = (1e-6 * scale, 1e3 * scale)
    kernel = ConstantKernel(float(np.clip(start.sill_db2, *bounds)), bounds) * Matern(
        float(np.clip(start.range_m, SHORTEST_RANGE_M, 1e5)), (SHORTEST_RANGE_M, 1e5), nu=0.5
    ) + WhiteKernel(float(np.clip(start.nugget_db2, *bounds)), bounds)
    model = GaussianProcessRegressor(
        kernel, alpha=1e-9, n_restarts_optimizer=ML_RESTARTS, random_state=0
    )
    with threadpool_limits(limits=1, user_api="blas"), warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a bound reached is an answer, not a failure
        model.fit(points, residual)
    fitted = model.kernel_
    found = Variogram(
        float(fitted.k1.k1.constant_value),
        float(fitted.k1.k2.length_scale),
        float(fitted.k2.noise_level),
    )
    distances = pairwise_m(points, points)
    if log_marginal_likelihood(distances, residual, found) < log_marginal_likelihood(
        distances, residual, start
    ):
        return start
    return found


def thin_indices(n: int, limit: int) -> np.ndarray:
    return (
        np.arange(n) if n <= limit else np.unique(np.linspace(0, n - 1, limit).round().astype(int))
    )
