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

Methods (``fit-radiomap --method``): ``kriging`` (1-3 above, the default), ``log-distance``
(the trend alone), ``gp`` (the same model with the residual field's parameters chosen by
maximum marginal likelihood, Rasmussen & Williams eq. 5.8, instead of the variogram) and
``neural`` (:mod:`skymule.radio.learned`: the prior, a digital twin, as an offset with a bias
linear in log-distance, plus guarded networks on link features; or, when blocked
cross-validation says the networks do not beat them, the simpler model alone: prior +
correction, log-distance or free space; what is left is kriged as above). With a prior, the
map holds the prior too (a fitted map, or a path-loss model and link budget). Every map gives
a predictive standard deviation per point (:meth:`RadioMapSource.sigma_db`): the kriging
posterior variance sigma^2 + tau^2 - k^T (K + tau^2 I)^{-1} k (R&W eq. 2.26; the trend's
residual variance for ``log-distance``) plus the learned base's for ``neural``, scaled so the
cross-validation's 95% intervals hold 95% of its held-out samples.

Missing samples (NaN; -99 in digital-twin exports) and deep drops (below ``drop_below_db``,
real but unpredictable link losses) are excluded and counted. At most ``MAX_KRIGING_POINTS``
samples per sensor (evenly thinned in time) enter the kriging system. Fit quality: in-sample
RMSE and one blocked cross-validation for every method (:func:`blocked_folds`): each fold
holds out one contiguous segment of every trace and trains on the samples farther than
``CV_BUFFER_M`` from it, so it scores extrapolation to a region the rest does not cover.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from skymule.errors import ScenarioError, SkymuleError
from skymule.geo import LocalFrame
from skymule.io import atomic
from skymule.io.textfiles import parse_json
from skymule.radio.kriging import (
    MAX_KRIGING_POINTS,
    Variogram,
    fit_variogram,
    fit_variogram_ml,
    krige,
    kriging_weights,
    pairwise_m,
    thin_indices,
)
from skymule.radio.learned import (
    CV_MEMBERS,
    ENSEMBLE_SIZE,
    LearnedModel,
    fit_learned,
)
from skymule.radio.mapcheck import map_problem
from skymule.radio.pathloss import MIN_DISTANCE_M

DEEP_DROP_DB = -40.0
"""SNR samples below this [dB] are deep drops (link losses): excluded from fits and scores."""

MIN_FIT_SAMPLES = 20
"""A sensor needs at least this many valid samples to fit its map."""


CV_FOLDS = 5
"""Cross-validation folds (contiguous segments of each trace)."""

CV_BUFFER_M = 50.0
"""Blocked cross-validation: samples within this distance [m] of a held-out segment are left
out of its training set too, so each fold predicts a region the rest does not cover."""

SELECTION_MARGIN_DB = 0.1
"""``neural`` keeps a more flexible model (networks > log-distance > prior + correction > free
space) only when its cross-validated RMSE beats the simpler one's by more than this [dB] (and
by more than one standard error: :func:`_choose`)."""

CV_KRIGING_POINTS = 400
"""Samples per fold in the kriging system of cross-validation (thinned evenly): a held-out
block lies beyond most of the field's reach, and the folds cost 5 x the candidates' fits."""

COVERAGE_Z = 1.959964
"""Half-width of the central 95% interval of a standard normal."""


MAP_FORMAT = "skymule-radiomap"
MAP_VERSION = 2
"""Version 2 adds ``method``, ``prior`` and each sensor's ``ensemble``; version 1 files
(kriging maps) are read as they are."""

