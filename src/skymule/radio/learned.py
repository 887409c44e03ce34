"""A learned radio map: a baseline corrected by an ensemble of small networks, kept honest.

Per sensor, the learned twin predicts SNR at a UAV position as

    baseline + trust * network correction        (+ the kriged residual, radiomap.py)

* **Baseline.** With a prior (a digital twin), the prior's SNR *as an offset* plus a bias
  linear in log-distance, c0 + c1 log10(d): the calibration the seen flight supports
  (Bayesian linear regression, a Gaussian prior of ``SLOPE_PRIOR_DB`` on the slope, so a seen
  part that spans little distance gives a bias close to constant and a slope whose posterior
  variance grows away from the seen distances; Bishop, *Pattern Recognition and Machine
  Learning*, 2006, eq. 3.53-3.59). Without a prior, the same regression on SNR itself: the
  log-distance trend.
* **Network correction.** An ensemble of ``ENSEMBLE_SIZE`` multilayer perceptrons
  (scikit-learn's ``MLPRegressor``: one tanh layer, L-BFGS, L2 decay, seeded) learns the
  residual over the baseline from where the UAV is *as the link sees it* (Zeng et al.'s and
  the AERPAW radio-map studies' inputs, not raw x/y): log10 distance, elevation, the azimuth's
  sine and cosine, height, and the prior's SNR only when it is not redundant with
  log-distance (|r| < ``PRIOR_REDUNDANT_R``). Deep-ensemble spread (Lakshminarayanan et al.,
  NeurIPS 2017) is its model uncertainty.
* **Extrapolation guard.** Inputs are standardised on the seen spread, floored per feature
  (``FEATURE_FLOORS``: a seen altitude spread of 0.12 m does not make 30 m "250 SD"), and
  clipped to the seen range before the networks see them: a network is never evaluated
  outside what it was fitted on. How far a point lies outside the seen range (the largest
  excess over the features, in floored SDs) sets a trust t = exp(-excess^2 / 2 w^2), w =
  ``GUARD_WIDTH_SD``: the correction is t times the networks', and the predictive variance
  is that of the mixture "network with weight t, baseline with weight 1 - t": t var_members +
  (1 - t) v_fallback + t (1 - t) m^2, v_fallback the mean squared correction on the seen data
  (what the networks explained there, unexplained where they are not trusted).

Which of these the map keeps (network, prior + correction, or log-distance) is chosen by the
blocked cross-validation of :func:`skymule.radio.radiomap.fit_sensor_map`, shared with every
method: the fitted map IS the simpler model when the networks do not beat it.

Everything is plain numbers (written to the map JSON, read back without running code from the
file); the networks are evaluated here in numpy from their weights.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from skymule.radio.pathloss import MIN_DISTANCE_M

HIDDEN_UNITS = (32,)
"""Hidden layer widths of each network."""

ENSEMBLE_SIZE = 5
"""Networks in the fitted ensemble."""

CV_MEMBERS = 3
"""Networks per ensemble inside cross-validation (the fold fits only score the candidate)."""

L2_PENALTY = 1.0
"""Weight decay, relative to the standardised mean squared error per sample and weight (the
scale of the hand-written fit this replaced; ``alpha`` = this x samples / weights)."""

MAX_ITERATIONS = 300
"""L-BFGS iterations per network."""

FEATURES = ("log10_distance", "elevation_rad", "sin_azimuth", "cos_azimuth", "height_m")
"""Input features without a prior; ``prior_db`` is appended when the prior is not redundant."""

PRIOR_FEATURE = "prior_db"

FEATURE_FLOORS = {
    "log10_distance": 0.05,
    "elevation_rad": 0.035,
    "sin_azimuth": 0.1,
    "cos_azimuth": 0.1,
    "height_m": 2.0,
    PRIOR_FEATURE: 1.0,
}
"""Smallest scale of each feature for standardisation and the guard (12% in distance, 2 deg
of elevation, 0.1 in sine/cosine, 2 m of height, 1 dB of prior)."""

GUARD_WIDTH_SD = 1.0
"""Width of the trust's fall-off beyond the seen range, in floored SDs (2 SD out: t = 0.14)."""

PRIOR_REDUNDANT_R = 0.95
"""The prior's SNR is an input only when |corr(prior, log10 d)| on the seen data is below."""

SLOPE_PRIOR_DB = 10.0
"""Prior SD of the correction's slope [dB per decade of distance] when there is a prior."""

TREND_PRIOR_DB = 1000.0
"""Prior SD of the coefficients without a prior (the log-distance trend: least squares)."""


