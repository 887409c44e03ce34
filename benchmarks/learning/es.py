"""Evolution strategies for the ``learned`` option scorer, on the batched engine (numpy only).

Each generation perturbs the model's weights theta with ``pairs`` antithetic Gaussian pairs
(theta +- sigma eps), flies every perturbed model on the same missions (one engine batch per
sensor count: members x missions columns, :class:`~skymule.policies.learned.LearnedPolicy`
with stacked weights), scores each member by its download relative to HGAD on the same
missions (minus a penalty on missions it loses by more than ``loss_margin``), and moves theta
along the rank-weighted perturbations with Adam. Salimans et al., "Evolution Strategies as a
Scalable Alternative to Reinforcement Learning", 2017 (antithetic sampling, centred ranks);
Kingma and Ba, "Adam", 2015.

Why ES here: the return of a mission is known only at its end and an option's worth depends
on the options after it; ES needs neither a value function nor gradients through the
simulator, every mission of a generation is one column of one engine batch, and its only
hyper-parameters are the noise and the step. ``benchmarks/train_learned.py --algorithm ppo``
runs the measured comparison with PPO on the same options, features and budget.

Work is split over ``workers`` processes, each holding the training missions of some sensor
counts (built once: building a mission with shadowing costs more than flying it).
"""

from __future__ import annotations

import multiprocessing as mp
import queue
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from learning.missions import TRAINING, Draw, draw_missions
from skymule.policies.builtin import HGAD
from skymule.policies.learned import LearnedPolicy, OptionNet, initial_net
from skymule.sim.run import run_mission, run_missions
from skymule.world import Mission


@dataclass(frozen=True)
class ESConfig:
    """Evolution-strategy settings (defaults: the shipped model's)."""

    pairs: int = 16
    sigma: float = 0.03
    learning_rate: float = 0.01
    missions_per_count: int = 16
    pool_per_count: int = 100
    sensor_counts: tuple[int, ...] = (3, 4, 5, 6, 7, 8)
    loss_margin: float = 0.02
    loss_weight: float = 4.0
    hidden: int = 16
    width: int = 32
    seed: int = 0
    workers: int = 2
    draw: Draw = field(default=TRAINING)
    teacher: str = "hgad"  # the reference each mission's gain is taken against: hgad or planner