Method = Literal["kriging", "log-distance", "gp", "neural"]
METHODS: tuple[Method, ...] = ("kriging", "log-distance", "gp", "neural")
"""The fitting methods of :func:`fit_radiomap` (``skymule fit-radiomap --method``)."""


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
        ensemble: ``neural``: the learned base the residual is kriged over (the prior and
            its correction, the networks, or the trend: :class:`LearnedModel`); None
            otherwise. ``stats["sigma_scale"]`` (when present) scales the predictive SD so
            the blocked cross-validation's 95% intervals cover 95% of held-out samples.
    """

    name: str
    position_m: np.ndarray
    intercept_db: float
    exponent: float
    variogram: Variogram
    train_m: np.ndarray
    weights: np.ndarray
    stats: dict[str, float] = field(default_factory=dict)
    ensemble: LearnedModel | None = None

    def trend_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P,) log-distance trend [dB] at positions (P, 3)."""
        return trend_db(positions_m, self.position_m, self.intercept_db, self.exponent)

    def _learned(self, prior_db: np.ndarray | None) -> LearnedModel:
        assert self.ensemble is not None
        if self.ensemble.needs_prior() and prior_db is None:
            raise SkymuleError(f"radio map of {self.name}: the learned map needs its prior")
        return self.ensemble

    def base_db(self, positions_m: np.ndarray, prior_db: np.ndarray | None = None) -> np.ndarray:
        """(P,) what the kriged residual is added to [dB]: the trend, or for ``neural`` the
        learned base (:meth:`LearnedModel.mean_db`)."""
        positions = np.atleast_2d(np.asarray(positions_m, float))
        if self.ensemble is None:
            return self.trend_db(positions)
        return self._learned(prior_db).mean_db(positions, self.position_m, prior_db)

    def snr_db(self, positions_m: np.ndarray, prior_db: np.ndarray | None = None) -> np.ndarray:
        """(P,) predicted SNR [dB] at positions (P, 3): base + kriged residual.

        ``prior_db`` (P,) is the prior's SNR at the positions (maps fitted with a prior only).
        """
        positions = np.atleast_2d(np.asarray(positions_m, float))
        return self.base_db(positions, prior_db) + krige(
            positions, self.train_m, self.weights, self.variogram
        )

    @functools.cached_property
    def _cholesky(self) -> tuple[np.ndarray, bool]:
        k = self.variogram.covariance(pairwise_m(self.train_m, self.train_m))
        k[np.diag_indices_from(k)] += (
            self.variogram.nugget_db2 + 1e-6 * self.variogram.sill_db2 + 1e-9
        )
        factor: tuple[np.ndarray, bool] = scipy.linalg.cho_factor(k, lower=True)
        return factor

    def sigma_db(self, positions_m: np.ndarray, prior_db: np.ndarray | None = None) -> np.ndarray:
        """(P,) predictive standard deviation [dB] at positions (P, 3).

        The kriging posterior variance sigma^2 + tau^2 - k^T (K + tau^2 I)^{-1} k, plus for
        ``neural`` the learned base's variance; times ``stats["sigma_scale"]`` if fitted.
        """
        positions = np.atleast_2d(np.asarray(positions_m, float))
        vario = self.variogram
        variance = np.full(len(positions), vario.sill_db2 + vario.nugget_db2)
        if self.train_m.shape[0]:
            step = max(1, 2_000_000 // self.train_m.shape[0])
            for start in range(0, len(positions), step):
                k = vario.covariance(pairwise_m(positions[start : start + step], self.train_m))
                solved = scipy.linalg.cho_solve(self._cholesky, k.T)
                variance[start : start + step] -= np.einsum("ps,sp->p", k, solved)
        variance = np.maximum(variance, vario.nugget_db2)
        if self.ensemble is not None:
            learned = self._learned(prior_db)
            variance = variance + learned.variance_db2(positions, self.position_m, prior_db)
        return float(self.stats.get("sigma_scale", 1.0)) * np.sqrt(variance)


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


@dataclass(frozen=True)
class FitOptions:
    """How :func:`fit_sensor_map` fits: the method and, for ``neural``, its seed."""

    method: Method = "kriging"
    seed: int = 0


def _free_space_line(
    positions: np.ndarray, sensor_m: np.ndarray, baseline_db: np.ndarray | None
) -> tuple[float, float] | None:
    """(A, n) when the baseline is exactly a log-distance law at these samples (free space is:
    A - 20 log10 d), so a map can be it; None otherwise."""
    if baseline_db is None:
        return None
    distance = distance_m(positions, sensor_m)
    intercept, exponent = fit_trend(distance, baseline_db)
    line = trend_db(positions, sensor_m, intercept, exponent)
    return (intercept, exponent) if _rmse(line - baseline_db) < 0.01 else None


def _candidates(method: str, prior_db: np.ndarray | None, free_space: bool) -> tuple[str, ...]:
    """What blocked cross-validation compares for ``method`` (``neural``: the networks and
    their fallbacks, :data:`skymule.radio.learned.CHOICES`), from the most flexible to the
    simplest (free space fits nothing; the prior + correction fits a shrunk bias)."""
    if method != "neural":
        return (method,)
    simpler = ("log-distance", "prior + correction") if prior_db is not None else ("log-distance",)
    return ("network", *simpler, *(("free space",) if free_space else ()))


def _fit_core(
    name: str,
    positions: np.ndarray,
    snr: np.ndarray,
    sensor_m: np.ndarray,
    variogram: Variogram | None,
    method: str,
    prior_db: np.ndarray | None,
    *,
    choice: str = "network",
    seed: int = 0,
    members: int = ENSEMBLE_SIZE,
    free_space: tuple[float, float] | None = None,
    max_points: int = MAX_KRIGING_POINTS,
) -> SensorMap:
    """The map of one sensor fitted to valid samples (``variogram`` kept when given).

    ``neural``: the learned base of ``choice``, then the kriged residual; ``free space`` is
    the line ``free_space`` (A, n) alone (a zero-mean field kriged over a biased line would
    pull predictions toward the bias near the data and drop it far away).
    """
    intercept, exponent = fit_trend(distance_m(positions, sensor_m), snr)
    ensemble = None
    if method == "neural":
        ensemble = fit_learned(
            positions, snr, sensor_m, prior_db, choice, seed=seed, members=members,
            line=free_space,
        )  # fmt: skip
        base = ensemble.mean_db(positions, sensor_m, prior_db)
    else:
        base = trend_db(positions, sensor_m, intercept, exponent)
    residual = snr - base
    if method == "log-distance" or choice == "free space":  # nothing kriged: the line alone
        no_field = Variogram(0.0, 1.0, float(np.mean(residual**2)))
        empty = np.zeros((0, 3))
        return SensorMap(
            name, sensor_m, intercept, exponent, no_field, empty, np.zeros(0), {}, ensemble
        )
    keep = thin_indices(len(snr), max_points)
    if variogram is None:
        variogram = fit_variogram(positions[keep], residual[keep])
        if method == "gp":
            variogram = fit_variogram_ml(positions[keep], residual[keep], variogram)
    weights = kriging_weights(positions[keep], residual[keep], variogram)
    return SensorMap(
        name, sensor_m, intercept, exponent, variogram, positions[keep], weights, {}, ensemble
    )


def blocked_folds(
    positions_m: np.ndarray, segment: np.ndarray, buffer_m: float = CV_BUFFER_M
) -> list[tuple[np.ndarray, np.ndarray]]:
    """(test, train) masks of the blocked cross-validation shared by every method.

    Fold k holds out segment k of every trace (a contiguous stretch of flight); its training
    set is every other sample farther than ``buffer_m`` from all held-out ones, so the fold
    predicts a region the rest does not cover (buffered block CV: Roberts et al., Ecography
    40, 2017). Folds left with too few training samples are skipped.
    """
    import scipy.spatial

    folds = []
    for fold in np.unique(segment):
        test = segment == fold
        if test.all():
            continue
        train = ~test
        gap, _ = scipy.spatial.cKDTree(positions_m[test]).query(positions_m[train])
        train[train] = gap > buffer_m
        if train.sum() >= MIN_FIT_SAMPLES // 2:
            folds.append((test, train))
    return folds


def _choose(candidates: tuple[str, ...], fold_errors: dict[str, list[np.ndarray]]) -> str:
    """The candidate kept, from the simplest up (``candidates`` run from the most flexible to
    the simplest): a more flexible one replaces the current choice only if its blocked
    cross-validated RMSE is lower by more than SELECTION_MARGIN_DB *and* its mean squared
    error per fold is lower by more than one standard error of the paired fold differences
    (the one-standard-error rule, Hastie, Tibshirani & Friedman, *The Elements of
    Statistical Learning*, 2nd ed., sec. 7.10)."""
    scored = [c for c in reversed(candidates) if fold_errors.get(c)]
    if not scored:
        return candidates[-1]
    chosen = scored[0]
    for challenger in scored[1:]:
        ours, theirs = fold_errors[chosen], fold_errors[challenger]
        gain = np.array([np.mean(a**2) - np.mean(b**2) for a, b in zip(ours, theirs, strict=True)])
        se = float(gain.std(ddof=1) / np.sqrt(gain.size)) if gain.size > 1 else 0.0
        margin = _rmse(np.concatenate(ours)) - _rmse(np.concatenate(theirs))
        if margin > SELECTION_MARGIN_DB and gain.mean() > se:
            chosen = challenger
    return chosen


def sigma_scale(z: np.ndarray) -> float:
    """Factor on the predictive SD making the central 95% interval hold 95% of the held-out
    standardised errors ``z`` (error / sigma) of cross-validation (1 without any)."""
    z = np.abs(z[np.isfinite(z)])
    if z.size < MIN_FIT_SAMPLES:
        return 1.0
    return float(np.clip(np.quantile(z, 0.95) / COVERAGE_Z, 0.5, 20.0))


def fit_sensor_map(
    name: str,
    sensor_m: np.ndarray,
    samples: SensorSamples,
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline_snr_db: np.ndarray | None = None,
    prior_snr_db: np.ndarray | None = None,
    options: FitOptions = FitOptions(),
    label: str = "traces",
) -> SensorMap:
    """Fit one sensor's map; ``stats`` holds counts, RMSE and cross-validated RMSE [dB].

    Every method is cross-validated the same way (:func:`blocked_folds`): ``cv_rmse_map_db``
    is the map's RMSE on held-out blocks, next to ``cv_rmse_trend_db`` (log-distance fitted
    on the same training sets), ``cv_rmse_baseline_db`` (``baseline_snr_db`` (S,), a
    reference model's SNR at the samples, e.g. free space) and ``cv_rmse_prior_db`` (the raw
    prior). ``cv_coverage_95`` is the share of held-out samples inside the map's 95%
    interval once ``sigma_scale`` (fitted on the same errors) is applied.

    ``neural`` (``prior_snr_db`` (S,): the prior's SNR at the samples, optional) compares
    its networks with the simpler models on these folds (``cv_rmse_<choice>_db``) and keeps
    the networks only if they win (:func:`_choose`); the map's ``ensemble.choice`` says
    which model it is.
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
    prior = None if prior_snr_db is None else np.asarray(prior_snr_db, float)[ok]
    base_db = None if baseline_snr_db is None else np.asarray(baseline_snr_db, float)[ok]
    sensor = np.asarray(sensor_m, float)
    method = options.method
    line = _free_space_line(positions, sensor, base_db) if method == "neural" else None
    candidates = _candidates(method, prior, line is not None)
    # gp keeps its maximum-likelihood parameters across folds (refitting them is the cost)
    kept = (
        _fit_core(name, positions, snr, sensor, None, method, prior).variogram
        if method == "gp"
        else None
    )
    errors: dict[str, list[np.ndarray]] = {k: [] for k in ("trend", "baseline", "prior")}
    errors.update({c: [] for c in candidates})
    z: dict[str, list[np.ndarray]] = {c: [] for c in candidates}
    with threadpool_limits(limits=1, user_api="blas"):  # small systems: one thread
        for test, train in blocked_folds(positions, segment):
            train_prior = None if prior is None else prior[train]
            test_prior = None if prior is None else prior[test]
            for choice in candidates:
                held = _fit_core(
                    name, positions[train], snr[train], sensor, kept, method, train_prior,
                    choice=choice, seed=options.seed, members=CV_MEMBERS, free_space=line,
                    max_points=CV_KRIGING_POINTS,
                )  # fmt: skip
                error = held.snr_db(positions[test], test_prior) - snr[test]
                errors[choice].append(error)
                z[choice].append(error / held.sigma_db(positions[test], test_prior))
            trend = fit_trend(distance_m(positions[train], sensor), snr[train])
            errors["trend"].append(trend_db(positions[test], sensor, *trend) - snr[test])
            if base_db is not None:
                errors["baseline"].append(base_db[test] - snr[test])
            if prior is not None:
                errors["prior"].append(prior[test] - snr[test])
    cv = {k: _rmse(np.concatenate(v)) if v else float("nan") for k, v in errors.items()}
    chosen = _choose(candidates, errors)
    fitted = _fit_core(
        name, positions, snr, sensor, kept, method, prior,
        choice=chosen, seed=options.seed, free_space=line,
    )  # fmt: skip
    scale = sigma_scale(np.concatenate(z[chosen])) if z[chosen] else 1.0
    stats = {
        "n_used": float(n_used),
        "n_missing": float(n_missing),
        "n_deep_drops": float(n_deep),
        "rmse_db": _rmse(fitted.snr_db(positions, prior) - snr),
        "rmse_trend_db": _rmse(fitted.trend_db(positions) - snr),
        "cv_folds": float(len(errors["trend"])),
        "sigma_scale": scale,
    }
    if z[chosen]:
        inside = np.abs(np.concatenate(z[chosen])) <= COVERAGE_Z * scale
        stats["cv_coverage_95"] = float(inside.mean())
    stats["cv_rmse_map_db"] = cv[chosen]
    for key in ("trend", "baseline", "prior"):
        if np.isfinite(cv[key]):
            stats[f"cv_rmse_{key}_db"] = cv[key]
    if method == "neural":
        for choice in candidates:
            stats[f"cv_rmse_{choice.replace(' + ', '_').replace(' ', '_')}_db"] = cv[choice]
    return replace(fitted, stats=stats)


def _rmse(error: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(error)))) if error.size else float("nan")


class Prior(Protocol):
    """What a learned map calibrates: a signal source for named sensors, stored in the map."""

    @property
    def label(self) -> str: ...

    def source(self, names: Sequence[str]) -> Any: ...

    def to_dict(self) -> dict[str, Any]: ...


@dataclass(frozen=True, eq=False)
class MapPrior:
    """A fitted map as the prior; ``offset_m`` (3,) moves this map's frame into its frame."""

    fitted: RadioMap
    offset_m: np.ndarray
    label: str

    def source(self, names: Sequence[str]) -> RadioMapSource:
        return self.fitted.source(names, self.offset_m)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "radiomap",
            "label": self.label,
            "offset_m": self.offset_m.tolist(),
            "map": self.fitted.to_dict(),
        }


