"""A learned radio map: an ensemble of small neural networks on physical link features.

Per sensor, the network sees where the UAV is *as the link sees it* (Zeng et al.'s and the
AERPAW radio-map studies' choice of inputs, rather than raw x/y):

* log10 of the 3-D UAV-antenna distance (the path-loss trend is linear in it),
* the elevation angle seen from the antenna (antenna pattern, ground clearance),
* the azimuth seen from the antenna, as its sine and cosine (pattern, obstacles behind which
  the UAV is blocked lie in a sector of azimuth beyond some distance),
* the UAV's height,
* and, with a prior (a digital twin), the twin's own SNR prediction at that point.

The target is the *residual* of the measurement over a base prediction: the prior's SNR when
there is one (so a few minutes of real flight calibrate the twin: the network learns where
and by how much the twin is wrong), else the fitted log-distance trend (so far from the data
the map falls back to physics, not to whatever a network extrapolates).

The network is a multilayer perceptron (tanh hidden layers, linear output) fitted by L-BFGS
(scipy) on the mean squared error plus an L2 penalty on the weights, inputs and target
standardised. ``ENSEMBLE_SIZE`` networks from independent seeded initialisations form a deep
ensemble (Lakshminarayanan, Pritzel & Blundell, NeurIPS 2017): their mean is the prediction,
their spread the model (epistemic) uncertainty, which the map adds to the kriging posterior
variance of what is left (:meth:`skymule.radio.radiomap.SensorMap.sigma_db`). Everything is
seeded: the same data give the same weights.

Weights are plain arrays (written to the map JSON as numbers, read back without running any
code from the file).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.optimize
from threadpoolctl import threadpool_limits

from skymule.radio.pathloss import MIN_DISTANCE_M

HIDDEN_UNITS = (32,)
"""Hidden layer widths of each network (one layer of 32: measured against 16, 32 x 32 and
16 x 16 on a time split, it extrapolated best to directions the seen part never flew)."""

ENSEMBLE_SIZE = 5
"""Networks in the ensemble."""

L2_PENALTY = 1.0
"""Weight decay: penalty on the mean squared weight, relative to the standardised MSE (the
default when there is too little data to choose one from ``PENALTIES``)."""

PENALTIES = (0.3, 1.0, 3.0, 10.0)
"""Weight decays :func:`choose_penalty` tries. Strong decay is what keeps a network sane
where the seen flight never went: on the time split of tests/test_sim2real.py a decay of
1e-3 predicted the unseen 60% at 5.7 dB RMSE, 1.0 at 1.3 dB (noise 1 dB)."""

SELECTION_MEMBERS = 2
"""Networks per candidate decay when choosing one."""

MIN_VALIDATION = 10
"""Fewest validation (and training) samples to choose a decay; else ``L2_PENALTY``."""

MAX_ITERATIONS = 300
"""L-BFGS iterations per network."""

FEATURES = ("log10_distance", "elevation_rad", "sin_azimuth", "cos_azimuth", "height_m")
"""Input features without a prior; ``prior_db`` is appended when the map has one."""

PRIOR_FEATURE = "prior_db"


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
    """A fitted ensemble on standardised features: residual [dB] and its spread at points.

    Attributes:
        features: names of the input columns (:func:`link_features`' order).
        input_mean, input_scale: (F,) standardisation of the inputs.
        target_mean, target_scale: standardisation of the residual [dB].
        networks: the members.
    """

    features: tuple[str, ...]
    input_mean: np.ndarray
    input_scale: np.ndarray
    target_mean: float
    target_scale: float
    networks: tuple[Network, ...]

    def members_db(self, features: np.ndarray) -> np.ndarray:
        """(M, P) each member's residual [dB] at feature rows (P, F)."""
        inputs = (features - self.input_mean) / self.input_scale
        return np.stack(
            [self.target_mean + self.target_scale * net.predict(inputs) for net in self.networks]
        )

    def mean_db(self, features: np.ndarray) -> np.ndarray:
        """(P,) ensemble mean residual [dB]."""
        return self.members_db(features).mean(axis=0)

    def to_dict(self) -> dict[str, Any]:
        return {
            "features": list(self.features),
            "input_mean": self.input_mean.tolist(),
            "input_scale": self.input_scale.tolist(),
            "target_mean": self.target_mean,
            "target_scale": self.target_scale,
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
        features = tuple(str(f) for f in data["features"])
        ensemble = Ensemble(
            features=features,
            input_mean=np.asarray(data["input_mean"], float),
            input_scale=np.asarray(data["input_scale"], float),
            target_mean=float(data["target_mean"]),
            target_scale=float(data["target_scale"]),
            networks=nets,
        )
        _check_shapes(ensemble)
        return ensemble


def _check_shapes(ensemble: Ensemble) -> None:
    n_features = len(ensemble.features)
    if ensemble.input_mean.shape != (n_features,) or ensemble.input_scale.shape != (n_features,):
        raise ValueError(f"input standardisation does not have {n_features} features")
    if not ensemble.networks:
        raise ValueError("no networks")
    for net in ensemble.networks:
        width = len(ensemble.features)
        for weights, bias in net.layers:
            if weights.ndim != 2 or weights.shape[0] != width or bias.shape != weights.shape[1:]:
                raise ValueError(f"layer of shape {weights.shape} after width {width}")
            width = weights.shape[1]
        if width != 1:
            raise ValueError("a network must end in one output")


def _shapes(n_inputs: int, hidden: tuple[int, ...]) -> list[tuple[int, int]]:
    sizes = [n_inputs, *hidden, 1]
    return list(itertools.pairwise(sizes))


def _unpack(
    theta: np.ndarray, shapes: list[tuple[int, int]]
) -> list[tuple[np.ndarray, np.ndarray]]:
    layers, start = [], 0
    for n_in, n_out in shapes:
        weights = theta[start : start + n_in * n_out].reshape(n_in, n_out)
        start += n_in * n_out
        layers.append((weights, theta[start : start + n_out]))
        start += n_out
    return layers


def _loss_and_gradient(
    theta: np.ndarray,
    inputs: np.ndarray,
    target: np.ndarray,
    shapes: list[tuple[int, int]],
    penalty: float,
) -> tuple[float, np.ndarray]:
    """Mean squared error + penalty * mean squared weight, and its gradient (backpropagation)."""
    layers = _unpack(theta, shapes)
    activations = [inputs]
    for weights, bias in layers[:-1]:
        activations.append(np.tanh(activations[-1] @ weights + bias))
    weights_out, bias_out = layers[-1]
    error = (activations[-1] @ weights_out + bias_out)[:, 0] - target
    n = target.shape[0]
    n_weights = sum(a * b for a, b in shapes)
    loss = float(error @ error) / n
    loss += penalty * sum(float((w * w).sum()) for w, _ in layers) / n_weights
    grads: list[np.ndarray] = []
    delta = (2.0 / n) * error[:, None]
    for index in range(len(layers) - 1, -1, -1):
        weights, _ = layers[index]
        grad_w = activations[index].T @ delta + (2.0 * penalty / n_weights) * weights
        grads[:0] = [grad_w.ravel(), delta.sum(axis=0)]
        if index:
            delta = (delta @ weights.T) * (1.0 - activations[index] ** 2)
    return loss, np.concatenate(grads)


def fit_network(
    inputs: np.ndarray,
    target: np.ndarray,
    rng: np.random.Generator,
    *,
    hidden: tuple[int, ...] = HIDDEN_UNITS,
    penalty: float = L2_PENALTY,
    max_iterations: int = MAX_ITERATIONS,
) -> Network:
    """One network fitted by L-BFGS to standardised ``inputs`` (P, F) and ``target`` (P,).

    Glorot-uniform initial weights from ``rng``, zero biases.
    """
    shapes = _shapes(inputs.shape[1], hidden)
    parts = []
    for n_in, n_out in shapes:
        limit = np.sqrt(6.0 / (n_in + n_out))
        parts += [rng.uniform(-limit, limit, n_in * n_out), np.zeros(n_out)]
    result = scipy.optimize.minimize(
        _loss_and_gradient,
        np.concatenate(parts),
        args=(inputs, target, shapes, penalty),
        jac=True,
        method="L-BFGS-B",
        options={"maxiter": max_iterations},
    )
    layers = _unpack(np.asarray(result.x, float), shapes)
    return Network(tuple((w.copy(), b.copy()) for w, b in layers))


def choose_penalty(
    features: np.ndarray, residual_db: np.ndarray, validation: np.ndarray, *, seed: int = 0
) -> float:
    """The decay of ``PENALTIES`` whose networks, fitted without the ``validation`` samples
    (a mask: the last stretch of each flight, a split in time), predict them best."""
    if validation.sum() < MIN_VALIDATION or (~validation).sum() < MIN_VALIDATION:
        return L2_PENALTY
    names = tuple(f"f{i}" for i in range(features.shape[1]))
    errors = []
    for penalty in PENALTIES:
        ensemble = fit_ensemble(
            features[~validation], residual_db[~validation], names,
            seed=seed, members=SELECTION_MEMBERS, penalty=penalty,
        )  # fmt: skip
        error = ensemble.mean_db(features[validation]) - residual_db[validation]
        errors.append(float(np.mean(error**2)))
    return PENALTIES[int(np.argmin(errors))]


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
    """An ensemble fitted to residuals [dB] (P,) at feature rows (P, F) named ``names``.

    Member k starts from ``numpy.random.default_rng([seed, k])``: the same data and seed give
    the same weights.
    """
    mean = features.mean(axis=0)
    scale = features.std(axis=0)
    scale = np.where(scale > 1e-9, scale, 1.0)  # a constant feature (e.g. one height) stays 0
    target_mean = float(residual_db.mean())
    target_scale = float(residual_db.std()) or 1.0
    inputs = (features - mean) / scale
    target = (residual_db - target_mean) / target_scale
    # one BLAS thread: these products are small (a few thousand rows x 32), and two threads
    # on two cores shared with other work ran the fit 5x slower (CPU time) than one here
    with threadpool_limits(limits=1, user_api="blas"):
        networks = tuple(
            fit_network(
                inputs,
                target,
                np.random.default_rng([seed, k]),
                hidden=hidden,
                penalty=penalty,
                max_iterations=max_iterations,
            )
            for k in range(members)
        )
    return Ensemble(names, mean, scale, target_mean, target_scale, networks)
