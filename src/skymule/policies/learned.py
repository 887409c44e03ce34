"""``learned``: a trained option scorer, evaluated in numpy (no torch, no pickle).

The policy thinks in options (:mod:`skymule.policies.options`: go to sensor k's hover point
and hover d slots, serve while passing, return home); at each option boundary a small network
scores every allowed option and the best one runs until it ends. The network is invariant to
the order and the number of sensors: a shared per-sensor encoder, mean and max pooling over
the sensors with data, and one shared scorer applied to every (sensor, duration) option with
the pooled context (Deep Sets; Zaheer et al., "Deep Sets", NeurIPS 2017). One model serves
any sensor count.

Scores (all arrays of one model, ``M`` = 1; training stacks M perturbed models):

* encoder ``e_k = tanh([s_k, g] W_e + b_e)`` over the per-sensor features ``s_k`` and the
  mission features ``g``; pooled ``p = [mean_k e_k, max_k e_k]`` over usable sensors;
* option (k, d): ``x = [s_k, o_kd, g]``, ``score = w_o . tanh([x, p] W_h + b_h) + b_o + w_l . x``;
* home: ``w_home . [g, p] + b_home``.

Weights live in an ``.npz`` file of plain float arrays (:data:`WEIGHT_NAMES`) plus the
format tag and the feature names it was trained with; :func:`load_net` checks every name,
shape and value before use and reports a bad file in one line. ``learned`` loads the model
shipped in the package (``skymule/data/learned_policy.npz``), ``learned:PATH`` your own.
"""

from __future__ import annotations

import zipfile
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

from skymule.errors import SkymuleError
from skymule.io.atomic import atomic_path
from skymule.io.npzcheck import NpzError, npz_members
from skymule.policies.base import BatchAction, BatchObservation, MissionContext
from skymule.policies.options import (
    FRACTIONS,
    GLOBAL_FEATURES,
    N_DURATIONS,
    OPTION_FEATURES,
    SENSOR_FEATURES,
    Decision,
    OptionRunner,
    option_features,
)
from skymule.sim import compiled

#: Policy names ``learned:path/to/weights.npz``.
PREFIX = "learned:"

#: The format tag every weights file carries.
FORMAT = "skymule-learned-options-1"

#: The arrays of a weights file (besides ``format`` and ``features``), in order.
WEIGHT_NAMES = (
    "encoder_w",
    "encoder_b",
    "hidden_w",
    "hidden_b",
    "out_w",
    "out_b",
    "linear_w",
    "home_w",
    "home_b",
)

#: Every feature name, in the order the network reads them.
FEATURE_NAMES = (
    *(f"sensor.{n}" for n in SENSOR_FEATURES),
    *(f"option.{n}" for n in OPTION_FEATURES),
    *(f"mission.{n}" for n in GLOBAL_FEATURES),
)

#: Numbers of sensor, option and mission features.
FS, FO, FG = len(SENSOR_FEATURES), len(OPTION_FEATURES), len(GLOBAL_FEATURES)


def shipped_weights() -> Path:
    """The weights file of the built-in ``learned`` policy (inside the package)."""
    return Path(str(resources.files("skymule") / "data" / "learned_policy.npz"))


@dataclass(frozen=True)
class OptionNet:
    """The scorer's weights, each with a leading model axis M (M = 1 for one model).

    Shapes: encoder_w (M, FS+FG, H), encoder_b (M, H), hidden_w (M, FS+FO+FG+2H, K),
    hidden_b (M, K), out_w (M, K), out_b (M,), linear_w (M, FS+FO+FG), home_w (M, FG+2H),
    home_b (M,).
    """

    encoder_w: np.ndarray
    encoder_b: np.ndarray
    hidden_w: np.ndarray
    hidden_b: np.ndarray
    out_w: np.ndarray
    out_b: np.ndarray
    linear_w: np.ndarray
    home_w: np.ndarray
    home_b: np.ndarray

    @property
    def models(self) -> int:
        """M, the number of stacked models."""
        return int(self.out_b.shape[0])

    @property
    def sizes(self) -> tuple[int, int]:
        """(H, K): encoder and hidden widths."""
        return int(self.encoder_b.shape[1]), int(self.hidden_b.shape[1])

    def flat(self) -> np.ndarray:
        """(M, P) every weight of each model in one row (for training)."""
        return np.concatenate(
            [getattr(self, n).reshape(self.models, -1) for n in WEIGHT_NAMES], axis=1
        )

    def with_flat(self, rows: np.ndarray) -> OptionNet:
        """Models of the same shapes with weights ``rows`` (M', P)."""
        rows = np.atleast_2d(np.asarray(rows, float))
        arrays, at = {}, 0
        for name in WEIGHT_NAMES:
            shape = getattr(self, name).shape[1:]
            size = int(np.prod(shape, dtype=np.int64))
            arrays[name] = rows[:, at : at + size].reshape(len(rows), *shape)
            at += size
        return OptionNet(**arrays)

    def model(self, index: int) -> OptionNet:
        """Model ``index`` alone (M = 1)."""
        return OptionNet(**{n: getattr(self, n)[index : index + 1] for n in WEIGHT_NAMES})