def relative_gain(bits: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(bits - reference) / reference, elementwise (reference 0: 0 when equal)."""
    safe = np.where(reference > 0, reference, 1.0)
    return np.where(reference > 0, (bits - reference) / safe, np.sign(bits - reference))


def fitness(gain: np.ndarray, margin: float, weight: float) -> np.ndarray:
    """(members,) mean relative gain over missions (last axis) minus ``weight`` x the mean
    shortfall beyond ``margin`` below the reference."""
    return gain.mean(axis=-1) - weight * np.maximum(0.0, -gain - margin).mean(axis=-1)


def centred_ranks(values: np.ndarray) -> np.ndarray:
    """Ranks of ``values`` scaled to [-0.5, 0.5] (ties broken by position)."""
    ranks = np.empty(len(values))
    ranks[np.argsort(values, kind="stable")] = np.arange(len(values))
    return ranks / max(len(values) - 1, 1) - 0.5


def downloads(missions: Sequence[Mission], net: OptionNet) -> np.ndarray:
    """(M, missions) bits each of the M stacked models downloads on every mission (one
    engine batch: models x missions columns)."""
    models = net.models
    columns = [m for m in missions for _ in range(models)]
    policy = LearnedPolicy(net, model=np.tile(np.arange(models), len(missions)))
    bits = run_missions(columns, policy, detail=False).downloaded_bit.sum(axis=1)
    return bits.reshape(len(missions), models).T


def hgad_downloads(missions: Sequence[Mission]) -> np.ndarray:
    """(missions,) bits HGAD downloads on each mission."""
    return run_missions(list(missions), HGAD(), detail=False).downloaded_bit.sum(axis=1)


def reference_downloads(missions: Sequence[Mission], teacher: str) -> np.ndarray:
    """(missions,) bits the reference policy ``teacher`` (hgad or planner) downloads on each
    mission (the planner one mission at a time: it is not batched)."""
    if teacher == "hgad":
        return hgad_downloads(missions)
    if teacher != "planner":
        raise ValueError(f"teacher = {teacher!r}; allowed: hgad, planner")
    from skymule.policies.planner import Planner

    return np.array([run_mission(m, Planner()).downloaded_bit.sum() for m in missions])


class Pool:
    """Training missions of some sensor counts and HGAD's download on each."""

    def __init__(self, counts: Sequence[int], config: ESConfig) -> None:
        self.missions = {
            n: draw_missions(config.seed, n, config.pool_per_count, config.draw) for n in counts
        }
        self.hgad = {n: reference_downloads(m, config.teacher) for n, m in self.missions.items()}

    def evaluate(
        self, n: int, picks: np.ndarray, rows: np.ndarray, template: OptionNet
    ) -> np.ndarray:
        """(members, picks) relative gain over HGAD of the models ``rows`` on missions
        ``picks`` of sensor count ``n``."""
        chosen = [self.missions[n][i] for i in picks]
        bits = downloads(chosen, template.with_flat(rows))
        return relative_gain(bits, self.hgad[n][picks][None])


def _worker(counts: Sequence[int], config: ESConfig, inbox: Any, outbox: Any) -> None:
    pool = Pool(counts, config)
    outbox.put("ready")
    while True:
        task = inbox.get()
        if task is None:
            return
        n, picks, rows, template = task
        outbox.put(pool.evaluate(n, picks, rows, template))


def _receive(outbox: Any, proc: Any) -> Any:
    """The next message of a worker; RuntimeError if the worker died (its traceback is on
    stderr) rather than waiting for ever."""
    while True:
        try:
            return outbox.get(timeout=5.0)
        except queue.Empty:
            if not proc.is_alive():
                raise RuntimeError(f"training worker {proc.pid} died") from None


@dataclass
class ESResult:
    """The trained model (the best validated centre) and the run's figures."""

    net: OptionNet
    generations: int
    missions_flown: int
    seconds: float
    curve: list[dict[str, float]]


class Adam:
    """Adam ascent on a flat parameter vector."""

    def __init__(self, size: int, rate: float, beta1: float = 0.9, beta2: float = 0.999) -> None:
        self.rate, self.beta1, self.beta2 = rate, beta1, beta2
        self.m, self.v, self.t = np.zeros(size), np.zeros(size), 0

    def step(self, gradient: np.ndarray) -> np.ndarray:
        """The ascent step for ``gradient``."""
        self.t += 1
        self.m = self.beta1 * self.m + (1 - self.beta1) * gradient
        self.v = self.beta2 * self.v + (1 - self.beta2) * gradient**2
        m_hat = self.m / (1 - self.beta1**self.t)
        v_hat = self.v / (1 - self.beta2**self.t)
        return self.rate * m_hat / (np.sqrt(v_hat) + 1e-8)


def train_es(
    config: ESConfig,
    seconds: float,
    validate: Callable[[OptionNet], dict[str, float]],
    validate_every: int = 10,
    max_generations: int | None = None,
    log: Callable[[str], None] = print,
    start_net: OptionNet | None = None,
) -> ESResult:
    """Train for ``seconds`` of wall time (or ``max_generations``); ``validate(net)`` scores
    the centre every ``validate_every`` generations (its ``"score"`` picks the model kept)
    and its figures form the learning curve. ``start_net`` (M = 1): fine-tune that model
    instead of starting from :func:`initial_net`; it is then validated first and kept unless a
    later centre scores better."""
    rng = np.random.default_rng(config.seed)
    start = time.monotonic()
    net = initial_net(rng, config.hidden, config.width) if start_net is None else start_net
    theta = net.flat()[0]
    adam = Adam(theta.size, config.learning_rate)
    workers = max(1, min(config.workers, len(config.sensor_counts)))
    shares = [tuple(config.sensor_counts[w::workers]) for w in range(workers)]
    ctx = mp.get_context("spawn") if workers > 1 else None
    procs, inboxes, outboxes = [], [], []
    local: Pool | None = None
    if ctx is None:
        local = Pool(config.sensor_counts, config)
    else:
        for share in shares:
            inbox, outbox = ctx.Queue(), ctx.Queue()
            proc = ctx.Process(target=_worker, args=(share, config, inbox, outbox), daemon=True)
            proc.start()
            procs.append(proc)
            inboxes.append(inbox)
            outboxes.append(outbox)
        for outbox, proc in zip(outboxes, procs, strict=True):
            _receive(outbox, proc)
    log(f"training missions built in {time.monotonic() - start:.0f} s")
    curve: list[dict[str, float]] = []
    best_score, best_theta = -np.inf, theta.copy()
    if start_net is not None:
        best_score = validate(start_net)["score"]
        log(f"starting model: validation score {best_score:+.4f}")
    generation = flown = 0
    try:
        while time.monotonic() - start < seconds and (
            max_generations is None or generation < max_generations
        ):
            eps = rng.standard_normal((config.pairs, theta.size))
            rows = np.concatenate([theta + config.sigma * eps, theta - config.sigma * eps])
            counts = [share[int(rng.integers(len(share)))] for share in shares]
            picks = [
                rng.choice(config.pool_per_count, config.missions_per_count, replace=False)
                for _ in counts
            ]
            if local is not None:
                gains = [
                    local.evaluate(n, p, rows, net) for n, p in zip(counts, picks, strict=True)
                ]
            else:
                for inbox, n, p in zip(inboxes, counts, picks, strict=True):
                    inbox.put((n, p, rows, net))
                gains = [_receive(o, p) for o, p in zip(outboxes, procs, strict=True)]
            gain = np.concatenate(gains, axis=1)
            flown += gain.size
            score = fitness(gain, config.loss_margin, config.loss_weight)
            ranks = centred_ranks(score)
            weights = ranks[: config.pairs] - ranks[config.pairs :]
            gradient = weights @ eps / (2 * config.pairs * config.sigma)
            theta = theta + adam.step(gradient)
            generation += 1
            if generation % validate_every == 0:
                figures = validate(net.with_flat(theta[None]))
                elapsed = time.monotonic() - start
                row = {
                    "generation": float(generation),
                    "seconds": elapsed,
                    "missions_flown": float(flown),
                    "train_fitness": float(score.mean()),
                    **figures,
                }
                curve.append(row)
                if figures["score"] > best_score:
                    best_score, best_theta = figures["score"], theta.copy()
                log(
                    f"gen {generation:4d} {elapsed:6.0f} s  train {score.mean():+.4f}  "
                    + "  ".join(f"{k} {v:+.4f}" for k, v in figures.items())
                )
    finally:
        for inbox in inboxes:
            inbox.put(None)
        for proc in procs:
            proc.join(timeout=30)
            if proc.is_alive():
                proc.terminate()
    if not curve and start_net is None:  # too short to validate: keep the last centre
        best_theta = theta
    return ESResult(
        net.with_flat(best_theta[None]), generation, flown, time.monotonic() - start, curve
    )