@dataclass(frozen=True, eq=False)
class ModelPrior:
    """A path-loss model and link budget as the prior (a scenario's ``[radio]`` without its
    random shadowing: a draw is not a prediction), sensors at ``sensor_m`` in this map's frame.
    """

    radio: dict[str, Any]
    sensor_m: dict[str, tuple[float, float, float]]
    label: str

    def source(self, names: Sequence[str]) -> Any:
        from skymule.radio.sources import model_source
        from skymule.scenario import RadioSpec

        missing = [n for n in names if n.upper() not in self.sensor_m]
        if missing:
            raise SkymuleError(f"prior {self.label}: no sensor {missing[0]!r}")
        spec = RadioSpec.model_validate({**self.radio, "shadowing_std_db": 0.0})
        return model_source(spec, np.array([self.sensor_m[n.upper()] for n in names], float))

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "model",
            "label": self.label,
            "radio": self.radio,
            "sensor_m": {k: list(v) for k, v in self.sensor_m.items()},
        }


@dataclass(frozen=True, eq=False)
class RadioMap:
    """Fitted maps of several sensors, in the local frame centred on ``origin`` (lat, lon).

    ``method`` is how it was fitted (:data:`METHODS`); ``prior`` the source a ``neural`` map
    learned its residual over (None: the log-distance trend).
    """

    origin: tuple[float, float]
    sensors: tuple[SensorMap, ...]
    method: str = "kriging"
    prior: Prior | None = None

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
        maps = tuple(self.sensor(n) for n in names)
        prior = None if self.prior is None else self.prior.source([m.name for m in maps])
        return RadioMapSource(maps, offset, prior)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": MAP_FORMAT,
            "version": MAP_VERSION,
            "method": self.method,
            "origin": {"lat": self.origin[0], "lon": self.origin[1]},
            "prior": None if self.prior is None else self.prior.to_dict(),
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
                    "ensemble": None if s.ensemble is None else s.ensemble.to_dict(),
                }
                for s in self.sensors
            ],
        }

    def write(self, path: Path) -> None:
        """Write the map as JSON, atomically (:mod:`skymule.io.atomic`)."""
        atomic.write_text(Path(path), json.dumps(self.to_dict()))