def link_features(
    positions_m: np.ndarray, sensor_m: np.ndarray, prior_db: np.ndarray | None = None
) -> np.ndarray:
    """(P, F) features of UAV positions (P, 3) for a sensor at ``sensor_m`` (3,).

    Columns: :data:`FEATURES`, then the prior's SNR [dB] when ``prior_db`` (P,) is given.
    """
    positions = np.atleast_2d(np.asarray(positions_m, float))
    delta = positions - np.asarray(sensor_m, float)
    horizontal = np.hypot(delta[:, 0], delta[:, 1])
    distance = np.maximum(np.hypot(horizontal, delta[:, 2]), MIN_DISTANCE_M)
    azimuth = np.arctan2(delta[:, 1], delta[:, 0])
    columns = [
        np.log10(distance),
        np.arctan2(delta[:, 2], horizontal),
        np.sin(azimuth),
        np.cos(azimuth),
        positions[:, 2],
    ]
    if prior_db is not None:
        columns.append(np.asarray(prior_db, float))
    return np.column_stack(columns)


# ---------------------------------------------------------------------------
# The baseline's correction: a bias linear in log-distance
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Correction:
    """c0 + c1 log10(d) [dB] with its posterior: mean ``coef`` (2,), ``covariance`` (2, 2).

    ``low``, ``high``: the seen range of log10 d. A correction over an offset (a prior or a
    line) is held at its edge value beyond it (``clip``): outside the distances it was fitted
    on it does not extrapolate its slope, the offset's shape carries on, and its variance
    (evaluated where asked) grows with the slope's uncertainty.
    """

    coef: np.ndarray
    covariance: np.ndarray
    low: float = -np.inf
    high: float = np.inf

    def mean_db(self, log10_distance: np.ndarray) -> np.ndarray:
        x = np.clip(np.asarray(log10_distance, float), self.low, self.high)
        return self.coef[0] + self.coef[1] * x

    def variance_db2(self, log10_distance: np.ndarray) -> np.ndarray:
        """(P,) posterior variance of the correction (phi^T S phi, phi = (1, log10 d))."""
        x = np.asarray(log10_distance, float)
        s = self.covariance
        return np.maximum(s[0, 0] + 2.0 * s[0, 1] * x + s[1, 1] * x * x, 0.0)

    def to_dict(self) -> dict[str, Any]:
        bounds = [None if not np.isfinite(v) else v for v in (self.low, self.high)]
        return {
            "coef": self.coef.tolist(),
            "covariance": self.covariance.tolist(),
            "range_log10_m": bounds,
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> Correction:
        coef = np.asarray(data["coef"], float)
        covariance = np.asarray(data["covariance"], float)
        if coef.shape != (2,) or covariance.shape != (2, 2):
            raise ValueError("a correction has 2 coefficients and a 2 x 2 covariance")
        low, high = data.get("range_log10_m") or (None, None)
        return Correction(
            coef,
            covariance,
            -np.inf if low is None else float(low),
            np.inf if high is None else float(high),
        )


def fit_correction(
    log10_distance: np.ndarray, residual_db: np.ndarray, slope_prior_db: float, clip: bool
) -> Correction:
    """Bayesian linear regression of residuals [dB] (P,) on (1, log10 d) (Bishop eq. 3.53-3.54).

    Gaussian prior N(0, diag(TREND_PRIOR_DB^2, slope_prior_db^2)) on (c0, c1), with log10 d
    centred on its seen mean so the prior shrinks the slope, not the level; noise variance
    from the least-squares residual.
    """
    x = np.asarray(log10_distance, float)
    y = np.asarray(residual_db, float)
    centre = float(x.mean())
    design = np.column_stack([np.ones_like(x), x - centre])
    ls, *_ = np.linalg.lstsq(design, y, rcond=None)
    noise = max(float(np.mean((design @ ls - y) ** 2)), 1e-6)
    precision = design.T @ design / noise + np.diag([TREND_PRIOR_DB**-2, slope_prior_db**-2])
    covariance = np.linalg.inv(precision)
    mean = covariance @ design.T @ y / noise
    # back from the centred (1, x - centre) to (1, x)
    to_raw = np.array([[1.0, -centre], [0.0, 1.0]])
    bounds = (float(x.min()), float(x.max())) if clip else (-np.inf, np.inf)
    return Correction(to_raw @ mean, to_raw @ covariance @ to_raw.T, *bounds)


# ---------------------------------------------------------------------------
# The networks
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Network:
    """One perceptron: ``layers`` of (weights (in, out), bias (out,)); tanh between layers."""

    layers: tuple[tuple[np.ndarray, np.ndarray], ...]

    def predict(self, inputs: np.ndarray) -> np.ndarray:
        """(P,) output for standardised inputs (P, F)."""
        hidden = inputs
        for weights, bias in self.layers[:-1]:
            hidden = np.tanh(hidden @ weights + bias)
        weights, bias = self.layers[-1]
        return (hidden @ weights + bias)[:, 0]


@dataclass(frozen=True, eq=False)
class Ensemble:
    """Guarded networks on standardised features: a residual [dB], its spread and trust.

    Attributes:
        features: names of the input columns (:func:`link_features`' order).
        input_mean, input_scale: (F,) standardisation of the inputs (scale floored).
        low, high: (F,) the seen range of each feature (inputs are clipped to it).
        target_mean, target_scale: standardisation of the residual [dB].
        fallback_db2: mean squared correction on the seen data [dB^2] (the variance the
            map adds where the networks are not trusted).
        networks: the members.
    """

    features: tuple[str, ...]
    input_mean: np.ndarray
    input_scale: np.ndarray
    low: np.ndarray
    high: np.ndarray
    target_mean: float
    target_scale: float
    fallback_db2: float
    networks: tuple[Network, ...]

    def trust(self, features: np.ndarray) -> np.ndarray:
        """(P,) in (0, 1]: 1 inside the seen range, falling off outside (``GUARD_WIDTH_SD``)."""
        below = (self.low - features) / self.input_scale
        above = (features - self.high) / self.input_scale
        excess = np.maximum(np.maximum(below, above), 0.0).max(axis=1)
        trust: np.ndarray = np.exp(-0.5 * (excess / GUARD_WIDTH_SD) ** 2)
        return trust

    def members_db(self, features: np.ndarray) -> np.ndarray:
        """(M, P) each member's residual [dB] at feature rows (P, F), inputs clipped to the
        seen range (no trust applied)."""
        inputs = (np.clip(features, self.low, self.high) - self.input_mean) / self.input_scale
        return np.stack(
            [self.target_mean + self.target_scale * net.predict(inputs) for net in self.networks]
        )

    def mean_db(self, features: np.ndarray) -> np.ndarray:
        """(P,) trusted correction [dB]: trust x the members' mean."""
        return self.trust(features) * self.members_db(features).mean(axis=0)

    def variance_db2(self, features: np.ndarray) -> np.ndarray:
        """(P,) variance [dB^2] of the mixture: networks (weight t), baseline (1 - t)."""
        members = self.members_db(features)
        t = self.trust(features)
        m = members.mean(axis=0)
        variance: np.ndarray = t * members.var(axis=0) + (1 - t) * self.fallback_db2
        return variance + t * (1 - t) * m * m

    def to_dict(self) -> dict[str, Any]:
        return {
            "features": list(self.features),
            "input_mean": self.input_mean.tolist(),
            "input_scale": self.input_scale.tolist(),
            "low": self.low.tolist(),
            "high": self.high.tolist(),
            "target_mean": self.target_mean,
            "target_scale": self.target_scale,
            "fallback_db2": self.fallback_db2,
            "networks": [
                [{"weights": w.tolist(), "bias": b.tolist()} for w, b in net.layers]
                for net in self.networks
            ],
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> Ensemble:
        """The ensemble :meth:`to_dict` wrote (KeyError/TypeError/ValueError if malformed)."""
        nets = tuple(
            Network(
                tuple(
                    (np.asarray(layer["weights"], float), np.asarray(layer["bias"], float))
                    for layer in net
                )
            )
            for net in data["networks"]
        )
        ensemble = Ensemble(
            features=tuple(str(f) for f in data["features"]),
            input_mean=np.asarray(data["input_mean"], float),
            input_scale=np.asarray(data["input_scale"], float),
            low=np.asarray(data["low"], float),
            high=np.asarray(data["high"], float),
            target_mean=float(data["target_mean"]),
            target_scale=float(data["target_scale"]),
            fallback_db2=float(data["fallback_db2"]),
            networks=nets,
        )
        _check_shapes(ensemble)
        return ensemble


def _check_shapes(ensemble: Ensemble) -> None:
    n_features = len(ensemble.features)
    for name in ("input_mean", "input_scale", "low", "high"):
        if getattr(ensemble, name).shape != (n_features,):
            raise ValueError(f"{name} does not have {n_features} features")
    if not np.all(ensemble.input_scale > 0):
        raise ValueError("input_scale must be positive")
    if not ensemble.networks:
        raise ValueError("no networks")
    for net in ensemble.networks:
        width = n_features
        for weights, bias in net.layers:
            if weights.ndim != 2 or weights.shape[0] != width or bias.shape != weights.shape[1:]:
                raise ValueError(f"layer of shape {weights.shape} after width {width}")
            width = weights.shape[1]
        if width != 1:
            raise ValueError("a network must end in one output")


def fit_network(
    inputs: np.ndarray,
    target: np.ndarray,
    seed: int,
    *,
    hidden: tuple[int, ...] = HIDDEN_UNITS,
    penalty: float = L2_PENALTY,
    max_iterations: int = MAX_ITERATIONS,
) -> Network:
    """One network fitted by scikit-learn's MLPRegressor (tanh, L-BFGS) to standardised
    ``inputs`` (P, F) and ``target`` (P,); its weights copied out as plain arrays."""
    from sklearn.neural_network import MLPRegressor

    n_weights = sum(a * b for a, b in zip((inputs.shape[1], *hidden), (*hidden, 1), strict=True))
    model = MLPRegressor(
        hidden_layer_sizes=hidden,
        activation="tanh",
        solver="lbfgs",
        alpha=penalty * len(target) / n_weights,
        max_iter=max_iterations,
        random_state=seed,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # stopping at max_iter is the budget, not a failure
        model.fit(inputs, target)
    layers = zip(model.coefs_, model.intercepts_, strict=True)
    return Network(tuple((np.array(w, float), np.array(b, float)) for w, b in layers))


def fit_ensemble(
    features: np.ndarray,
    residual_db: np.ndarray,
    names: tuple[str, ...],
    *,
    seed: int = 0,
    members: int = ENSEMBLE_SIZE,
    hidden: tuple[int, ...] = HIDDEN_UNITS,
    penalty: float = L2_PENALTY,
    max_iterations: int = MAX_ITERATIONS,
) -> Ensemble:
    """A guarded ensemble fitted to residuals [dB] (P,) at feature rows (P, F) named ``names``.

    Member k is seeded by ``seed * 1000 + k``: the same data and seed give the same weights.
    """
    floors = np.array([FEATURE_FLOORS.get(n, 1e-9) for n in names])
    mean = features.mean(axis=0)
    scale = np.maximum(features.std(axis=0), floors)
    target_mean = float(residual_db.mean())
    target_scale = float(residual_db.std()) or 1.0
    inputs = (features - mean) / scale
    target = (residual_db - target_mean) / target_scale
    # one BLAS thread: these products are small (a few thousand rows x 32), and two threads
    # on two cores shared with other work ran the fit several times slower (CPU time)
    with threadpool_limits(limits=1, user_api="blas"):
        networks = tuple(
            fit_network(
                inputs,
                target,
                seed * 1000 + k,
                hidden=hidden,
                penalty=penalty,
                max_iterations=max_iterations,
            )
            for k in range(members)
        )
    outputs = np.stack([target_mean + target_scale * n.predict(inputs) for n in networks])
    fallback = float(np.mean(outputs.mean(axis=0) ** 2))
    low, high = features.min(axis=0), features.max(axis=0)
    return Ensemble(names, mean, scale, low, high, target_mean, target_scale, fallback, networks)


# ---------------------------------------------------------------------------
# The learned model of one sensor
# ---------------------------------------------------------------------------

CHOICES = ("network", "prior + correction", "log-distance", "free space")
"""What a learned map can be: baseline + networks, or a fallback: the prior + its linear
correction, the log-distance trend, or free space (the link budget's line, nothing fitted)."""


@dataclass(frozen=True, eq=False)
class LearnedModel:
    """One sensor's learned base: (prior, if ``uses_prior``) + correction (+ networks).

    ``choice`` is one of :data:`CHOICES` (what blocked cross-validation kept); ``line``
    (A, n) a log-distance line A - 10 n log10 d [dB] added too (free space when the fit had
    it as its baseline: what ``log-distance`` and the networks without a prior correct).
    """

    choice: str
    uses_prior: bool
    correction: Correction
    ensemble: Ensemble | None = None
    line: tuple[float, float] | None = None

    @property
    def features(self) -> tuple[str, ...]:
        return () if self.ensemble is None else self.ensemble.features

    def needs_prior(self) -> bool:
        return self.uses_prior or PRIOR_FEATURE in self.features

    def _inputs(
        self, positions_m: np.ndarray, sensor_m: np.ndarray, prior_db: np.ndarray | None
    ) -> np.ndarray:
        wants = PRIOR_FEATURE in self.features
        return link_features(positions_m, sensor_m, prior_db if wants else None)

    def mean_db(
        self, positions_m: np.ndarray, sensor_m: np.ndarray, prior_db: np.ndarray | None
    ) -> np.ndarray:
        """(P,) the learned base [dB] at positions (P, 3)."""
        features = self._inputs(positions_m, sensor_m, prior_db)
        out = self.correction.mean_db(features[:, 0])
        if self.line is not None:
            out = out + self.line[0] - 10.0 * self.line[1] * features[:, 0]
        if self.uses_prior:
            assert prior_db is not None
            out = out + np.asarray(prior_db, float)
        if self.ensemble is not None:
            out = out + self.ensemble.mean_db(features)
        return out

    def variance_db2(
        self, positions_m: np.ndarray, sensor_m: np.ndarray, prior_db: np.ndarray | None
    ) -> np.ndarray:
        """(P,) the base's own variance [dB^2]: the correction's and the guarded networks'."""
        features = self._inputs(positions_m, sensor_m, prior_db)
        out = self.correction.variance_db2(features[:, 0])
        if self.ensemble is not None:
            out = out + self.ensemble.variance_db2(features)
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "choice": self.choice,
            "uses_prior": self.uses_prior,
            "correction": self.correction.to_dict(),
            "networks": None if self.ensemble is None else self.ensemble.to_dict(),
            "line": None if self.line is None else list(self.line),
        }

    @staticmethod
    def from_dict(data: dict[str, Any]) -> LearnedModel:
        """The model :meth:`to_dict` wrote (KeyError/TypeError/ValueError if malformed)."""
        if "choice" not in data:
            raise ValueError(
                "a learned map from an older skymule: refit it with 'skymule fit-radiomap "
                "--method neural'"
            )
        choice = str(data["choice"])
        if choice not in CHOICES:
            raise ValueError(f"choice {choice!r} is not one of {', '.join(CHOICES)}")
        networks = data.get("networks")
        line = data.get("line")
        return LearnedModel(
            choice,
            bool(data["uses_prior"]),
            Correction.from_dict(data["correction"]),
            Ensemble.from_dict(networks) if networks else None,
            None if line is None else (float(line[0]), float(line[1])),
        )


def prior_is_redundant(prior_db: np.ndarray, log10_distance: np.ndarray) -> bool:
    """True when the prior's SNR is (almost) a function of log-distance on the seen data."""
    if np.std(prior_db) < 1e-9 or np.std(log10_distance) < 1e-9:
        return True
    r = float(np.corrcoef(prior_db, log10_distance)[0, 1])
    return abs(r) >= PRIOR_REDUNDANT_R


def fit_learned(
    positions_m: np.ndarray,
    snr_db: np.ndarray,
    sensor_m: np.ndarray,
    prior_db: np.ndarray | None,
    choice: str,
    *,
    seed: int = 0,
    members: int = ENSEMBLE_SIZE,
    line: tuple[float, float] | None = None,
) -> LearnedModel:
    """The learned base of ``choice`` (:data:`CHOICES`) fitted to samples (P, 3), (P,).

    The offset is the prior (``prior + correction``, and ``network`` with a prior), else
    ``line`` (A, n) when given (free space: ``free space`` is the line alone; ``log-distance``
    is the line plus a free linear correction, the same fit as the trend where the samples
    are, free space's slope beyond), else nothing (``log-distance``: the trend by least
    squares). A correction over an offset is held constant beyond the seen distances.
    """
    uses_prior = prior_db is not None and choice in ("network", "prior + correction")
    features = link_features(positions_m, sensor_m)
    x = features[:, 0]
    kept_line = None if uses_prior else line
    if choice == "free space":
        if line is None:
            raise ValueError("the free-space fallback needs the free-space line")
        return LearnedModel(choice, False, Correction(np.zeros(2), np.zeros((2, 2))), None, line)
    offset = np.asarray(prior_db, float) if uses_prior and prior_db is not None else 0.0
    if kept_line is not None:
        offset = kept_line[0] - 10.0 * kept_line[1] * x
    slope_prior = SLOPE_PRIOR_DB if uses_prior else TREND_PRIOR_DB
    clip = uses_prior or kept_line is not None
    correction = fit_correction(x, snr_db - offset, slope_prior, clip)
    if choice != "network":
        return LearnedModel(choice, uses_prior, correction, None, kept_line)
    residual = snr_db - offset - correction.mean_db(x)
    names: tuple[str, ...] = FEATURES
    if prior_db is not None and not prior_is_redundant(prior_db, x):
        features = np.column_stack([features, prior_db])
        names = (*FEATURES, PRIOR_FEATURE)
    ensemble = fit_ensemble(features, residual, names, seed=seed, members=members)
    return LearnedModel(choice, uses_prior, correction, ensemble, kept_line)