def expected_shapes(hidden: int, width: int) -> dict[str, tuple[int, ...]]:
    """The shape of every weight (without the model axis) for widths H and K."""
    return {
        "encoder_w": (FS + FG, hidden),
        "encoder_b": (hidden,),
        "hidden_w": (FS + FO + FG + 2 * hidden, width),
        "hidden_b": (width,),
        "out_w": (width,),
        "out_b": (),
        "linear_w": (FS + FO + FG,),
        "home_w": (FG + 2 * hidden,),
        "home_b": (),
    }


def initial_net(rng: np.random.Generator, hidden: int = 16, width: int = 32) -> OptionNet:
    """A starting model: small random encoder and hidden layer, zero output layer, and a
    linear prior that adds HGAD's next option (``option.hgad``) to the bits per slot spent
    (``option.pace``), and never goes home while anything else is allowed."""
    shapes = expected_shapes(hidden, width)
    arrays = {}
    for name, shape in shapes.items():
        fan_in = shape[0] if len(shape) == 2 else 1
        scale = 1.0 / np.sqrt(fan_in) if name in ("encoder_w", "hidden_w") else 0.0
        arrays[name] = (rng.standard_normal(shape) * scale)[None]
    arrays["linear_w"][0, FS + OPTION_FEATURES.index("pace")] = 1.0
    arrays["linear_w"][0, FS + OPTION_FEATURES.index("hgad")] = 1.0
    arrays["home_b"][0] = -2.0
    return OptionNet(**arrays)


def scores(net: OptionNet, model: np.ndarray | None, decision: Decision) -> np.ndarray:
    """(R, N*D + 1) score of every option of R decisions (-inf where not allowed).

    ``model`` (R,) picks each decision's model among the M stacked ones (None: model 0).
    """
    sensor, option, mission, allowed = option_features(decision)
    rows, n = sensor.shape[:2]
    width = N_DURATIONS
    usable = np.any(allowed[:, :-1].reshape(rows, n, width), axis=2)
    g_n = np.broadcast_to(mission[:, None, :], (rows, n, FG))
    enc_in = np.concatenate([sensor, g_n], axis=2)
    single = model is None or net.models == 1
    index = np.zeros(rows, np.int64) if model is None else np.asarray(model, np.int64)

    def weight(name: str) -> np.ndarray:
        w = getattr(net, name)
        return w[0] if single else w[index]

    if single:
        encoded = np.tanh(enc_in @ weight("encoder_w") + weight("encoder_b"))
    else:
        encoded = np.tanh(
            np.einsum("rns,rsh->rnh", enc_in, weight("encoder_w")) + weight("encoder_b")[:, None]
        )
    count = usable.sum(axis=1, keepdims=True)
    mean = np.where(usable[..., None], encoded, 0.0).sum(axis=1) / np.maximum(count, 1)
    top = np.where(usable[..., None], encoded, -1.0).max(axis=1)
    top = np.where(count > 0, top, 0.0)
    pooled = np.concatenate([mean, top], axis=1)  # (R, 2H)
    x = np.concatenate(
        [
            np.broadcast_to(sensor[:, :, None, :], (rows, n, width, FS)),
            option,
            np.broadcast_to(mission[:, None, None, :], (rows, n, width, FG)),
        ],
        axis=3,
    )
    xp = np.concatenate(
        [x, np.broadcast_to(pooled[:, None, None, :], (rows, n, width, pooled.shape[1]))], axis=3
    )
    if single:
        hidden = np.tanh(xp @ weight("hidden_w") + weight("hidden_b"))
        value = hidden @ weight("out_w") + weight("out_b") + x @ weight("linear_w")
        home = np.concatenate([mission, pooled], axis=1) @ weight("home_w") + weight("home_b")
    else:
        hidden = np.tanh(
            np.einsum("rndf,rfk->rndk", xp, weight("hidden_w")) + weight("hidden_b")[:, None, None]
        )
        value = (
            np.einsum("rndk,rk->rnd", hidden, weight("out_w"))
            + weight("out_b")[:, None, None]
            + np.einsum("rndf,rf->rnd", x, weight("linear_w"))
        )
        home = np.einsum(
            "rf,rf->r", np.concatenate([mission, pooled], axis=1), weight("home_w")
        ) + weight("home_b")
    flat = np.concatenate([value.reshape(rows, -1), home[:, None]], axis=1)
    return np.where(allowed, flat, -np.inf)