def _map_from_dict(data: dict[str, Any]) -> RadioMap:
    """The map of a parsed JSON document (KeyError/TypeError/ValueError when malformed)."""
    sensors = tuple(
        SensorMap(
            name=s["name"],
            position_m=np.asarray(s["position_m"], float),
            intercept_db=float(s["intercept_db"]),
            exponent=float(s["exponent"]),
            variogram=Variogram(float(s["sill_db2"]), float(s["range_m"]), float(s["nugget_db2"])),
            train_m=np.asarray(s["train_m"], float).reshape(-1, 3),
            weights=np.asarray(s["weights"], float),
            stats={k: float(v) for k, v in s.get("stats", {}).items()},
            ensemble=LearnedModel.from_dict(s["ensemble"]) if s.get("ensemble") else None,
        )
        for s in data["sensors"]
    )
    origin = (float(data["origin"]["lat"]), float(data["origin"]["lon"]))
    method = str(data.get("method", "kriging"))
    if method not in METHODS:
        raise ValueError(f"method {method!r} is not one of {', '.join(METHODS)}")
    prior: Prior | None = None
    spec = data.get("prior")
    if spec:
        if spec["kind"] == "radiomap":
            offset = np.asarray(spec["offset_m"], float).reshape(3)
            prior = MapPrior(_map_from_dict(spec["map"]), offset, str(spec["label"]))
        elif spec["kind"] == "model":
            positions = {
                str(k).upper(): (float(v[0]), float(v[1]), float(v[2]))
                for k, v in spec["sensor_m"].items()
            }
            prior = ModelPrior(dict(spec["radio"]), positions, str(spec["label"]))
        else:
            raise ValueError(f"prior kind {spec['kind']!r} is not radiomap or model")
    return RadioMap(origin, sensors, method, prior)


def read_radiomap(path: Path) -> RadioMap:
    """Read a map written by :meth:`RadioMap.write` (one-line SkymuleError if it is not one)."""
    try:
        data = parse_json(Path(path).read_text())
    except FileNotFoundError:
        raise SkymuleError(f"{path}: radio map file not found") from None
    except (OSError, ValueError) as exc:
        raise SkymuleError(f"{path}: not a radio map JSON file ({exc})") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT:
        raise SkymuleError(
            f'{path}: not a skymule radio map (expected "format": "{MAP_FORMAT}"; '
            "make one with 'skymule fit-radiomap TRACE... --out map.json')"
        )
    version = data.get("version")
    if version not in (1, MAP_VERSION):
        raise SkymuleError(
            f"{path}: radio map version {version!r}; this skymule reads versions 1 and "
            f"{MAP_VERSION} (refit it with 'skymule fit-radiomap')"
        )
    try:
        radio_map = _map_from_dict(data)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError, RecursionError) as exc:
        raise SkymuleError(f"{path}: radio map is incomplete or malformed ({exc!r})") from None
    problem = map_problem(radio_map)  # values checked before any is used (issue 32)
    if problem:
        raise SkymuleError(f"{path}: radio map {problem}")
    return radio_map


@dataclass(frozen=True, eq=False)
class RadioMapSource:
    """Signal source from a fitted map: positions (P, 3) -> SNR (P, N) [dB].

    ``offset_m`` (3,) is added to query positions to move them into the map's frame;
    ``prior`` is the prior's source for the same sensors (learned maps with a prior).
    """

    maps: tuple[SensorMap, ...]
    offset_m: np.ndarray
    prior: Any = None

    def _per_sensor(self, positions_m: np.ndarray, what: str) -> np.ndarray:
        """(P, N) ``SensorMap.<what>`` of every sensor, with the prior's SNR when there is one."""
        positions = np.atleast_2d(np.asarray(positions_m, float)) + self.offset_m
        prior = None if self.prior is None else np.asarray(self.prior.snr_db(positions))
        return np.column_stack(
            [getattr(m, what)(positions, None if prior is None else prior[:, j])
             for j, m in enumerate(self.maps)]
        )  # fmt: skip

    def snr_db(self, positions_m: np.ndarray) -> np.ndarray:
        return self._per_sensor(positions_m, "snr_db")

    def sigma_db(self, positions_m: np.ndarray) -> np.ndarray:
        """(P, N) predictive standard deviation [dB] (:meth:`SensorMap.sigma_db`)."""
        return self._per_sensor(positions_m, "sigma_db")


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
    options: FitOptions = FitOptions(),
    prior: Prior | None = None,
) -> RadioMap:
    """Fit a map for each named sensor (antennas at ``sensor_m`` (N, 3)) to the traces.

    ``baseline`` is an optional signal source (e.g. free space) scored on the same
    cross-validation segments for comparison; ``prior`` the source a ``neural`` map learns
    its residual over.
    """
    label = ", ".join(str(p) for p in paths)
    samples = load_samples(paths, names, frame)
    return fit_samples(
        samples,
        names,
        sensor_m,
        (frame.origin_lat_deg, frame.origin_lon_deg),
        drop_below_db=drop_below_db,
        baseline=baseline,
        options=options,
        prior=prior,
        label=label,
    )