_FRACTIONS = np.asarray(FRACTIONS)


def compiled_scores(net: OptionNet, decision: Decision) -> np.ndarray:
    """:func:`scores` of model 0 by the compiled twin
    (:func:`skymule.policies.learned_kernel.score_rows`; plain Python without numba)."""
    from skymule.policies.learned_kernel import score_kernel

    d = decision
    rows, n = d.travel.shape
    out = np.empty((rows, n * N_DURATIONS + 1))
    # C-contiguous arguments: numba types any other layout in Python, ~40 us a call
    c = np.ascontiguousarray
    score_kernel()(
        c(d.travel), c(d.back), c(d.pair), c(d.home), c(d.slots_left), c(d.n_slots),
        c(d.slot_s), c(d.remaining), c(d.initial), c(d.peak), c(d.rate_now), c(d.usable),
        c(d.visited), c(d.near), _FRACTIONS, net.encoder_w[0], net.encoder_b[0],
        net.hidden_w[0], net.hidden_b[0], net.out_w[0], float(net.out_b[0]), net.linear_w[0],
        net.home_w[0], float(net.home_b[0]), out,
    )  # fmt: skip
    return out


def _bad(path: Path, what: str) -> SkymuleError:
    return SkymuleError(f"learned policy weights {path}: {what}")


MAX_WEIGHTS_BYTES = 64 * 2**20
"""Largest weights file, and largest sum of its arrays, :func:`load_net` reads [bytes]
(64 MiB; the shipped model is 22 kB, and a hidden width of 1024 needs about 17 MB)."""


def _check_declared(path: Path) -> None:
    """Refuse a weights file from its zip directory and array headers alone (issue 32):
    too big, other names than the model's, dtypes other than floats (a string for
    ``format`` and ``features``), or shapes that do not fit together."""
    try:
        members = npz_members(path, MAX_WEIGHTS_BYTES)
    except NpzError as exc:
        raise _bad(path, f"not a readable .npz of plain arrays ({exc})") from None
    expected = {*WEIGHT_NAMES, "format", "features"}
    missing, extra = sorted(expected - set(members)), sorted(set(members) - expected)
    if missing or extra:
        parts = [
            f"missing {', '.join(missing)}" if missing else "",
            f"unexpected {', '.join(extra)}" if extra else "",
        ]
        raise _bad(
            path, "; ".join(p for p in parts if p) + f"; allowed: {', '.join(sorted(expected))}"
        )
    tag, features = members["format"], members["features"]
    if tag.dtype.kind != "U" or tag.shape != ():
        raise _bad(path, f"format is {tag.dtype} of shape {tag.shape}; allowed: {FORMAT}")
    if features.dtype.kind != "U" or features.shape != (len(FEATURE_NAMES),):
        raise _bad(
            path, "trained on other features than this skymule computes; retrain it with "
            "benchmarks/train_learned.py"
        )  # fmt: skip
    hidden, width = members["encoder_b"].shape, members["hidden_b"].shape
    if len(hidden) != 1 or len(width) != 1 or not hidden[0] or not width[0]:
        raise _bad(path, "encoder_b and hidden_b must be non-empty 1-d arrays")
    for name, shape in expected_shapes(hidden[0], width[0]).items():
        declared = members[name]
        if declared.dtype.kind != "f":
            raise _bad(path, f"{name} has dtype {declared.dtype}; allowed: floats")
        if declared.shape != shape:
            raise _bad(path, f"{name} has shape {declared.shape}; expected {shape}")