def fit_samples(
    samples: Sequence[SensorSamples],
    names: Sequence[str],
    sensor_m: np.ndarray,
    origin: tuple[float, float],
    *,
    drop_below_db: float = DEEP_DROP_DB,
    baseline: Any = None,
    options: FitOptions = FitOptions(),
    prior: Prior | None = None,
    label: str = "samples",
) -> RadioMap:
    """:func:`fit_radiomap` on samples already gathered (one :class:`SensorSamples` a name),
    positions in the frame of ``origin`` (lat, lon)."""
    if prior is not None and options.method != "neural":
        raise ValueError(f"a prior needs the neural method, not {options.method!r}")
    positions = samples[0].positions_m
    base = None if baseline is None else baseline.snr_db(positions)
    prior_db = None if prior is None else np.asarray(prior.source(list(names)).snr_db(positions))
    maps = tuple(
        fit_sensor_map(
            name,
            sensor_m[j],
            samples[j],
            drop_below_db=drop_below_db,
            baseline_snr_db=None if base is None else base[:, j],
            prior_snr_db=None if prior_db is None else prior_db[:, j],
            options=options,
            label=label,
        )
        for j, name in enumerate(names)
    )
    return RadioMap(origin, maps, options.method, prior)


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
    """Per-sensor RMSE, bias (predicted - measured) and MAE of SNR [dB]; RMSE and bias of
    the rate [Mbit/s].

    Missing samples and deep drops of the measurement are left out and counted.
    """
    out: dict[str, dict[str, float]] = {
        k: {}
        for k in (
            "rmse_db",
            "bias_db",
            "mae_db",
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
        out["mae_db"][name] = float(np.abs(error).mean()) if error.size else float("nan")
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