def load_net(path: str | Path) -> OptionNet:
    """The model in the weights file ``path``: every name, shape and value checked (one-line
    SkymuleError naming the file and what is wrong). The file is read as plain arrays: no
    pickle, no code."""
    path = Path(path)
    if not path.is_file():
        raise _bad(path, "no such file (give learned:path/to/weights.npz)")
    _check_declared(path)  # names, dtypes, shapes and size from the headers, nothing read yet
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise _bad(path, f"not a readable .npz of plain arrays ({reason})") from None
    tag = arrays["format"]  # the names were checked from the zip directory
    if tag.dtype.kind != "U" or tag.shape != () or str(tag) != FORMAT:
        raise _bad(path, f"format is {tag!s:.40}; allowed: {FORMAT}")
    features = arrays["features"]
    if features.dtype.kind != "U" or tuple(features.tolist()) != FEATURE_NAMES:
        raise _bad(
            path, "trained on other features than this skymule computes; retrain it with "
            "benchmarks/train_learned.py"
        )  # fmt: skip
    encoder_b = arrays["encoder_b"]
    hidden_b = arrays["hidden_b"]
    if encoder_b.ndim != 1 or hidden_b.ndim != 1 or not encoder_b.size or not hidden_b.size:
        raise _bad(path, "encoder_b and hidden_b must be non-empty 1-d arrays")
    shapes = expected_shapes(encoder_b.size, hidden_b.size)
    for name, shape in shapes.items():
        value = arrays[name]
        if value.dtype.kind != "f":
            raise _bad(path, f"{name} has dtype {value.dtype}; allowed: floats")
        if value.shape != shape:
            raise _bad(path, f"{name} has shape {value.shape}; expected {shape}")
        if not np.isfinite(value).all():
            raise _bad(path, f"{name} holds NaN or infinite values")
    return OptionNet(**{name: np.asarray(arrays[name], float)[None] for name in WEIGHT_NAMES})


def save_net(net: OptionNet, path: str | Path) -> Path:
    """Write model 0 of ``net`` to ``path`` (.npz, atomically: a temporary name in the same
    folder, then a rename)."""
    path = Path(path)
    arrays = {name: getattr(net, name)[0] for name in WEIGHT_NAMES}
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        np.savez(handle, format=np.array(FORMAT), features=np.array(FEATURE_NAMES), **arrays)
    return path


class LearnedPolicy:
    """The option scorer as a batched policy (module docstring).

    Args:
        net: the model(s); with M > 1, ``model`` (B,) names each mission's model (training).
        name: the policy name in logs.
        model: (B,) model index per mission, or None (model 0).
    """

    batched = True

    def __init__(self, net: OptionNet, name: str = "learned", model: np.ndarray | None = None):
        self.net = net
        self.name = name
        self.model = None if model is None else np.asarray(model, np.int64)
        self.runner: OptionRunner | None = None
        self._compiled = compiled.available() and self.net.models == 1

    def reset(self, contexts: Sequence[MissionContext]) -> None:
        if any(c.mode != "autonomous" for c in contexts):
            raise SkymuleError(
                f"policy.name = {self.name!r} steers the UAV: it needs trajectory.mode = "
                "'autonomous' (use 'hgad' or 'optimal-fixed' on fixed paths)"
            )
        if any(
            c.hover_points_m is None or c.home_m is None or c.navigator is None for c in contexts
        ):
            raise SkymuleError(f"policy {self.name!r} needs hover points, home and a navigator")
        if self.model is not None and len(self.model) != len(contexts):
            raise ValueError("one model index per mission")
        self.runner = OptionRunner(contexts, self.choose)

    def choose(self, decision: Decision) -> np.ndarray:
        """(R,) the best-scored option of each decision (one model with numba installed: by
        the compiled twin, the same scores)."""
        if self.model is None and self._compiled:
            return np.argmax(compiled_scores(self.net, decision), axis=1)
        model = None if self.model is None else self.model[decision.rows]
        return np.argmax(scores(self.net, model, decision), axis=1)

    def act(self, observation: BatchObservation) -> BatchAction:
        if self.runner is None:
            raise SkymuleError(f"policy {self.name!r}: act() before reset()")
        return self.runner.act(observation)


def shipped_policy() -> LearnedPolicy:
    """``learned``: the model shipped in the package."""
    return LearnedPolicy(load_net(shipped_weights()), "learned")


def learned_policy(name: str = "learned") -> LearnedPolicy:
    """The policy a name makes: ``learned`` (the shipped model) or ``learned:PATH``."""
    if name == "learned":
        return shipped_policy()
    if not name.startswith(PREFIX) or len(name) == len(PREFIX):
        raise SkymuleError(f"policy.name = {name!r}: give learned or learned:path/to/weights.npz")
    path = Path(name[len(PREFIX) :])
    return LearnedPolicy(load_net(path), f"learned:{path.stem}")
